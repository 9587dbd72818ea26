// Transfer operators between nested dicings (transfer.hpp): the content
// check, the row generator (a coarse element at a time, rows in id order),
// and P / P^T applied over threads and ranges.
//
// Why the transpose keeps per-element partial sums: a coarse-store node on
// a coarse element's boundary gets contributions from every element around
// it. Summing each element's share first (O(coarse n^2) per element) and
// adding the shares in element order makes the result independent of how
// elements are split over threads or ranks, with one share per element and
// node to carry across a split instead of one per fine node (a coarse store
// at interval 1 would otherwise carry every fine node of a range).
#include "dicer/transfer.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <exception>
#include <thread>

#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"
#include "evaluate.hpp"
#include "work_split.hpp"

namespace dicer {
namespace {

std::string name_of(const FineMesh& m) { return m.tables().origin.empty() ? std::string("(in memory)") : m.tables().origin; }

bool same_bits(const Vec3& a, const Vec3& b) {
  return std::bit_cast<std::uint64_t>(a.x) == std::bit_cast<std::uint64_t>(b.x) &&
         std::bit_cast<std::uint64_t>(a.y) == std::bit_cast<std::uint64_t>(b.y) &&
         std::bit_cast<std::uint64_t>(a.z) == std::bit_cast<std::uint64_t>(b.z);
}

// Entries of one entity's rows along one axis: n - 1 interior fine nodes
// over n_c coarse intervals, 2 entries each except on coarse planes.
__int128 axis_entries(Id n, Id nc) { return 2 * static_cast<__int128>(n) - nc - 1; }

}  // namespace

// ------------------------------------------------------------ nesting

Nesting check_nesting(const FineMesh& coarse, const FineMesh& fine) {
  const std::string cn = name_of(coarse), fn = name_of(fine);
  auto differ = [&](const std::string& what) {
    throw Error(ErrorKind::BadInput, cn + " and " + fn + " are not dicings of one coarse mesh: " + what);
  };
  auto count = [&](const char* what, Id a, Id b) {
    if (a != b) differ(std::string(what) + " " + std::to_string(a) + " vs " + std::to_string(b));
  };
  if (coarse.mode() != fine.mode())
    differ(std::string("mode ") + mode_name(coarse.mode()) + " vs " + mode_name(fine.mode()));
  const MeshInfo &ci = coarse.info(), &fi = fine.info();
  count("coarse vertices", ci.coarse_vertices, fi.coarse_vertices);
  count("coarse edges", ci.coarse_edges, fi.coarse_edges);
  count("coarse faces", ci.coarse_faces, fi.coarse_faces);
  count("coarse elements", ci.coarse_elements, fi.coarse_elements);
  count("sheets", ci.sheets, fi.sheets);
  count("blocks", static_cast<Id>(ci.blocks.size()), static_cast<Id>(fi.blocks.size()));
  for (size_t b = 0; b < ci.blocks.size(); ++b)
    if (ci.blocks[b].id != fi.blocks[b].id)
      differ("block " + std::to_string(b) + " has id " + std::to_string(ci.blocks[b].id) + " vs " +
             std::to_string(fi.blocks[b].id));

  MeshCursor cc, fc;
  const detail::Evaluator CE(coarse.tables(), cc), FE(fine.tables(), fc);
  const RowReader &C = CE.R, &F = FE.R;
  const MeshTables& T = coarse.tables();
  auto field = [&](const char* table, Id row, const char* name, Id a, Id b) {
    if (a != b)
      differ(std::string(table) + " row " + std::to_string(row) + ": " + name + " is " + std::to_string(a) + " vs " +
             std::to_string(b));
  };
  // A CAD owner in words: "no CAD entity" or "CAD surface 3".
  auto cad_name = [](std::int64_t o) {
    static const char* kDim[] = {"point", "curve", "surface", "volume"};
    const int d = owner_dim(o);
    return d < 0 || d > 3 ? std::string("no CAD entity") : "CAD " + std::string(kDim[d]) + " " + std::to_string(owner_tag(o));
  };
  auto cad_field = [&](const char* table, Id row, std::int64_t a, std::int64_t b) {
    if (a == b) return;
    const bool one_placed = (owner_dim(a) < 0) != (owner_dim(b) < 0);
    differ(std::string(table) + " row " + std::to_string(row) + ": on " + cad_name(a) + " vs " + cad_name(b) +
           (one_placed ? " (one was diced with --geometry and the other not: dice both with the same CAD)"
                       : " (diced onto different CAD files?)"));
  };
  for (Id v = 0; v < T.num_vertices(); ++v) {
    const VertexRow a = C.vertex(v), b = F.vertex(v);
    field("topology/vertex_nodes", v, "owner element", a.owner_element, b.owner_element);
    field("topology/vertex_nodes", v, "corner", a.corner, b.corner);
    cad_field("geometry/vertex_owner", v, C.vertex_geo(v), F.vertex_geo(v));
  }
  // Sheets: the first (in id order) whose fine interval is not a multiple.
  Nesting out;
  out.sheets = ci.sheets;
  std::vector<Id> sc = coarse.sheet_intervals(), sf = fine.sheet_intervals();
  const bool have_sheets = static_cast<Id>(sc.size()) == ci.sheets && static_cast<Id>(sf.size()) == ci.sheets;
  if (!have_sheets) sc.assign(static_cast<size_t>(ci.sheets), 0), sf.assign(static_cast<size_t>(ci.sheets), 0);
  // P's weights are those of equally spaced levels: a graded sheet's fine
  // nodes are not at the reference positions P assumes.
  Id graded_sheet = -1;
  bool graded_in_fine = false;
  for (Id e = 0; e < T.edges.rows(); ++e) {
    const EdgeRow a = C.edge(e), b = F.edge(e);
    const char* t = "topology/edges";
    field(t, e, "lo", a.lo, b.lo), field(t, e, "hi", a.hi, b.hi), field(t, e, "sheet", a.sheet, b.sheet);
    field(t, e, "owner element", a.owner_element, b.owner_element), cad_field(t, e, a.geo, b.geo);
    field(t, e, "other element", a.other_element, b.other_element);
    if (a.sheet < 0 || a.sheet >= ci.sheets) C.corrupt(RowTable::Edges, e, "sheet id outside the sheets");
    auto& s_c = sc[static_cast<size_t>(a.sheet)];
    auto& s_f = sf[static_cast<size_t>(a.sheet)];
    if (!have_sheets && s_c == 0) s_c = a.n, s_f = b.n;
    if (a.n != s_c) C.corrupt(RowTable::Edges, e, "interval disagrees with its sheet's");
    if (b.n != s_f) F.corrupt(RowTable::Edges, e, "interval disagrees with its sheet's");
    if ((a.grading.kind != tfi::Spacing::Equal || b.grading.kind != tfi::Spacing::Equal) &&
        (graded_sheet < 0 || a.sheet < graded_sheet))
      graded_sheet = a.sheet, graded_in_fine = b.grading.kind != tfi::Spacing::Equal;
  }
  for (Id f = 0; f < T.faces.rows(); ++f) {
    const FaceRow a = C.face(f), b = F.face(f);
    const char* t = "topology/faces";
    for (int k = 0; k < 4; ++k) field(t, f, "corner", a.v[k], b.v[k]), field(t, f, "side", a.e[k], b.e[k]);
    field(t, f, "owner element", a.owner_element, b.owner_element), cad_field(t, f, a.geo, b.geo);
    field(t, f, "other element", a.other_element, b.other_element);
  }
  const int nc = C.corners(), ne = C.edges(), nf = C.faces();
  ElementRow a, b;
  for (Id h = 0; h < T.elements.rows(); ++h) {
    C.element(h, a), F.element(h, b);
    const char* t = "topology/elements";
    for (int k = 0; k < nc; ++k) field(t, h, "corner vertex", a.corner[k], b.corner[k]);
    for (int k = 0; k < ne; ++k) field(t, h, "edge", a.edge[k], b.edge[k]);
    for (int k = 0; k < nf; ++k) field(t, h, "face", a.face[k], b.face[k]);
    const std::uint64_t orient = ~(std::uint64_t{1} << ElementRow::kCurvedBit);  // curved depends on the intervals
    field(t, h, "orientation flags", static_cast<Id>(a.flags & orient), static_cast<Id>(b.flags & orient));
    field(t, h, "file id", a.file_id, b.file_id), field(t, h, "block", a.block, b.block);
    Vec3 xa[8], xb[8];
    C.corner_xyz(h, xa), F.corner_xyz(h, xb);
    for (int k = 0; k < nc; ++k)
      if (!same_bits(xa[k], xb[k]))
        differ("topology/element_corners row " + std::to_string(h) + ": corner " + std::to_string(k) +
               " has other coordinates (other vertices, or diced with another CAD)");
  }
  for (Id s = 0; s < ci.sheets; ++s) {
    const Id n_c = sc[static_cast<size_t>(s)], n_f = sf[static_cast<size_t>(s)];
    if (n_c == 0) continue;  // a sheet without edges (none are written so)
    if (n_f % n_c != 0) {
      out.sheet = s, out.coarse_interval = n_c, out.fine_interval = n_f;
      break;
    }
    const Id m = n_f / n_c;
    out.min_factor = out.min_factor ? std::min(out.min_factor, m) : m;
    out.max_factor = std::max(out.max_factor, m);
  }
  if (out.sheet < 0 && graded_sheet >= 0) {
    out.sheet = graded_sheet, out.graded = true;
    out.coarse_interval = sc[static_cast<size_t>(graded_sheet)], out.fine_interval = sf[static_cast<size_t>(graded_sheet)];
  }
  out.nested = out.sheet < 0;
  out.rows = fine.num_nodes(), out.cols = coarse.num_nodes();
  if (out.graded) {
    out.min_factor = out.max_factor = 0;
    out.message = "not nested: sheet " + std::to_string(out.sheet) + " is graded in " + (graded_in_fine ? fn : cn) +
                  "; transfer operators need equally spaced sheets in both stores";
    return out;
  }
  if (!out.nested) {
    out.min_factor = out.max_factor = 0;
    out.message = "not nested: sheet " + std::to_string(out.sheet) + " has interval " + std::to_string(out.fine_interval) +
                  " in " + fn + ", not a multiple of its interval " + std::to_string(out.coarse_interval) + " in " + cn;
    return out;
  }
  // Coincident nodes moved onto the CAD: the coarse store's against their
  // fine twins, bit for bit (O(moved nodes)).
  auto compare = [&](const Vec3& x, const Vec3& y, Id coarse_node) {
    ++out.moved_nodes_checked;
    if (!same_bits(x, y) && out.moved_nodes_differ++ == 0) out.first_differing_coarse_node = coarse_node;
  };
  for (Id e = 0; e < T.edges.rows(); ++e) {
    const EdgeRow a = C.edge(e), b = F.edge(e);
    if ((a.bound < 0 && b.bound < 0) || a.n < 2) continue;
    const Id m = b.n / a.n;
    for (Id t = 1; t < a.n; ++t) compare(CE.edge_point(a, t), FE.edge_point(b, m * t), ids::edge_node(a.node, t));
  }
  for (Id f = 0; f < T.faces.rows(); ++f) {
    const FaceRow a = C.face(f), b = F.face(f);
    if ((a.bound < 0 && b.bound < 0) || a.nu < 2 || a.nv < 2) continue;
    const Id mu = b.nu / a.nu, mv = b.nv / a.nv;
    for (Id v = 1; v < a.nv; ++v)
      for (Id u = 1; u < a.nu; ++u)
        compare(CE.face_point(a, u, v), FE.face_point(b, mu * u, mv * v), ids::face_node(a.node, a.nu, u, v));
  }
  out.message = "nested: every sheet's interval in " + fn + " is a multiple (" + std::to_string(out.min_factor) +
                (out.max_factor != out.min_factor ? " to " + std::to_string(out.max_factor) : std::string()) +
                ") of its interval in " + cn;
  if (out.moved_nodes_differ > 0)
    out.message += "; but " + std::to_string(out.moved_nodes_differ) + " of " + std::to_string(out.moved_nodes_checked) +
                   " moved nodes (onto the CAD, or onto second-order curves and surfaces) differ from their fine "
                   "twins (first: coarse node " +
                   std::to_string(out.first_differing_coarse_node) + ")";
  return out;
}

// ------------------------------------------------------------ rows

namespace detail {

// Generates the rows of P a batch at a time (see ProlongationCursor), with
// each entry's slot in its coarse element's coarse-store boundary
// (FineBlock::Scratch::Boundary::index; -1: a coarse interior node, which
// only that element's rows read). Both grids' boundary ids come from
// fill_slab (the element rows alone), interior ids from numbering.hpp.
// Owns its cursors and blocks: one generator per thread.
class RowGenerator {
 public:
  RowGenerator(const Prolongation& p, Id first, Id end, Id slab_rows)
      : p_(p),
        vol_(p.fine().mode() == Mode::Volume),
        h_(first),
        end_(end < 0 ? p.fine().num_coarse_elements() : end),
        slab_rows_(std::max<Id>(1, slab_rows)) {
    const Id H = p.fine().num_coarse_elements();
    if (first < 0 || first > end_ || end_ > H)
      throw Error(ErrorKind::Usage, "prolongation: coarse elements " + std::to_string(first) + ".." +
                                        std::to_string(end_) + " outside the mesh (" + std::to_string(H) + ")");
  }

