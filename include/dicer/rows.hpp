#pragma once
// Rows: the typed, validated view of every table row (tables.hpp). The only
// code that knows where a column sits; everything else (the fine mesh,
// cursors, chunks, export, verify, geometry, benchmarks) reads rows here.
//
// Rows are data, not trust: a store can be crafted with valid checksums.
// RowReader checks every id against its table, every interval against the
// limits the writer obeys (numbering.hpp: kMaxElementPoints), and every id
// range a row names against the fine counts, with 128-bit products, before
// a caller sizes or indexes anything by it. A row that fails is
// Error{Corrupt} naming the store, the dataset, the row and the field.
//
// Node ids of an entity (numbering.hpp): a vertex has one (`node`); an edge
// with interval n has n - 1 interior nodes from `node` on, canonical t = 1
// first; a face with intervals (nu, nv) has (nu-1)(nv-1) from `node`, u
// fastest; an element's interior (n1-1)(n2-1)(n3-1) from `cell_node`
// (surface mode: its face's nodes).
//
// Cost: a read is one row pointer (TableCursor) and a copy of the row.
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dicer/orientation.hpp"
#include "dicer/tables.hpp"
#include "dicer/tfi.hpp"

namespace dicer {

// Upper bound of grid points ((n1+1)(n2+1)(n3+1)) of one coarse element,
// shared by the writer (numbering refuses more: Error{Overflow}) and the
// readers (a row claiming more is Corrupt). 2^40 points could never be
// held anyway; it keeps every product of a row's intervals within 64 bits.
inline constexpr Id kMaxElementPoints = Id{1} << 40;

// topology/vertex_nodes: who owns vertex v (the corner slot it is at in
// its owner: its coordinates are that corner's) and its fine node id.
struct VertexRow {
  Id owner_element = -1;
  int corner = 0;
  Id node = -1;
};

// topology/edges: lo < hi are vertex ids (the canonical direction).
struct EdgeRow {
  Id lo = 0, hi = 0;
  Id n = 1;                  // the sheet's interval
  Id node = 0;               // first interior node id
  Id sheet = 0;              // as `dicer sheets` numbers them for the input file
  Id owner_element = 0;      // lowest coarse element containing the edge
  std::int64_t geo = -1;     // geometric owner, pack_owner(dim, tag), -1 unknown
  Id bound = -1;             // first row of `bounding` for its n-1 nodes, -1: not moved
  Id other_element = -1;     // surface mode: the other quad on the edge (-1: boundary or non-manifold); volume: -1
  // The sheet's grading in the edge's canonical direction (lo -> hi):
  // node t sits at tfi::param(t, n, grading) (tfi::grading_ok holds).
  tfi::Grading grading;
};

// topology/faces: canonical corners v (v0 lowest id, v1 its lower
// neighbour), sides e (v0v1, v3v2, v0v3, v1v2), intervals along u (v0->v1)
// and v (v0->v3).
struct FaceRow {
  std::array<Id, 4> v{}, e{};
  Id nu = 1, nv = 1;
  Id node = 0;
  Id owner_element = 0;
  std::int64_t geo = -1;
  Id bound = -1;             // first row of `bounding` for its (nu-1)(nv-1) nodes
  Id other_element = -1;     // volume mode: the other hex on the face (-1: boundary); surface: -1
};

// topology/element_bounds: an axis-aligned box holding every fine node of
// the coarse element (so every fine cell: trilinear cells stay in their
// nodes' box). Straight elements: their corners' box (TFI of straight
// edges is a convex combination of the corners); curved ones: the box of
// all their fine nodes. The spatial index (index/group_bounds) is the union
// of kBoundsGroup consecutive rows.
struct ElementBounds {
  std::array<double, 3> lo{}, hi{};
  bool contains(const Vec3& p, double pad = 0) const {
    return p.x >= lo[0] - pad && p.x <= hi[0] + pad && p.y >= lo[1] - pad && p.y <= hi[1] + pad && p.z >= lo[2] - pad &&
           p.z <= hi[2] + pad;
  }
  bool overlaps(const std::array<double, 3>& blo, const std::array<double, 3>& bhi) const {
    for (int d = 0; d < 3; ++d)
      if (hi[d] < blo[d] || lo[d] > bhi[d]) return false;
    return true;
  }
};

// topology/elements. Local numbering of corners, edges and faces:
// orientation.hpp (HEX8 / QUAD4 corner order; kHexEdge, kHexFace; surface
// mode: kQuadEdge and one face, the quad itself). Entries past the mode's
// counts (4 corners, 4 edges, 1 face in surface mode) are unused.
struct ElementRow {
  std::array<Id, 8> corner{}, corner_node{};  // vertex ids and their node ids
  std::array<Id, 12> edge{}, edge_node{};     // edge ids and their first interior node ids
  std::array<Id, 6> face{}, face_node{};
  Id node_first = 0;     // first node id the element owns: its entities' and interior ids are >= this
  Id element_first = 0;  // fine id of element (0, 0, 0); then i fastest, j, k
  Id cell_node = 0;      // first interior node id
  Id file_id = 0;        // element id in the input file
  std::int32_t block = 0;  // index into MeshInfo::blocks
  // bit k: local edge k runs hi -> lo; bits 12 + 3k..14 + 3k: face code of
  // local face k; bit kCurvedBit: some edge or face has bounding rows.
  std::uint64_t flags = 0;
  std::array<Id, 3> n{1, 1, 1};  // intervals along local i, j, k (k = 1 in surface mode)
  // Grading along local i, j, k, each in its axis' increasing direction:
  // the edges along axis a carry grading[a] (tfi::reversed where rev()).
  std::array<tfi::Grading, 3> grading{};

