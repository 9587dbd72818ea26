// The row layer: where every column of every table sits (private to this
// file), and the checks a row passes before anyone uses it.
#include "dicer/rows.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>

#include "dicer/error.hpp"

namespace dicer {
namespace {

// ---------------------------------------------------------------- columns

enum VertexCol : int { kVertexOwner = 0, kVertexCorner, kVertexNode, kVertexWidth };
enum EdgeCol : int {
  kEdgeLo = 0, kEdgeHi, kEdgeN, kEdgeNode, kEdgeSheet, kEdgeOwner, kEdgeGeo, kEdgeBound, kEdgeOther, kEdgeGrade,
  kEdgeRatio, kEdgeWidth
};
enum FaceCol : int {
  kFaceV = 0, kFaceE = 4, kFaceNu = 8, kFaceNv, kFaceNode, kFaceOwner, kFaceGeo, kFaceBound, kFaceOther, kFaceWidth
};

// Element row: corners, their node ids, edges, their first node ids, faces,
// their first node ids (c, c, e, e, f, f columns for c corners, e edges, f
// faces), then the scalars below.
struct ElementCols {
  int c, e, f;
  int corner() const { return 0; }
  int corner_node() const { return c; }
  int edge() const { return 2 * c; }
  int edge_node() const { return 2 * c + e; }
  int face() const { return 2 * c + 2 * e; }
  int face_node() const { return 2 * c + 2 * e + f; }
  int node_first() const { return 2 * (c + e + f); }
  int element_first() const { return node_first() + 1; }
  int cell_node() const { return node_first() + 2; }
  int file_id() const { return node_first() + 3; }
  int block() const { return node_first() + 4; }
  int flags() const { return node_first() + 5; }
  int n() const { return node_first() + 6; }
  int grade() const { return node_first() + 9; }
  int ratio() const { return node_first() + 10; }
  int width() const { return node_first() + 13; }
  static ElementCols of(Mode m) { return m == Mode::Volume ? ElementCols{8, 12, 6} : ElementCols{4, 4, 1}; }
};

using i128 = __int128;

// A grading as columns: kind | flip << 2 (3 bits; an element packs its
// three axes at bits 3a), and the ratio's IEEE bits.
constexpr int kGradeBits = 3;
std::int64_t grade_code(const tfi::Grading& g) { return static_cast<std::int64_t>(g.kind) | (g.flip ? 4 : 0); }
tfi::Grading grading_of(std::int64_t code, std::int64_t ratio) {
  return {static_cast<tfi::Spacing>(code & 3), (code & 4) != 0, std::bit_cast<double>(ratio)};
}
std::string grading_text(const tfi::Grading& g) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "grading (kind %d%s, ratio %.17g)", static_cast<int>(g.kind), g.flip ? ", flipped" : "",
                g.ratio);
  return buf;
}

}  // namespace

std::int64_t row_width(RowTable table, Mode mode) {
  switch (table) {
    case RowTable::VertexNodes: return kVertexWidth;
    case RowTable::Edges: return kEdgeWidth;
    case RowTable::Faces: return kFaceWidth;
    case RowTable::Elements: return ElementCols::of(mode).width();
    case RowTable::Corners: return 3 * ElementCols::of(mode).c;
    case RowTable::Bounds: return 6;
  }
  return 0;
}

const char* row_dataset(RowTable table) {
  switch (table) {
    case RowTable::VertexNodes: return "topology/vertex_nodes";
    case RowTable::Edges: return "topology/edges";
    case RowTable::Faces: return "topology/faces";
    case RowTable::Elements: return "topology/elements";
    case RowTable::Corners: return "topology/element_corners";
    case RowTable::Bounds: return "topology/element_bounds";
  }
  return "?";
}

void RowReader::corrupt(RowTable table, Id row, const std::string& what) const {
  throw Error(ErrorKind::Corrupt, (t_.origin.empty() ? std::string("in memory") : t_.origin) + ": " +
                                      row_dataset(table) + " row " + std::to_string(row) + ": " + what);
}

namespace {
// An id range [first, first + count) inside [0, total).
bool range_ok(Id first, i128 count, Id total) { return first >= 0 && count >= 0 && first + count <= i128{total}; }
bool interval_ok(Id n) { return n >= 1 && n < kMaxElementPoints; }
// -1 (unknown) or a CAD entity of dimension 0..3 (pack_owner).
bool geo_ok(std::int64_t g) { return g == -1 || (g >= 0 && owner_dim(g) <= 3); }
}  // namespace