  // The batch made by the last next(): rows [row_begin, row_end) of
  // coarse element h, and whether it ends its element. CSR arrays: the
  // first rows() + 1 offsets and the first entries() cols, slots, weights
  // (the arrays keep their size between batches: nothing is refilled).
  Id h = -1, row_begin = 0, row_end = 0;
  bool last_of_element = false;
  std::vector<Id> offsets, cols, slots;
  std::vector<double> weights;
  Id rows() const { return row_end - row_begin; }
  Id entries() const { return offsets[static_cast<size_t>(rows())]; }
  // The current element's coarse-store boundary: slot -> coarse node id.
  const std::vector<Id>& coarse_boundary_ids() const { return cb_.scratch.boundary.id; }

  bool next() {
    for (;;) {
      if (h_ >= end_) return false;
      if (!entered_) enter();
      h = h_;
      last_of_element = false;
      if (phase_ == 0) {
        boundary_batch();
        phase_ = 1;
        if (!vol_ || fr_.n[2] < 2) finish_element();
      } else {
        interior_batch();
      }
      if (row_end > row_begin || last_of_element) return true;
    }
  }

 private:
  struct Axis {
    Id m = 1, nc = 1, nf = 1;
    Id cell(Id I) const { return I < nf ? I / m : nc - 1; }
  };
  // Coarse-store ids and slots of one grid plane of the current element.
  struct Plane {
    Id k = -1;
    std::vector<Id> id, slot;
  };