  static constexpr int kCurvedBit = 30;
  bool rev(int k) const { return (flags >> k) & 1; }
  FaceCode code(int k) const { return static_cast<FaceCode>((flags >> (12 + 3 * k)) & 7); }
  bool curved() const { return (flags >> kCurvedBit) & 1; }
  // Whether this element owns the node id (entities owned by earlier
  // elements have lower ids: owner order).
  bool owns(Id node) const { return node >= node_first; }
  // Local edge k's grading in its canonical direction (as its edge row has it).
  tfi::Grading edge_grading(int k, Mode mode) const {
    const tfi::Grading& g = grading[mode == Mode::Volume ? k / 4 : k / 2];
    return rev(k) ? tfi::reversed(g) : g;
  }
};

// Which table a row comes from (errors, widths, dataset names).
enum class RowTable : std::uint8_t { VertexNodes, Edges, Faces, Elements, Corners, Bounds };
// Values per row (int64, or float64 for Corners and Bounds) in `mode`.
std::int64_t row_width(RowTable table, Mode mode);
// The table's dataset in the store (store/FORMAT.md), e.g. "topology/edges".
const char* row_dataset(RowTable table);

// Reads and validates rows through one MeshCursor. Cheap to construct; not
// thread-safe (one per thread, like the cursor).
class RowReader {
 public:
  RowReader(const MeshTables& t, MeshCursor& c) : t_(t), c_(c) {}

  const MeshTables& tables() const { return t_; }
  Mode mode() const { return t_.mode; }
  int corners() const { return t_.mode == Mode::Volume ? 8 : 4; }
  int edges() const { return t_.mode == Mode::Volume ? 12 : 4; }
  int faces() const { return t_.mode == Mode::Volume ? 6 : 1; }

