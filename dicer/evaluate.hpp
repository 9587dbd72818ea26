#pragma once
// Private to dicer/: evaluation of the TFI recipe (tfi.hpp) at one point of
// one entity, in that entity's canonical frame, from validated rows
// (rows.hpp). Shared by node(id), the block fill and the cursors, so every
// path computes the same function with the same inputs (invariant 2).
#include <array>
#include <cstdint>
#include <new>
#include <vector>

#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"

namespace dicer::detail {

// Room for N objects of an aggregate T (Vec3, ElementRow) left
// uninitialised: their member initialisers would zero arrays and rows that
// are filled at once anyway (rep stos, a fifth of a random node query).
// The byte array implicitly creates the objects (C++20: an aggregate is an
// implicit-lifetime type). Only for storage every field of which is written
// before it is read.
template <class T, int N = 1>
struct Uninitialised {
  alignas(T) unsigned char bytes[N * sizeof(T)];
  T* data() { return std::launder(reinterpret_cast<T*>(bytes)); }
  const T* data() const { return std::launder(reinterpret_cast<const T*>(bytes)); }
  T& operator[](int q) { return data()[q]; }
  const T& operator[](int q) const { return data()[q]; }
  T& operator*() { return data()[0]; }
};

struct Evaluator {
  RowReader R;

  Evaluator(const MeshTables& t, MeshCursor& c) : R(t, c) {}
  Mode mode() const { return R.mode(); }