  void enter() {
    RowReader(p_.fine().tables(), fb_.cursor).element(h_, fr_);
    RowReader(p_.coarse().tables(), cb_.cursor).element(h_, cr_);
    for (int a = 0; a < 3; ++a) {
      const Id nf = fr_.n[a], nc = cr_.n[a];
      if (nc < 1 || nf % nc != 0)
        RowReader(p_.fine().tables(), fb_.cursor)
            .corrupt(RowTable::Elements, h_, "interval " + std::to_string(nf) + " along local axis " + std::to_string(a) +
                                                 " is not a multiple of the coarse store's " + std::to_string(nc));
      ax_[a] = {nf / nc, nc, nf};
      cell_[a].resize(static_cast<size_t>(nf + 1)), rem_[a].resize(static_cast<size_t>(nf + 1));
      for (Id I = 0; I <= nf; ++I) cell_[a][I] = ax_[a].cell(I), rem_[a][I] = I - cell_[a][I] * ax_[a].m;
    }
    M_ = static_cast<double>(ax_[0].m * ax_[1].m * (vol_ ? ax_[2].m : 1));
    // Both grids' boundary ids (and plane 0, unused).
    p_.fine().fill_slab(h_, 0, 0, fb_, false, false);
    p_.coarse().fill_slab(h_, 0, 0, cb_, false, false);
    plane_[0].k = plane_[1].k = -1;
    phase_ = 0;
    K_ = 1;
    entered_ = true;
    own_end_ = h_ + 1 < p_.fine().num_coarse_elements() ? RowReader(p_.fine().tables(), fb_.cursor).node_first(h_ + 1)
                                                          : p_.fine().num_nodes();
  }