Vec3 RowReader::xyz(Id v) const {
  const VertexRow o = vertex(v);
  Vec3 c[8];
  corner_xyz(o.owner_element, c);
  return c[o.corner];
}

VertexRow RowReader::vertex(Id v) const {
  if (v < 0 || v >= t_.vertex_nodes.rows()) corrupt(RowTable::VertexNodes, v, "vertex id out of range");
  const std::int64_t* r = t_.vertex_nodes.row(v, c_.vertex_nodes);
  if (r[kVertexCorner] < 0 || r[kVertexCorner] >= corners())
    corrupt(RowTable::VertexNodes, v, "corner slot " + std::to_string(r[kVertexCorner]) + " out of range");
  const VertexRow out{r[kVertexOwner], static_cast<int>(r[kVertexCorner]), r[kVertexNode]};
  if (out.owner_element < 0 || out.owner_element >= t_.elements.rows())
    corrupt(RowTable::VertexNodes, v, "owner element " + std::to_string(out.owner_element) + " out of range");
  if (out.node < 0 || out.node >= t_.fine_nodes) corrupt(RowTable::VertexNodes, v, "node id " + std::to_string(out.node) + " out of range");
  return out;
}

EdgeRow RowReader::edge(Id e) const {
  if (e < 0 || e >= t_.edges.rows()) corrupt(RowTable::Edges, e, "edge id out of range");
  const std::int64_t* r = t_.edges.row(e, c_.edges);
  EdgeRow o;
  o.lo = r[kEdgeLo], o.hi = r[kEdgeHi], o.n = r[kEdgeN], o.node = r[kEdgeNode], o.sheet = r[kEdgeSheet];
  o.owner_element = r[kEdgeOwner], o.geo = r[kEdgeGeo], o.bound = r[kEdgeBound], o.other_element = r[kEdgeOther];
  const std::int64_t grade = r[kEdgeGrade];
  o.grading = grading_of(grade, r[kEdgeRatio]);
  const Id V = t_.num_vertices();
  if (o.lo < 0 || o.hi >= V || o.lo >= o.hi) corrupt(RowTable::Edges, e, "vertex ids out of range or not ascending");
  if (!interval_ok(o.n)) corrupt(RowTable::Edges, e, "interval " + std::to_string(o.n) + " out of range");
  if (!range_ok(o.node, o.n - 1, t_.fine_nodes)) corrupt(RowTable::Edges, e, "node ids outside the mesh");
  if (o.sheet < 0 || (t_.sheets > 0 && o.sheet >= t_.sheets)) corrupt(RowTable::Edges, e, "sheet id out of range");
  if (o.owner_element < 0 || o.owner_element >= t_.elements.rows()) corrupt(RowTable::Edges, e, "owner element out of range");
  // The other element comes after the owner (the owner is the lowest).
  if (o.other_element != -1 &&
      (t_.mode == Mode::Volume || o.other_element <= o.owner_element || o.other_element >= t_.elements.rows()))
    corrupt(RowTable::Edges, e, "other element " + std::to_string(o.other_element) + " out of range");
  if (!geo_ok(o.geo)) corrupt(RowTable::Edges, e, "geometric owner " + std::to_string(o.geo) + " is not a CAD entity");
  if (o.bound != -1 && !range_ok(o.bound, o.n - 1, t_.bounding.rows()))
    corrupt(RowTable::Edges, e, "bounding rows outside geometry/bounding");
  if (grade < 0 || grade >= (1 << kGradeBits) || !tfi::grading_ok(o.grading))
    corrupt(RowTable::Edges, e, grading_text(o.grading) + " is not valid");
  return o;
}

std::array<tfi::Grading, 2> RowReader::face_grading(const FaceRow& row) const {
  EdgeRow sides[4];
  for (int k = 0; k < 4; ++k) sides[k] = edge(row.e[k]);
  return face_grading(row, sides);
}

std::array<tfi::Grading, 2> RowReader::face_grading(const FaceRow& row, const EdgeRow* sides) const {
  std::array<tfi::Grading, 2> out;
  for (int axis = 0; axis < 2; ++axis) {
    tfi::Grading side[2];
    for (int q = 0; q < 2; ++q) {
      const int k = 2 * axis + q;  // sides 0, 1 run along u; 2, 3 along v (kQuadEdge)
      const tfi::Grading& g = sides[k].grading;
      side[q] = row.v[kQuadEdge[k][0]] < row.v[kQuadEdge[k][1]] ? g : tfi::reversed(g);
    }
    if (!(side[0] == side[1]))
      corrupt(RowTable::Edges, row.e[2 * axis + 1],
              "graded unlike the opposite side of a face it bounds (an inconsistent sheet direction)");
    out[axis] = side[0];
  }
  return out;
}