  // A predicted point corrected by bounding row `row` (a moved node).
  Vec3 moved(const Vec3& p, Id row) const;
  // Edge point at canonical t in [0, n]: at the edge's graded parameter
  // from lo to hi, moved when the edge has bounding rows.
  Vec3 edge_point(const EdgeRow& e, Id t) const;
  // The row of local edge k of element h, checked against the element's
  // interval and grading along it (Corrupt when they disagree).
  EdgeRow edge_of(const ElementRow& h, int k) const;
  // Side k of a face (0 v0v1, 1 v3v2, 2 v0v3, 3 v1v2): its edge's row
  // (interval checked), and its point at face parameter s.
  EdgeRow face_side_row(const FaceRow& f, int k) const;
  Vec3 face_side(const FaceRow& f, int k, const EdgeRow& e, Id s) const;
  // Face point at canonical (u, v), moved when bounded.
  Vec3 face_point(const FaceRow& f, Id u, Id v) const;
  // Interior face point before any move: the bilinear patch of its corners
  // when its sides are unmoved and `coons` is false (a straight face), else
  // the Coons patch of its sides (tfi.hpp). face_point passes coons = the
  // face is moved, and a move's prediction true: a moved face's nodes are
  // corrections to its Coons patch.
  Vec3 face_tfi(const FaceRow& f, Id u, Id v, bool coons) const;
  // Interior point (i, j, k) of element h, row hid (0 < i < n1 ...).
  // `corners`: h's corner coordinates (corner_xyz) when already read.
  Vec3 cell_point(const ElementRow& h, Id hid, Id i, Id j, Id k, const Vec3* corners = nullptr) const;
  // A vertex, edge or face node that straight element h owns, at local
  // slot `slot` (NodeOwner), from h's corners alone: the values and bits
  // of node(r) (a straight element's edges and faces are straight: the
  // inputs are copies of the same corner coordinates), without reading the
  // entity's rows or its vertices' owners.
  Vec3 straight_owned_point(const ElementRow& h, Id hid, int slot, const NodeRef& r,
                            const Vec3* corners = nullptr) const;
  // The owner's view of grid point (i, j, k) of element h.
  NodeRef grid_node(const ElementRow& h, Id hid, Id i, Id j, Id k) const;
  // Its node id, from the element row alone.
  Id grid_node_id(const ElementRow& h, Id i, Id j, Id k) const;
  // The node ids of the 8 corners of hex cell (i, j, k) of element h
  // (volume mode), in kHexCorner order: grid_node_id of each corner. The
  // corners fall into at most 8 of the element's 27 regions (per axis: the
  // low side, the high side, inside) and in each region the id is affine in
  // the grid point, so this forms one map per region the cell touches (two
  // for most boundary cells) instead of finding each corner's entity, whose
  // branches a random query mispredicts.
  void hex_cell_node_ids(const ElementRow& h, Id i, Id j, Id k, Id* out) const;
  Vec3 node(const NodeRef& r) const;
};

// The boundary points of one coarse element, each computed by its owning
// entity's function in that entity's canonical frame: edges (canonical
// t = 1..n-1) and faces ((nu-1)(nv-1), u fastest): a straight face (a
// straight element's all) from the element's corners alone, the others
// from the edge and face rows (moved nodes included); a curved element's
// rows say which of its faces are straight. One definition for the block
// fill and the node cursor.
// Results in out.corner (from the corners table), out.edge[k][d] (edge
// k's interior points, canonical order, index t - 1) and out.face[k][d]
// (face k's, canonical order). Fills what `want_edge`/`want_face` ask for
// (all when null): edges first (faces need them), then faces.
// `to` (a straight element's owned entities, owned_places): the edges and
// faces it places go there instead of into out.edge / out.face: the faces
// first, in increasing address order, then the edges (a face writes up to
// kPatchSlack - 1 values past its end, onto a face, edge or corner
// written after it or the interior, which its caller writes later).
struct OwnedPlaces;
void element_boundary(const Evaluator& E, const ElementRow& h, Id hid, FineBlock::Scratch& out,
                      const bool* want_edge = nullptr, const bool* want_face = nullptr,
                      const OwnedPlaces* to = nullptr);

// The local edges and faces whose nodes element h owns (edges with
// interior nodes only): what own_boundary_nodes copies and owned_places
// places.
void owned_entities(const ElementRow& h, Mode mode, bool want_edge[12], bool want_face[6]);

// Where the coordinates of the nodes element h owns outside its interior
// go in out[d][id - node_first] (own_boundary_nodes' layout): coordinate d
// of owned corner k at corner[k][d], of owned local edge k's points at
// edge[k][d] (canonical order), of owned face k's at face[k][d]; null
// where h does not own it. owned_places validates the layout (the errors
// own_boundary_nodes gives: the ranges must tile the element's own range
// exactly) and returns the end of the id range. A batch
// writes a straight element's owned edges and faces there directly
// (element_boundary's `to`): copying them from the scratch cost 5% of a
// sweep at interval 10.
struct OwnedPlaces {
  double* corner[8][3] = {};
  double* edge[12][3] = {};
  double* face[6][3] = {};
};
Id owned_places(const Evaluator& E, const ElementRow& h, Id hid, double* const out[3], Id size, OwnedPlaces& at);

// The coordinates of the nodes element h owns outside its interior
// (volume: ids [node_first, cell_node); surface: [node_first, cell_node +
// its face's nodes)), in id order, into out[d][id - node_first] (`size`
// values each): its owned corners, edges and faces, copied from `s`, which
// must hold every entity of h in canonical frames (s.boundary holds h at
// Held::All: fill_slab with coordinates of a curved hex or a surface
// element has just put them there; a straight hex's batch has them
// written in place instead, owned_places). Returns the end of
// that id range. Error{Corrupt} when the range is not `size` long or the
// row's owned entities do not tile it.
Id own_boundary_nodes(const Evaluator& E, const ElementRow& h, Id hid, const FineBlock::Scratch& s,
                      double* const out[3], Id size);

// The bilinear patch p[0..3] (tfi::bilinear_row, then bilinear_point, as
// face_tfi and cell_point compute each point) at s[1 .. nu - 1] x
// t[1 .. nv - 1], row v (1 <= v < nv) at out + (v - 1)(nu - 1): a straight
// face's interior, and each interior plane of a straight hex (p its
// trilinear_plane). Rows are written in whole blocks of kPatchSlack points,
// up to kPatchSlack - 1 values past a row's end, which the next row then
// overwrites, and past the last row into the caller's room: out holds
// (nu - 1)(nv - 1) + kPatchSlack doubles and s is readable up to
// s[nu - 1 + kPatchSlack]. Why: a row's scalar tail and the vectoriser's
// alias checks cost more than its points (bench/README.md, stop 37).
inline constexpr Id kPatchSlack = 8;
void bilinear_patch(const double* s, const double* t, Id nu, Id nv, const double* p, double* out);

// FineBatch::lines of grid planes k0..k1 (0 in surface mode) of the element
// whose ids B holds (fill_slab keeps them) and whose cell's first node is
// cell_node: row r = j + (n[1] + 1) (k - k0) into start[r], first[r],
// step[r], end[r]. O(rows); the interior rows' ends are the ring's.
void slab_lines(const FineBlock::Scratch::Boundary& B, Id cell_node, Id k0, Id k1, Id* start, Id* first, Id* step,
                Id* end);

// The same patches, many over one (s, t) grid (a hex's interior planes,
// three coordinates each): prepare_patch_grid lays out each row's weights
// and each point's s and row once, after which a patch is one pass over
// its points 8 at a time, the row's terms picked by a two-register
// permute: on AVX-512 machines and for up to 16 rows (interval <= 17),
// else bilinear_patch above. Rows of 9 points (interval 10) cost about as
// much in row set-up as in points there, and 16 lanes were written for 9
// (bench/README.md, stop 38). Same bits: each lane computes
// bilinear_row's terms and bilinear_point in their order. s and t must
// outlive the grid; out as bilinear_patch's (up to kPatchSlack - 1
// values past the last point). No allocation once warm; a grid prepared
// again with the same parameters' bits (uniform grading: every hex and
// face of one interval) only takes the new pointers.
struct PatchGrid {
  alignas(64) double T[16], t[16];  // rows' weights 1 - t[v] and t[v], lane v - 1
  std::vector<double> s;            // point f's s, f = (v - 1)(nu - 1) + u - 1
  std::vector<std::int64_t> row;    // point f's lane, v - 1
  const double *su = nullptr, *tv = nullptr;
  Id nu = 0, nv = 0;
  bool permute = false;  // the permute path; else bilinear_patch(su, tv, ...)
};
void prepare_patch_grid(const double* s, const double* t, Id nu, Id nv, PatchGrid& g);
void bilinear_patch(const PatchGrid& g, const double* p, double* out);

// tfi::Series(n, g).at(t) for 0 <= t0 <= t < t1 <= n + 1 into out[t], the same bits,
// from a per-thread cache of the last few series of up to 64 intervals
// (a sweep's hexes and faces mostly share a handful; each value is a
// division, or a log and a power, otherwise). No allocation.
void series_values(Id n, const tfi::Grading& g, Id t0, Id t1, double* out);

// Every grid point of one facet of element h: local face `slot` (volume)
// or local edge `slot` (surface), with its node id and coordinates, each
// computed by its owner as everywhere else. O(facet points); uses `s`.
void facet_points(const Evaluator& E, const ElementRow& h, Id hid, int slot, FineBlock::Scratch& s,
                  std::vector<Id>& ids, std::vector<Vec3>& xyz);

// Local edge of the element carrying canonical side `side` of local face lf.
inline int face_side_edge(Mode mode, int lf, FaceCode code, int side) {
  return mode == Mode::Volume ? hex_face_side_edge(lf, code, side) : quad_side_edge(code, side);
}
// Grading of local face lf along its canonical u and v, from the element
// row (what RowReader::face_grading gives from the face's edge rows).
std::array<tfi::Grading, 2> face_grading(Mode mode, const ElementRow& h, int lf);

}  // namespace dicer::detail