  void finish_element() {
    last_of_element = true;
    entered_ = false;
    ++h_;
  }

  // Room for `rows` rows of at most 8 entries.
  void reserve(Id rows) {
    const size_t r = static_cast<size_t>(rows) + 1, e = 8 * static_cast<size_t>(rows);
    if (offsets.size() < r) offsets.resize(r);
    if (cols.size() < e) cols.resize(e), slots.resize(e), weights.resize(e);
    offsets[0] = 0;
  }

  // The entries of the row of fine grid point (I, J, K) (its owner's
  // boundary) at entry e on; returns the end. Coarse ids from the coarse
  // boundary: a point on an element's boundary lies in cells of that
  // boundary facet, whose corners are boundary points too.
  Id emit_boundary(Id I, Id J, Id K, Id e) {
    const Id P[3] = {I, J, K};
    Id c[3], num[3][2];
    for (int a = 0; a < 3; ++a) {
      c[a] = cell_[a][P[a]];
      const Id r = rem_[a][P[a]];
      num[a][0] = ax_[a].m - r, num[a][1] = r;
    }
    if (!vol_) num[2][0] = 1, num[2][1] = 0, c[2] = 0;
    const auto& B = cb_.scratch.boundary;
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const Id q = num[0][dx] * num[1][dy] * num[2][dz];
          if (q == 0) continue;
          const Id i = c[0] + dx, j = c[1] + dy, k = c[2] + dz;
          if (vol_ && i > 0 && i < cr_.n[0] && j > 0 && j < cr_.n[1] && k > 0 && k < cr_.n[2])
            RowReader(p_.fine().tables(), fb_.cursor).corrupt(RowTable::Elements, h_, "a boundary node reads a coarse interior node");
          const Id slot = B.index(i, j, k);
          cols[e] = B.id[static_cast<size_t>(slot)], slots[e] = slot, weights[e] = static_cast<double>(q) / M_, ++e;
        }
    return e;
  }