FaceRow RowReader::face(Id f) const {
  if (f < 0 || f >= t_.faces.rows()) corrupt(RowTable::Faces, f, "face id out of range");
  const std::int64_t* r = t_.faces.row(f, c_.faces);
  FaceRow o;
  for (int k = 0; k < 4; ++k) o.v[k] = r[kFaceV + k], o.e[k] = r[kFaceE + k];
  o.nu = r[kFaceNu], o.nv = r[kFaceNv], o.node = r[kFaceNode], o.owner_element = r[kFaceOwner];
  o.geo = r[kFaceGeo], o.bound = r[kFaceBound], o.other_element = r[kFaceOther];
  for (int k = 0; k < 4; ++k) {
    if (o.v[k] < 0 || o.v[k] >= t_.num_vertices()) corrupt(RowTable::Faces, f, "corner vertex id out of range");
    if (o.e[k] < 0 || o.e[k] >= t_.edges.rows()) corrupt(RowTable::Faces, f, "side edge id out of range");
  }
  if (!interval_ok(o.nu) || !interval_ok(o.nv) || i128{o.nu + 1} * (o.nv + 1) > kMaxElementPoints)
    corrupt(RowTable::Faces, f, "intervals out of range");
  const i128 interior = i128{o.nu - 1} * (o.nv - 1);
  if (!range_ok(o.node, interior, t_.fine_nodes)) corrupt(RowTable::Faces, f, "node ids outside the mesh");
  if (o.owner_element < 0 || o.owner_element >= t_.elements.rows()) corrupt(RowTable::Faces, f, "owner element out of range");
  if (o.other_element != -1 &&
      (t_.mode == Mode::Surface || o.other_element <= o.owner_element || o.other_element >= t_.elements.rows()))
    corrupt(RowTable::Faces, f, "other element " + std::to_string(o.other_element) + " out of range");
  if (!geo_ok(o.geo)) corrupt(RowTable::Faces, f, "geometric owner " + std::to_string(o.geo) + " is not a CAD entity");
  if (o.bound != -1 && !range_ok(o.bound, interior, t_.bounding.rows()))
    corrupt(RowTable::Faces, f, "bounding rows outside geometry/bounding");
  return o;
}

namespace {
// An element row's three axis gradings: element() and cells() decode and
// check them here, the same way.
void element_grading(const RowReader& R, Id h, const std::int64_t* r, const ElementCols& L,
                     std::array<tfi::Grading, 3>& out) {
  const std::int64_t grade = r[L.grade()];
  constexpr std::int64_t kOne = std::bit_cast<std::int64_t>(1.0);
  if (grade == 0 && r[L.ratio()] == kOne && r[L.ratio() + 1] == kOne && r[L.ratio() + 2] == kOne) {
    out = {};  // equally spaced (most rows): the checks below hold
    return;
  }
  if (grade < 0 || grade >= (1 << (3 * kGradeBits)))
    R.corrupt(RowTable::Elements, h, "unknown grading bits " + std::to_string(grade));
  for (int a = 0; a < 3; ++a) {
    out[a] = grading_of(grade >> (kGradeBits * a), r[L.ratio() + a]);
    if (!tfi::grading_ok(out[a]) || (a == 2 && R.mode() == Mode::Surface && out[a].kind != tfi::Spacing::Equal))
      R.corrupt(RowTable::Elements, h, "axis " + std::to_string(a) + ": " + grading_text(out[a]) + " is not valid");
  }
}
}  // namespace

// The fields of an element row that say where its fine grid is: element()
// and cells() check them here, the same way.
void RowReader::check_grid(Id h, const std::array<Id, 3>& n, Id element_first, std::uint64_t flags) const {
  i128 points = 1, cells = 1;
  for (int k = 0; k < 3; ++k) {
    if (!interval_ok(n[k])) corrupt(RowTable::Elements, h, "interval " + std::to_string(n[k]) + " out of range");
    points *= n[k] + 1, cells *= n[k];
  }
  if (points > kMaxElementPoints || (t_.mode == Mode::Surface && n[2] != 1))
    corrupt(RowTable::Elements, h, "intervals out of range");
  if (flags >= (std::uint64_t{1} << (ElementRow::kCurvedBit + 1))) corrupt(RowTable::Elements, h, "unknown flag bits");
  if (!range_ok(element_first, cells, t_.fine_elements)) corrupt(RowTable::Elements, h, "fine element ids outside the mesh");
}