  Vec3 xyz(Id v) const;                       // its owner's corner; v checked
  VertexRow vertex(Id v) const;
  EdgeRow edge(Id e) const;
  FaceRow face(Id f) const;
  // A face's grading along its canonical u (v0 -> v1) and v (v0 -> v3):
  // its side edges' (e0 and e2), seen from v0. Corrupt (naming the side
  // e1 or e3) when opposite sides disagree: a sheet graded inconsistently.
  // `sides`: the rows of its side edges e0..e3 when already read.
  std::array<tfi::Grading, 2> face_grading(const FaceRow& row) const;
  std::array<tfi::Grading, 2> face_grading(const FaceRow& row, const EdgeRow* sides) const;
  ElementRow element(Id h) const {
    ElementRow o;
    element(h, o);
    return o;
  }
  // The same into `o` (every field written; no copy of the ~450-byte row:
  // random queries decode one per call).
  void element(Id h, ElementRow& o) const;
  // Element h's grid alone: node_first, element_first, cell_node, file_id,
  // block, flags, n and grading, validated as element() validates them,
  // without the entity columns (corner, edge and face ids and node ids: 80%
  // of the row; the rest is 2 or 3 of its cache lines), which are set to
  // -1. Enough for a node or cell inside a straight element's interior
  // (FineMesh::node, element); anything that needs an entity reads element().
  void element_grid(Id h, ElementRow& o) const;
  // The rest of row h into `o`, which element_grid(h, o) filled (its grid
  // valid: the entity checks size by it); volume mode, where the two are
  // element(h, o), each column read once. Surface rows use element().
  void element_entities(Id h, ElementRow& o) const;
  // The element's corner coordinates (corners() of them), as `corners`
  // stores them: bit-identical to xyz() of its corner vertices.
  void corner_xyz(Id h, Vec3* out) const;
  // Asks the memory system for element h's corner row without waiting for
  // it (a random query's misses then overlap), for callers about to read
  // it with corner_xyz: the row's page is pinned as corner_xyz would (a
  // page that fails to load throws here), the values are not checked. An
  // id outside the table does nothing.
  void prefetch_corners(Id h) const;
  // Element h's row (and its corners), into the cache at once: one
  // query's misses overlap instead of following each other. Pins like
  // prefetch_corners; the values are not checked, and an id outside the
  // table does nothing.
  void prefetch_element(Id h, bool corners = true) const;
  // Element h's bounds: finite, lo <= hi (Corrupt otherwise).
  ElementBounds bounds(Id h) const;
  // Bounds rows h, h + 1, ... as one pointer (6 values per row, lo then
  // hi), validated like bounds(): at most `count` rows, as many as share h's
  // page (at least 1); returns how many. Valid until the cursor's bounds
  // page moves (a scan of a group of rows reads each page once).
  // `checked`: this reader's caller validated these rows before, through
  // this call (a store is immutable: a row re-read after its page left the
  // cache is the same CRC-checked bytes); the validation pass is skipped.
  Id bounds_rows(Id h, Id count, const double*& rows, bool checked = false) const;
  // Row `row` of the bounding arrays: the three codes of one moved node.
  std::array<std::int64_t, 3> bounding(Id row) const;
  // Geometric owner of vertex v (pack_owner), -1 unknown.
  std::int64_t vertex_geo(Id v) const;
  // One column of an element row, for searches (no full validation: the
  // row found is read with element() afterwards).
  Id node_first(Id h) const;
  Id element_first(Id h) const;
  // The first row in [lo, hi) whose node_first (by_node) or element_first
  // exceeds x (hi if none), over rows that share one page (Table::run),
  // through one pointer (the page's dense column, else the rows').
  // Unvalidated like the two above. An
  // interpolation search: about 2 rows touched when rows own about as many
  // ids as their neighbours (plus the two end rows without hints),
  // O(log(hi - lo)) at worst. `hints`: the values
  // at row lo and at row hi (the next page's first row), when the caller
  // knows them (the page index); they only steer the probes, so any hints
  // give the same answer. Without them the two end rows are read. On a
  // store (a dense column), an element_first search with hints prefetches
  // the row its first probe names (prefetch_element): what the caller
  // reads next, arriving with the search's own miss.
  struct SearchHints {
    std::int64_t at_lo = 0, at_hi = 0;
  };
  Id search_first(Id lo, Id hi, Id x, bool by_node, const SearchHints* hints = nullptr) const;
  // What a search needs of element h (its fine grid, grading and curved flag),
  // validated like element() validates these fields, without decoding the
  // rest of the ~450-byte row.
  struct Cells {
    std::array<Id, 3> n{1, 1, 1};
    Id element_first = 0;
    bool curved = false;
    std::array<tfi::Grading, 3> grading{};
  };
  Cells cells(Id h) const;

  // Error{Corrupt}: "<store>: <dataset> row <row>: <what>".
  [[noreturn]] void corrupt(RowTable table, Id row, const std::string& what) const;

 private:
  void check_grid(Id h, const std::array<Id, 3>& n, Id element_first, std::uint64_t flags) const;
  void element_scalars(Id h, ElementRow& o) const;
  const std::int64_t* first_ids(Id h, bool by_node, std::int64_t& stride) const;
  [[noreturn]] void element_failure(Id h, const ElementRow& o) const;

  const MeshTables& t_;
  MeshCursor& c_;
};

// The element-row columns a store's loader lays out densely after each
// page's rows (Table::derived), in this order: node_first, element_first.
// search_first reads them there when the table has them.
std::vector<int> element_search_columns(Mode mode);

// Encoders: a row into `out`, row_width(kind, mode) values (corners: 3
// per corner; bounds: 6), as the table holds it. write_store streams pages
// of them (DicedRows) without building the tables.
void encode_row(Mode mode, const VertexRow& r, std::int64_t* out);
void encode_row(Mode mode, const EdgeRow& r, std::int64_t* out);
void encode_row(Mode mode, const FaceRow& r, std::int64_t* out);
void encode_row(Mode mode, const ElementRow& r, std::int64_t* out);
void encode_corners(Mode mode, const Vec3* xyz, double* out);
void encode_bounds(const ElementBounds& b, double* out);

// Writers, for in-memory tables only (dicing, geometry-conforming moves):
// row i of the table, which grows by one row when i == rows().
void write_row(MeshTables& t, Id v, const VertexRow& r);
void write_row(MeshTables& t, Id e, const EdgeRow& r);
void write_row(MeshTables& t, Id f, const FaceRow& r);
void write_row(MeshTables& t, Id h, const ElementRow& r);
void write_corners(MeshTables& t, Id h, const Vec3* xyz);
void write_bounds(MeshTables& t, Id h, const ElementBounds& b);

// The box of n points padded by 1e-12 of their magnitude (a straight
// element's bounds from its corners: its nodes' rounding stays inside).
ElementBounds corner_bounds(const Vec3* xyz, int n);
// MeshTables::group_bounds from the bounds rows: O(H) reads; or from the
// bounds of elements 0 .. elements-1 as bounds(h) gives them.
std::vector<double> group_bounds(const MeshTables& t);
std::vector<double> group_bounds(Id elements, const std::function<ElementBounds(Id)>& bounds);

}  // namespace dicer