  // The element's owned nodes outside its interior (surface mode: all its
  // owned nodes), in id order: O(n^2) rows, found by walking the boundary
  // grid (the whole grid in surface mode) and placed by id.
  void boundary_batch() {
    const Id first = fr_.node_first, end = vol_ ? fr_.cell_node : own_end_;
    if (end < first) RowReader(p_.fine().tables(), fb_.cursor).corrupt(RowTable::Elements, h_, "the element's own node ids run backwards");
    row_begin = first, row_end = end;
    const size_t rows = static_cast<size_t>(end - first);
    where_.assign(rows, {-1, -1, -1});
    const auto& n = fr_.n;
    const auto& B = fb_.scratch.boundary;
    auto corrupt = [&](const char* what) { RowReader(p_.fine().tables(), fb_.cursor).corrupt(RowTable::Elements, h_, what); };
    const Id nk = vol_ ? n[2] : 0;
    for (Id K = 0; K <= nk; ++K) {
      const bool whole = !vol_ || K == 0 || K == nk;
      for (Id J = 0; J <= n[1]; ++J)
        for (Id I = 0; I <= n[0]; ++I) {
          if (!whole && J != 0 && J != n[1] && I != 0 && I != n[0]) {
            I = n[0] - 1;  // to the ring's far side
            continue;
          }
          const Id id = B.id[static_cast<size_t>(B.index(I, J, K))];
          if (id < first || id >= end) continue;
          auto& w = where_[static_cast<size_t>(id - first)];
          if (w[0] >= 0) corrupt("two grid points have one node id");
          w = {I, J, K};
        }
    }
    reserve(end - first);
    Id e = 0;
    for (size_t r = 0; r < rows; ++r) {
      const auto& w = where_[r];
      if (w[0] < 0) corrupt("the element's own node ids are not all its grid points'");
      e = emit_boundary(w[0], w[1], w[2], e);
      offsets[r + 1] = e;
    }
  }

  const Plane& plane(Id k) {
    for (auto& p : plane_)
      if (p.k == k) return p;
    Plane& p = plane_[plane_[0].k < plane_[1].k ? 0 : 1];  // planes are visited in increasing k
    const Id ni = cr_.n[0] + 1, nj = cr_.n[1] + 1;
    const auto& B = cb_.scratch.boundary;
    p.k = k;
    p.id.resize(static_cast<size_t>(ni * nj)), p.slot.resize(static_cast<size_t>(ni * nj));
    for (Id j = 0; j < nj; ++j)
      for (Id i = 0; i < ni; ++i) {
        const size_t at = static_cast<size_t>(i + ni * j);
        if (i > 0 && i < cr_.n[0] && j > 0 && j < cr_.n[1] && k > 0 && k < cr_.n[2]) {
          p.id[at] = ids::cell_node(cr_.cell_node, cr_.n, i, j, k), p.slot[at] = -1;
        } else {
          p.slot[at] = B.index(i, j, k), p.id[at] = B.id[static_cast<size_t>(p.slot[at])];
        }
      }
    return p;
  }

  // Interior planes K_.. of a volume element, about slab_rows_ rows: the
  // same entries, in the same order, as emit_boundary gives a point, written
  // straight into the batch's arrays. Per row of fine nodes (J, K) the up
  // to 4 (dy, dz) corner pairs of its coarse cells are fixed; each gets a
  // table of the weights v * num_yz / M for v = 0..m_x, so the loop along I
  // divides nothing.
  void interior_batch() {
    const auto& n = fr_.n;
    const Id per_plane = (n[0] - 1) * (n[1] - 1);
    const Id K0 = K_, K1 = std::min(n[2] - 1, K0 + std::max<Id>(1, slab_rows_ / std::max<Id>(1, per_plane)) - 1);
    row_begin = ids::cell_node(fr_.cell_node, n, 1, 1, K0);
    row_end = row_begin + per_plane * (K1 - K0 + 1);
    reserve(row_end - row_begin);
    Id* off = offsets.data() + 1;
    Id *col = cols.data(), *slot = slots.data();
    double* w = weights.data();
    const Id ni = cr_.n[0] + 1, mx = ax_[0].m;
    const Id *cx = cell_[0].data(), *rx = rem_[0].data();
    wtab_.resize(static_cast<size_t>(4 * (mx + 1)));
    Id e = 0;
    for (Id K = K0; K <= K1; ++K) {
      const Id ck = cell_[2][K], rk = rem_[2][K];
      const Plane* pl[2] = {&plane(ck), nullptr};
      if (rk != 0) pl[1] = &plane(ck + 1);  // replaces the older plane, never plane ck
      DICER_ASSERT(pl[0]->k == ck, "prolongation: the plane cache keeps the lower plane");
      const Id nz[2] = {ax_[2].m - rk, rk};
      for (Id J = 1; J < n[1]; ++J) {
        const Id cj = cell_[1][J], rj = rem_[1][J], ny[2] = {ax_[1].m - rj, rj};
        // The (dy, dz) pairs with a non-zero weight, dz slowest.
        const Id* gid[4];
        const Id* gslot[4];
        int groups = 0;
        for (int dz = 0; dz < 2; ++dz)
          for (int dy = 0; dy < 2; ++dy) {
            const Id q = ny[dy] * nz[dz];
            if (q == 0) continue;
            const size_t at = static_cast<size_t>(ni * (cj + dy));
            gid[groups] = pl[dz]->id.data() + at, gslot[groups] = pl[dz]->slot.data() + at;
            double* t = wtab_.data() + groups * (mx + 1);
            for (Id v = 0; v <= mx; ++v) t[v] = static_cast<double>(v * q) / M_;
            ++groups;
          }
        for (Id I = 1; I < n[0]; ++I) {
          const Id ci = cx[I], hi = rx[I], lo = mx - hi;
          for (int g = 0; g < groups; ++g) {
            const double* t = wtab_.data() + g * (mx + 1);
            col[e] = gid[g][ci], slot[e] = gslot[g][ci], w[e] = t[lo], ++e;
            if (hi) col[e] = gid[g][ci + 1], slot[e] = gslot[g][ci + 1], w[e] = t[hi], ++e;
          }
          *off++ = e;
        }
      }
    }
    K_ = K1 + 1;
    if (K_ >= n[2]) finish_element();
  }