// The scalar columns (node_first on), shared by element() and element_grid():
// decoded and checked the same way.
void RowReader::element_scalars(Id h, ElementRow& o) const {
  if (h < 0 || h >= t_.elements.rows()) corrupt(RowTable::Elements, h, "element id out of range");
  const ElementCols L = ElementCols::of(t_.mode);
  const std::int64_t* r = t_.elements.row(h, c_.elements);
  o.node_first = r[L.node_first()], o.element_first = r[L.element_first()], o.cell_node = r[L.cell_node()];
  o.file_id = r[L.file_id()];
  const std::int64_t block = r[L.block()];
  o.flags = static_cast<std::uint64_t>(r[L.flags()]);
  o.n = {r[L.n()], r[L.n() + 1], r[L.n() + 2]};
  check_grid(h, o.n, o.element_first, o.flags);
  element_grading(*this, h, r, L, o.grading);
  // The grid is valid now, so the interior count is under kMaxElementPoints.
  const Id interior = (o.n[0] - 1) * (o.n[1] - 1) * (t_.mode == Mode::Volume ? o.n[2] - 1 : 1);
  if (block < 0 || block >= t_.blocks) corrupt(RowTable::Elements, h, "block index " + std::to_string(block) + " out of range");
  if (!range_ok(o.cell_node, interior, t_.fine_nodes) || o.node_first < 0 || o.node_first > o.cell_node)
    corrupt(RowTable::Elements, h, "owned node ids out of range");
  o.block = static_cast<std::int32_t>(block);
}

void RowReader::element_grid(Id h, ElementRow& o) const {
  element_scalars(h, o);
  // Entity columns unread: ids no table holds, so a caller that uses one
  // anyway meets a Corrupt error, not a wrong row.
  o.corner.fill(-1), o.corner_node.fill(-1), o.edge.fill(-1), o.edge_node.fill(-1);
  o.face.fill(-1), o.face_node.fill(-1);
}

void RowReader::element(Id h, ElementRow& o) const {
  if (t_.mode == Mode::Surface) o = ElementRow{};  // surface rows leave the volume-only entries zero
  element_scalars(h, o);
  element_entities(h, o);
}

void RowReader::element_entities(Id h, ElementRow& o) const {
  DICER_ASSERT(interval_ok(o.n[0]) && interval_ok(o.n[1]) && interval_ok(o.n[2]),
               "element_entities: the grid of element_grid comes first");
  const ElementCols L = ElementCols::of(t_.mode);
  if (h < 0 || h >= t_.elements.rows()) corrupt(RowTable::Elements, h, "element id out of range");
  const std::int64_t* r = t_.elements.row(h, c_.elements);
  for (int k = 0; k < L.c; ++k) o.corner[k] = r[L.corner() + k], o.corner_node[k] = r[L.corner_node() + k];
  for (int k = 0; k < L.e; ++k) o.edge[k] = r[L.edge() + k], o.edge_node[k] = r[L.edge_node() + k];
  for (int k = 0; k < L.f; ++k) o.face[k] = r[L.face() + k], o.face_node[k] = r[L.face_node() + k];
  // The entity columns in one pass without branches (random queries decode
  // a row per call); which one failed is looked for only when one did.
  const bool vol = t_.mode == Mode::Volume;
  const Id V = t_.num_vertices(), N = t_.fine_nodes;
  auto below = [](Id x, Id limit) { return static_cast<std::uint64_t>(x) < static_cast<std::uint64_t>(limit); };
  // [first, first + count) in [0, N): first < 2^63 and count < 2^40, so the sum cannot wrap.
  auto run = [N](Id first, Id count) {
    return (first >= 0) & (static_cast<std::uint64_t>(first) + static_cast<std::uint64_t>(count) <= static_cast<std::uint64_t>(N));
  };
  bool ok = true;
  for (int k = 0; k < L.c; ++k) ok &= below(o.corner[k], V), ok &= below(o.corner_node[k], N);
  for (int k = 0; k < L.e; ++k) ok &= below(o.edge[k], t_.edges.rows()) & run(o.edge_node[k], o.n[vol ? k / 4 : k / 2] - 1);
  for (int k = 0; k < L.f; ++k) {
    const Id a = o.n[vol ? kHexFaceAxes[k][0] : 0] - 1, b = o.n[vol ? kHexFaceAxes[k][1] : 1] - 1;
    ok &= below(o.face[k], t_.faces.rows()) & run(o.face_node[k], a * b);
  }
  if (!ok) element_failure(h, o);
}

// The entity checks of element() one by one, for the message: which field
// of row h is wrong. Only called when one is.
void RowReader::element_failure(Id h, const ElementRow& o) const {
  const ElementCols L = ElementCols::of(t_.mode);
  const bool vol = t_.mode == Mode::Volume;
  const auto RT = RowTable::Elements;
  for (int k = 0; k < L.c; ++k)
    if (o.corner[k] < 0 || o.corner[k] >= t_.num_vertices() || o.corner_node[k] < 0 || o.corner_node[k] >= t_.fine_nodes)
      corrupt(RT, h, "corner " + std::to_string(k) + " out of range");
  for (int k = 0; k < L.e; ++k) {
    const Id n = o.n[vol ? k / 4 : k / 2];
    if (o.edge[k] < 0 || o.edge[k] >= t_.edges.rows() || !range_ok(o.edge_node[k], n - 1, t_.fine_nodes))
      corrupt(RT, h, "edge " + std::to_string(k) + " out of range");
  }
  for (int k = 0; k < L.f; ++k) {
    const i128 a = o.n[vol ? kHexFaceAxes[k][0] : 0] - 1, b = o.n[vol ? kHexFaceAxes[k][1] : 1] - 1;
    if (o.face[k] < 0 || o.face[k] >= t_.faces.rows() || !range_ok(o.face_node[k], a * b, t_.fine_nodes))
      corrupt(RT, h, "face " + std::to_string(k) + " out of range");
  }
  DICER_ASSERT(false, "element(): the branch-free checks and these agree");
}

void RowReader::corner_xyz(Id h, Vec3* out) const {
  if (h < 0 || h >= t_.corners.rows()) corrupt(RowTable::Corners, h, "element id out of range");
  const double* r = t_.corners.row(h, c_.corners);
  for (int k = 0; k < corners(); ++k) {
    out[k] = {r[3 * k], r[3 * k + 1], r[3 * k + 2]};
    if (!std::isfinite(out[k].x) || !std::isfinite(out[k].y) || !std::isfinite(out[k].z))
      corrupt(RowTable::Corners, h, "coordinate is not finite");
  }
}

void RowReader::prefetch_corners(Id h) const {
  if (h < 0 || h >= t_.corners.rows()) return;
  const char* r = reinterpret_cast<const char*>(t_.corners.row(h, c_.corners));
  const std::size_t bytes = sizeof(double) * 3 * static_cast<std::size_t>(corners());
  for (std::size_t b = 0; b < bytes; b += 64) __builtin_prefetch(r + b);
  __builtin_prefetch(r + bytes - 1);
}

void RowReader::prefetch_element(Id h, bool corners) const {
  if (h < 0 || h >= t_.elements.rows()) return;
  const char* r = reinterpret_cast<const char*>(t_.elements.row(h, c_.elements));
  const std::size_t bytes = sizeof(std::int64_t) * static_cast<std::size_t>(t_.elements.width());
  const std::size_t scalars = sizeof(std::int64_t) * static_cast<std::size_t>(ElementCols::of(t_.mode).node_first());
  // The scalar columns first (every query reads them; 2 or 3 lines, by the
  // row's offset in its line), then the corners, then the entity columns
  // (a query on the element's boundary reads them).
  for (std::size_t b = scalars; b < bytes; b += 64) __builtin_prefetch(r + b);
  __builtin_prefetch(r + bytes - 1);
  if (corners) prefetch_corners(h);
  for (std::size_t b = 0; b < scalars; b += 64) __builtin_prefetch(r + b);
}

ElementBounds RowReader::bounds(Id h) const {
  if (h < 0 || h >= t_.bounds.rows()) corrupt(RowTable::Bounds, h, "element id out of range");
  const double* r = t_.bounds.row(h, c_.bounds);
  ElementBounds b;
  for (int d = 0; d < 3; ++d) {
    b.lo[d] = r[d], b.hi[d] = r[3 + d];
    if (!std::isfinite(b.lo[d]) || !std::isfinite(b.hi[d]) || b.lo[d] > b.hi[d])
      corrupt(RowTable::Bounds, h, "bounds not finite or lower above upper");
  }
  return b;
}