  const Prolongation& p_;
  const bool vol_;
  Id h_, end_, slab_rows_;
  bool entered_ = false;
  int phase_ = 0;  // 0: the owned boundary next, 1: interior planes
  Id K_ = 1, own_end_ = 0;
  FineBlock fb_, cb_;  // boundary ids of both grids (Scratch::Boundary), with their cursors
  ElementRow fr_, cr_;
  Axis ax_[3];
  double M_ = 1;
  std::vector<Id> cell_[3], rem_[3];  // per axis and fine grid index: coarse cell, I - cell m (m at I = n)
  std::vector<double> wtab_;
  std::vector<std::array<Id, 3>> where_;
  Plane plane_[2];
};

}  // namespace detail

ProlongationCursor::ProlongationCursor(const Prolongation& p, Id first, Id end, Id slab_rows)
    : gen_(std::make_unique<detail::RowGenerator>(p, first, end, slab_rows)) {}
ProlongationCursor::~ProlongationCursor() = default;

bool ProlongationCursor::next(ProlongationBatch& out) {
  if (!gen_->next()) return false;
  const auto& g = *gen_;
  out.coarse_element = g.h;
  out.row_begin = g.row_begin, out.row_end = g.row_end;
  const auto rows = static_cast<size_t>(g.rows()), entries = static_cast<size_t>(g.entries());
  out.offsets = std::span<const Id>(g.offsets).first(rows + 1);
  out.cols = std::span<const Id>(g.cols).first(entries);
  out.weights = std::span<const double>(g.weights).first(entries);
  return true;
}

// ------------------------------------------------------------ the operator

Prolongation::Prolongation(const FineMesh& coarse, const FineMesh& fine)
    : coarse_(coarse), fine_(fine), nesting_(check_nesting(coarse, fine)) {
  if (!nesting_.nested) throw Error(ErrorKind::BadInput, "no prolongation: " + nesting_.message);
  // Non-zeros entity by entity (transfer.hpp): the fine store's own rows
  // carry every entity's two intervals.
  MeshCursor cc, fc;
  const RowReader C(coarse.tables(), cc), F(fine.tables(), fc);
  const MeshTables& T = fine.tables();
  __int128 nnz = T.num_vertices();
  for (Id e = 0; e < T.edges.rows(); ++e) nnz += axis_entries(F.edge(e).n, C.edge(e).n);
  for (Id f = 0; f < T.faces.rows(); ++f) {
    const FaceRow a = C.face(f), b = F.face(f);
    nnz += axis_entries(b.nu, a.nu) * axis_entries(b.nv, a.nv);
  }
  if (fine.mode() == Mode::Volume) {
    ElementRow a, b;
    for (Id h = 0; h < T.elements.rows(); ++h) {
      C.element(h, a), F.element(h, b);
      nnz += axis_entries(b.n[0], a.n[0]) * axis_entries(b.n[1], a.n[1]) * axis_entries(b.n[2], a.n[2]);
    }
  }
  if (nnz > static_cast<__int128>(INT64_MAX))
    throw Error(ErrorKind::Overflow, name_of(fine) + ": the prolongation's non-zeros overflow 64 bits");
  nonzeros_ = static_cast<Id>(nnz);
}