Id RowReader::bounds_rows(Id h, Id count, const double*& rows, bool checked) const {
  if (h < 0 || h >= t_.bounds.rows() || count < 1) corrupt(RowTable::Bounds, h, "element id out of range");
  const Id k = std::min({count, t_.bounds.rows() - h, t_.bounds.run(h)});
  rows = t_.bounds.row(h, c_.bounds);
  if (checked) return k;
  // One pass without branches; the bad row is looked for only when there is one.
  // -max <= lo <= hi <= max: both finite, ordered (NaN fails every test).
  constexpr double big = std::numeric_limits<double>::max();
  bool ok = true;
  for (Id i = 0; i < 6 * k; i += 6)
    for (int d = 0; d < 3; ++d) ok &= (rows[i + d] >= -big) & (rows[i + d] <= rows[i + 3 + d]) & (rows[i + 3 + d] <= big);
  if (!ok)
    for (Id i = 0; i < k; ++i) bounds(h + i);
  return k;
}

std::array<std::int64_t, 3> RowReader::bounding(Id row) const {
  if (row < 0 || row >= t_.bounding.rows())
    throw Error(ErrorKind::Corrupt, (t_.origin.empty() ? std::string("in memory") : t_.origin) +
                                        ": geometry/bounding: row " + std::to_string(row) + " out of range");
  const std::int64_t* r = t_.bounding.row(row, c_.bounding);
  return {r[0], r[1], r[2]};
}

std::int64_t RowReader::vertex_geo(Id v) const {
  if (v < 0 || v >= t_.vertex_owner.rows())
    throw Error(ErrorKind::Corrupt, (t_.origin.empty() ? std::string("in memory") : t_.origin) +
                                        ": geometry/vertex_owner: row " + std::to_string(v) + " out of range");
  const std::int32_t* r = t_.vertex_owner.row(v, c_.vertex_owner);
  return r[0] < 0 ? -1 : pack_owner(r[0], r[1]);
}

// Row h's node_first (by_node) or element_first, the values of the rows
// after it on its page `stride` values apart: in the dense column the
// store's loader derived (stride 1; element_search_columns' order), else
// in the rows themselves.
const std::int64_t* RowReader::first_ids(Id h, bool by_node, std::int64_t& stride) const {
  if (const std::int64_t* v = t_.elements.derived(h, by_node ? 0 : 1, c_.elements)) {
    stride = 1;
    return v;
  }
  const ElementCols L = ElementCols::of(t_.mode);
  stride = t_.elements.width();
  return t_.elements.row(h, c_.elements) + (by_node ? L.node_first() : L.element_first());
}
Id RowReader::node_first(Id h) const {
  std::int64_t stride;
  return *first_ids(h, true, stride);
}
Id RowReader::element_first(Id h) const {
  std::int64_t stride;
  return *first_ids(h, false, stride);
}

std::vector<int> element_search_columns(Mode mode) {
  const ElementCols L = ElementCols::of(mode);
  return {L.node_first(), L.element_first()};
}

Id RowReader::search_first(Id lo, Id hi, Id x, bool by_node, const SearchHints* hints) const {
  if (lo >= hi) return lo;
  // One pointer for the run [lo, hi) on one page (or in memory).
  DICER_ASSERT(lo >= 0 && hi <= t_.elements.rows() && hi - lo <= t_.elements.run(lo), "search_first: one page");
  std::int64_t w;
  const std::int64_t* base = first_ids(lo, by_node, w);
  auto at = [&](Id r) { return base[(r - lo) * w]; };
  // The answer lies in [a, b]: rows below a hold values <= x (or lie below
  // lo), row b one > x (or b == hi). va at row pa and vb at row pb: values
  // read or hinted, which only steer the probes.
  Id a = lo, b = hi, pa = lo, pb = hi;
  std::int64_t va, vb;
  if (hints) {
    va = hints->at_lo, vb = hints->at_hi;
  } else {
    va = at(lo);
    if (va > x) return lo;
    a = lo + 1;
    vb = at(hi - 1);
    if (vb <= x) return hi;
    b = pb = hi - 1;
  }
  // Interpolation: every row owns about as many ids as its neighbours, so
  // the straight line through (pa, va) and (pb, vb) lands on or next to the
  // answer: about 2 probes, each a cache line (of the dense column, or of a
  // ~520-byte row in memory), where a bisection of a page takes 7. Each
  // probe lies inside the bracket and shrinks it, whatever the values;
  // after four, bisection bounds the rest.
  for (int probe = 0; probe < 4 && a < b; ++probe) {
    Id m = a + (b - a) / 2;
    if (vb > va && x >= va && pb > pa) {
      // The first row above x on that line (rows pa + 1, pa + 2, ... at
      // even steps): pa + 1 + floor((x - va) / step).
      // Differences exact in 64 unsigned bits (x >= va, vb > va: each is
      // below 2^64), then rounded: vb - va >= 1, so the quotient is finite
      // and >= 0 for any values (no NaN to convert). (128-bit differences
      // cost a libgcc call each to convert.)
      const auto diff = [](std::int64_t hi, std::int64_t lo) {
        return static_cast<double>(static_cast<std::uint64_t>(hi) - static_cast<std::uint64_t>(lo));
      };
      const double span = static_cast<double>(pb - pa);
      const double rows = diff(x, va) * span / diff(vb, va);
      m = std::clamp(pa + 1 + static_cast<Id>(rows < span ? rows : span), a, b - 1);
    }
    if (probe == 0 && w > 1) {
      // The next probe is most often a neighbour: its cache line now, so
      // that its miss overlaps this one's instead of following it.
      if (m > lo) __builtin_prefetch(base + (m - 1 - lo) * w);
      if (m + 1 < hi) __builtin_prefetch(base + (m + 1 - lo) * w);
    } else if (probe == 0 && hints && !by_node) {
      // Rows hold equally many fine elements wherever the intervals are
      // uniform, so the line through the page index's values names the
      // row (m - 1), which the caller reads next: its lines now, so that
      // their miss overlaps the column's. (Nodes per row vary with the
      // entities each element owns: that guess is often a row off.)
      prefetch_element(std::max(m - 1, lo), false);
    }
    const std::int64_t v = at(m);
    if (v <= x) a = m + 1, va = v, pa = m;
    else b = pb = m, vb = v;
  }
  while (a < b) {
    const Id mid = a + (b - a) / 2;
    if (at(mid) <= x) a = mid + 1;
    else b = mid;
  }
  return a;
}