std::array<Id, 2> Prolongation::owned_rows(Id first, Id end) const {
  MeshCursor cur;
  return fine_.owned_nodes(first, end, cur);
}

std::array<Id, 2> Prolongation::owned_cols(Id first, Id end) const {
  MeshCursor cur;
  return coarse_.owned_nodes(first, end, cur);
}

std::vector<Id> Prolongation::ghost_cols(Id first, Id end) const {
  const Id begin = owned_cols(first, end)[0];
  MeshCursor cur;
  const RowReader R(coarse_.tables(), cur);
  const bool vol = coarse_.mode() == Mode::Volume;
  std::vector<std::array<Id, 2>> runs;  // [first id, count) of each entity owned before `first`
  ElementRow r;
  for (Id h = first; h < end; ++h) {
    R.element(h, r);
    for (int k = 0; k < R.corners(); ++k)
      if (r.corner_node[k] < begin) runs.push_back({r.corner_node[k], 1});
    for (int k = 0; k < R.edges(); ++k)
      if (r.edge_node[k] < begin) runs.push_back({r.edge_node[k], ids::edge_nodes(r.n[vol ? k / 4 : k / 2])});
    for (int k = 0; k < R.faces(); ++k)
      if (r.face_node[k] < begin) {
        const auto [nu, nv] = face_intervals(r, k, coarse_.mode());
        runs.push_back({r.face_node[k], ids::face_nodes(nu, nv)});
      }
  }
  std::sort(runs.begin(), runs.end());
  runs.erase(std::unique(runs.begin(), runs.end()), runs.end());
  std::vector<Id> out;
  for (const auto& [a, n] : runs)
    for (Id q = 0; q < n; ++q) out.push_back(a + q);
  return out;
}