RowReader::Cells RowReader::cells(Id h) const {
  if (h < 0 || h >= t_.elements.rows()) corrupt(RowTable::Elements, h, "element id out of range");
  const ElementCols L = ElementCols::of(t_.mode);
  const std::int64_t* r = t_.elements.row(h, c_.elements);
  Cells o;
  o.n = {r[L.n()], r[L.n() + 1], r[L.n() + 2]};
  o.element_first = r[L.element_first()];
  const auto flags = static_cast<std::uint64_t>(r[L.flags()]);
  o.curved = (flags >> ElementRow::kCurvedBit) & 1;
  check_grid(h, o.n, o.element_first, flags);
  element_grading(*this, h, r, L, o.grading);
  return o;
}

// ---------------------------------------------------------------- writers

namespace {
template <class T>
T* row_for_write(Table<T>& t, Id i) {
  if (!t.in_memory()) throw Error(ErrorKind::Usage, "write_row: tables opened from a store are read-only");
  auto& m = t.memory();
  const size_t w = static_cast<size_t>(t.width());
  if (static_cast<size_t>(i) * w >= m.size()) {
    m.resize((static_cast<size_t>(i) + 1) * w);
    t.reshape();
  }
  return m.data() + static_cast<size_t>(i) * w;
}
}  // namespace

void encode_row(Mode, const VertexRow& r, std::int64_t* o) {
  o[kVertexOwner] = r.owner_element, o[kVertexCorner] = r.corner, o[kVertexNode] = r.node;
}

void encode_row(Mode, const EdgeRow& r, std::int64_t* o) {
  o[kEdgeLo] = r.lo, o[kEdgeHi] = r.hi, o[kEdgeN] = r.n, o[kEdgeNode] = r.node, o[kEdgeSheet] = r.sheet;
  o[kEdgeOwner] = r.owner_element, o[kEdgeGeo] = r.geo, o[kEdgeBound] = r.bound, o[kEdgeOther] = r.other_element;
  o[kEdgeGrade] = grade_code(r.grading), o[kEdgeRatio] = std::bit_cast<std::int64_t>(r.grading.ratio);
}

void encode_row(Mode, const FaceRow& r, std::int64_t* o) {
  for (int k = 0; k < 4; ++k) o[kFaceV + k] = r.v[k], o[kFaceE + k] = r.e[k];
  o[kFaceNu] = r.nu, o[kFaceNv] = r.nv, o[kFaceNode] = r.node, o[kFaceOwner] = r.owner_element;
  o[kFaceGeo] = r.geo, o[kFaceBound] = r.bound, o[kFaceOther] = r.other_element;
}

void encode_row(Mode mode, const ElementRow& r, std::int64_t* o) {
  const ElementCols L = ElementCols::of(mode);
  for (int k = 0; k < L.c; ++k) o[L.corner() + k] = r.corner[k], o[L.corner_node() + k] = r.corner_node[k];
  for (int k = 0; k < L.e; ++k) o[L.edge() + k] = r.edge[k], o[L.edge_node() + k] = r.edge_node[k];
  for (int k = 0; k < L.f; ++k) o[L.face() + k] = r.face[k], o[L.face_node() + k] = r.face_node[k];
  o[L.node_first()] = r.node_first, o[L.element_first()] = r.element_first, o[L.cell_node()] = r.cell_node;
  o[L.file_id()] = r.file_id, o[L.block()] = r.block, o[L.flags()] = static_cast<std::int64_t>(r.flags);
  std::int64_t grade = 0;
  for (int k = 0; k < 3; ++k) {
    o[L.n() + k] = r.n[k];
    grade |= grade_code(r.grading[k]) << (kGradeBits * k);
    o[L.ratio() + k] = std::bit_cast<std::int64_t>(r.grading[k].ratio);
  }
  o[L.grade()] = grade;
}

void encode_corners(Mode mode, const Vec3* xyz, double* o) {
  const int c = ElementCols::of(mode).c;
  for (int k = 0; k < c; ++k) o[3 * k] = xyz[k].x, o[3 * k + 1] = xyz[k].y, o[3 * k + 2] = xyz[k].z;
}

void encode_bounds(const ElementBounds& b, double* o) {
  for (int d = 0; d < 3; ++d) o[d] = b.lo[d], o[3 + d] = b.hi[d];
}

void write_row(MeshTables& t, Id v, const VertexRow& r) { encode_row(t.mode, r, row_for_write(t.vertex_nodes, v)); }
void write_row(MeshTables& t, Id e, const EdgeRow& r) { encode_row(t.mode, r, row_for_write(t.edges, e)); }
void write_row(MeshTables& t, Id f, const FaceRow& r) { encode_row(t.mode, r, row_for_write(t.faces, f)); }
void write_row(MeshTables& t, Id h, const ElementRow& r) { encode_row(t.mode, r, row_for_write(t.elements, h)); }
void write_corners(MeshTables& t, Id h, const Vec3* xyz) { encode_corners(t.mode, xyz, row_for_write(t.corners, h)); }
void write_bounds(MeshTables& t, Id h, const ElementBounds& b) { encode_bounds(b, row_for_write(t.bounds, h)); }

ElementBounds corner_bounds(const Vec3* xyz, int n) {
  ElementBounds b;
  b.lo = {xyz[0].x, xyz[0].y, xyz[0].z}, b.hi = b.lo;
  for (int k = 1; k < n; ++k) {
    const double c[3] = {xyz[k].x, xyz[k].y, xyz[k].z};
    for (int d = 0; d < 3; ++d) b.lo[d] = std::min(b.lo[d], c[d]), b.hi[d] = std::max(b.hi[d], c[d]);
  }
  // TFI of straight edges is a convex combination of the corners, but in
  // floating point a node of a flat side may land an ulp outside: pad by far
  // more than rounding and far less than any cell.
  double scale = 0;
  for (int d = 0; d < 3; ++d) scale = std::max({scale, std::abs(b.lo[d]), std::abs(b.hi[d]), b.hi[d] - b.lo[d]});
  const double pad = 1e-12 * scale;
  for (int d = 0; d < 3; ++d) b.lo[d] -= pad, b.hi[d] += pad;
  return b;
}

std::vector<double> group_bounds(Id elements, const std::function<ElementBounds(Id)>& bounds) {
  const Id groups = (elements + kBoundsGroup - 1) / kBoundsGroup;
  std::vector<double> out(static_cast<size_t>(groups) * 6);
  for (Id g = 0; g < groups; ++g) {
    double* o = &out[static_cast<size_t>(g) * 6];
    for (int d = 0; d < 3; ++d) o[d] = INFINITY, o[3 + d] = -INFINITY;
    for (Id h = g * kBoundsGroup; h < std::min(elements, (g + 1) * kBoundsGroup); ++h) {
      const ElementBounds b = bounds(h);
      for (int d = 0; d < 3; ++d) o[d] = std::min(o[d], b.lo[d]), o[3 + d] = std::max(o[3 + d], b.hi[d]);
    }
  }
  return out;
}

std::vector<double> group_bounds(const MeshTables& t) {
  MeshCursor cur;
  const RowReader R(t, cur);
  return group_bounds(t.bounds.rows(), [&](Id h) { return R.bounds(h); });
}

}  // namespace dicer