namespace {

void need(bool ok, const std::string& what) {
  if (!ok) throw Error(ErrorKind::Usage, "prolongation: " + what);
}
std::string sz(size_t n) { return std::to_string(n); }

// Columns in a local numbering: owned [begin, end) at 0.., then `ghosts`.
struct Columns {
  Id begin, end;
  std::span<const Id> ghosts;
  Id local(Id col) const {
    if (col >= begin) return col - begin;
    const auto it = std::lower_bound(ghosts.begin(), ghosts.end(), col);
    if (it == ghosts.end() || *it != col)
      throw Error(ErrorKind::Usage, "prolongation: column " + std::to_string(col) + " is neither owned nor a ghost");
    return (end - begin) + (it - ghosts.begin());
  }
};

// y[r - rows_begin] for the rows of [first, end).
void apply_rows(const Prolongation& p, Id first, Id end, const Columns& c, const double* x, double* y, Id rows_begin) {
  detail::RowGenerator g(p, first, end, kCursorSlabPoints);
  while (g.next()) {
    const Id* off = g.offsets.data();
    const Id* col = g.cols.data();
    const double* w = g.weights.data();
    double* out = y + (g.row_begin - rows_begin);
    for (Id r = 0; r < g.row_end - g.row_begin; ++r) {
      double s = 0;
      for (Id e = off[r]; e < off[r + 1]; ++e) s += w[e] * x[c.local(col[e])];
      out[r] = s;
    }
  }
}

// x_owned[col - cols_begin] += the transpose of the rows of [first, end)
// applied to y (indexed r - rows_begin); shares for columns below
// cols_begin go to `lower`.
void transpose_rows(const Prolongation& p, Id first, Id end, const double* y, Id rows_begin, double* x_owned,
                    Id cols_begin, std::vector<std::pair<Id, double>>& lower) {
  detail::RowGenerator g(p, first, end, kCursorSlabPoints);
  std::vector<double> share;
  std::vector<Id> share_col;
  std::vector<Id> touched;
  while (g.next()) {
    if (share.size() < g.coarse_boundary_ids().size()) {
      share.resize(g.coarse_boundary_ids().size(), 0.0);
      share_col.resize(share.size(), -1);
    }
    const Id* off = g.offsets.data();
    const Id* col = g.cols.data();
    const Id* slot = g.slots.data();
    const double* w = g.weights.data();
    const double* in = y + (g.row_begin - rows_begin);
    for (Id r = 0; r < g.row_end - g.row_begin; ++r) {
      const double v = in[r];
      for (Id e = off[r]; e < off[r + 1]; ++e) {
        const double t = w[e] * v;
        if (slot[e] < 0) {
          x_owned[col[e] - cols_begin] += t;  // a coarse interior node: this element's alone
        } else {
          const auto s = static_cast<size_t>(slot[e]);
          if (share_col[s] < 0) share_col[s] = col[e], share[s] = 0.0, touched.push_back(slot[e]);
          share[s] += t;
        }
      }
    }
    if (!g.last_of_element) continue;
    // The element's shares, in slot order: the same order for any split.
    std::sort(touched.begin(), touched.end());
    for (Id s : touched) {
      const auto q = static_cast<size_t>(s);
      if (share_col[q] >= cols_begin) x_owned[share_col[q] - cols_begin] += share[q];
      else lower.emplace_back(share_col[q], share[q]);
      share_col[q] = -1;
    }
    touched.clear();
  }
}

unsigned threads_for(const Prolongation& p, unsigned threads) {
  return std::min(detail::threads_for_cache(p.coarse(), threads), detail::threads_for_cache(p.fine(), threads));
}

template <class Work>
void run_threads(unsigned threads, Work&& work) {
  std::vector<std::exception_ptr> errors(threads);
  auto run = [&](unsigned t) {
    try {
      work(t);
    } catch (...) {
      errors[t] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(run, t);
  run(0);
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace

void Prolongation::apply(std::span<const double> x, std::span<double> y, unsigned threads) const {
  need(static_cast<Id>(x.size()) == cols(), "x has " + sz(x.size()) + " values for " + std::to_string(cols()) + " columns");
  need(static_cast<Id>(y.size()) == rows(), "y has " + sz(y.size()) + " values for " + std::to_string(rows()) + " rows");
  threads = threads_for(*this, threads);
  const std::vector<Id> split = detail::split_work(fine_, threads, 0, fine_.num_coarse_elements());
  const Columns all{0, cols(), {}};
  run_threads(threads, [&](unsigned t) { apply_rows(*this, split[t], split[t + 1], all, x.data(), y.data(), 0); });
}

void Prolongation::apply_transpose(std::span<const double> y, std::span<double> x, unsigned threads) const {
  need(static_cast<Id>(y.size()) == rows(), "y has " + sz(y.size()) + " values for " + std::to_string(rows()) + " rows");
  need(static_cast<Id>(x.size()) == cols(), "x has " + sz(x.size()) + " values for " + std::to_string(cols()) + " columns");
  threads = threads_for(*this, threads);
  const std::vector<Id> split = detail::split_work(fine_, threads, 0, fine_.num_coarse_elements());
  std::fill(x.begin(), x.end(), 0.0);
  std::vector<std::vector<std::pair<Id, double>>> lower(threads);
  run_threads(threads, [&](unsigned t) {
    const Id c0 = owned_cols(split[t], split[t + 1])[0];
    transpose_rows(*this, split[t], split[t + 1], y.data(), 0, x.data() + c0, c0, lower[t]);
  });
  for (const auto& l : lower)  // thread order, each in its order: the serial sums
    for (const auto& [c, v] : l) x[static_cast<size_t>(c)] += v;
}

void Prolongation::apply_range(Id first, Id end, std::span<const Id> ghosts, std::span<const double> x_local,
                               std::span<double> y_owned) const {
  const auto r = owned_rows(first, end), c = owned_cols(first, end);
  need(static_cast<Id>(x_local.size()) == c[1] - c[0] + static_cast<Id>(ghosts.size()),
       "x_local has " + sz(x_local.size()) + " values for " + std::to_string(c[1] - c[0]) + " owned columns and " +
           sz(ghosts.size()) + " ghosts");
  need(static_cast<Id>(y_owned.size()) == r[1] - r[0],
       "y has " + sz(y_owned.size()) + " values for " + std::to_string(r[1] - r[0]) + " owned rows");
  need(std::is_sorted(ghosts.begin(), ghosts.end()) && (ghosts.empty() || ghosts.back() < c[0]),
       "ghost columns must be sorted and below the owned ones");
  apply_rows(*this, first, end, Columns{c[0], c[1], ghosts}, x_local.data(), y_owned.data(), r[0]);
}

void Prolongation::apply_transpose_range(Id first, Id end, std::span<const double> y_owned, std::span<double> x_owned,
                                         std::vector<std::pair<Id, double>>& lower) const {
  const auto r = owned_rows(first, end), c = owned_cols(first, end);
  need(static_cast<Id>(y_owned.size()) == r[1] - r[0],
       "y has " + sz(y_owned.size()) + " values for " + std::to_string(r[1] - r[0]) + " owned rows");
  need(static_cast<Id>(x_owned.size()) == c[1] - c[0],
       "x has " + sz(x_owned.size()) + " values for " + std::to_string(c[1] - c[0]) + " owned columns");
  transpose_rows(*this, first, end, y_owned.data(), r[0], x_owned.data(), c[0], lower);
}

}  // namespace dicer
