#include "dicer/numbering.hpp"

#include <algorithm>
#include <atomic>
#include <memory>
#include <tuple>
#include <utility>

#include "dicer/error.hpp"

namespace dicer {
namespace {

Id mul(Id a, Id b, const char* what) {
  Id r;
  if (__builtin_mul_overflow(a, b, &r))
    throw Error(ErrorKind::Overflow, std::string("fine ") + what + " count overflows 64-bit ids: " +
                                         std::to_string(a) + " x " + std::to_string(b));
  return r;
}
Id add(Id a, Id b, const char* what) {
  Id r;
  if (__builtin_add_overflow(a, b, &r))
    throw Error(ErrorKind::Overflow, std::string("fine ") + what + " count overflows 64-bit ids: " +
                                         std::to_string(a) + " + " + std::to_string(b));
  return r;
}

}  // namespace

Numbering::Numbering(const Topology& t, std::vector<Id> edge_n) : edge_n_(std::move(edge_n)) {
  const Id nv = t.num_vertices, ne = t.num_edges(), nf = t.num_faces(), nh = t.num_elements();
  if (static_cast<Id>(edge_n_.size()) != ne)
    throw Error(ErrorKind::BadInput, "interval list has " + std::to_string(edge_n_.size()) + " entries for " +
                                         std::to_string(ne) + " edges");
  DICER_ASSERT(static_cast<Id>(t.edge_owner_elem.size()) == ne && static_cast<Id>(t.face_owner_elem.size()) == nf &&
                   static_cast<Id>(t.vertex_owner_elem.size()) == nv,
               "Numbering needs a topology in owner order (to_owner_order)");
  for (Id e = 0; e < ne; ++e)
    if (edge_n_[e] < 1) throw Error(ErrorKind::BadInput, "edge " + std::to_string(e) + " has interval < 1");
  face_n_.resize(static_cast<size_t>(nf));
  for (Id f = 0; f < nf; ++f) {
    const Id* fe = &t.face_edge[4 * f];
    if (edge_n_[fe[0]] != edge_n_[fe[1]] || edge_n_[fe[2]] != edge_n_[fe[3]])
      throw Error(ErrorKind::BadInput, "face " + std::to_string(f) +
                                           ": opposite edges have different intervals (not one per sheet)");
    face_n_[f] = {edge_n_[fe[0]], edge_n_[fe[2]]};
  }
  const int epe = t.edges_per_element();
  const bool vol = t.mode == Mode::Volume;
  elem_n_.resize(static_cast<size_t>(nh));
  for (Id h = 0; h < nh; ++h) {
    const Id* ee = &t.elem_edge[h * epe];
    elem_n_[h] = vol ? std::array<Id, 3>{edge_n_[ee[0]], edge_n_[ee[4]], edge_n_[ee[8]]}
                     : std::array<Id, 3>{edge_n_[ee[0]], edge_n_[ee[2]], 1};
    // The limit every reader checks (rows.hpp): refused here, not written.
    const auto& n = elem_n_[h];
    const __int128 points = static_cast<__int128>(n[0] + 1) * (n[1] + 1) * (vol ? n[2] + 1 : 1);
    if (points > kMaxElementPoints)
      throw Error(ErrorKind::Overflow, "coarse element " + std::to_string(h) + " would have " + std::to_string(n[0]) +
                                           " x " + std::to_string(n[1]) + (vol ? " x " + std::to_string(n[2]) : "") +
                                           " fine elements, more than 2^40 grid points in one coarse element");
  }
  // Owner order: element by element, what it owns, in entity id order. The
  // owner arrays are ordered by entity id, so one cursor per kind suffices.
  vertex_node_.assign(static_cast<size_t>(nv), -1);
  edge_node_.assign(static_cast<size_t>(ne), -1);
  face_node_.assign(static_cast<size_t>(nf), -1);
  cell_node_.assign(static_cast<size_t>(nh), 0);
  node_first_.assign(static_cast<size_t>(nh), 0);
  element_first_.assign(static_cast<size_t>(nh) + 1, 0);
  Id next = 0, v = 0, e = 0, f = 0;
  for (Id h = 0; h < nh; ++h) {
    node_first_[h] = next;
    for (; v < nv && t.vertex_owner_elem[v] == h; ++v) vertex_node_[v] = next, next = add(next, 1, "node");
    for (; e < ne && t.edge_owner_elem[e] == h; ++e)
      edge_node_[e] = next, next = add(next, ids::edge_nodes(edge_n_[e]), "node");
    for (; f < nf && t.face_owner_elem[f] == h; ++f)
      face_node_[f] = next, next = add(next, mul(face_n_[f][0] - 1, face_n_[f][1] - 1, "node"), "node");
    const auto& n = elem_n_[h];
    if (vol) {
      cell_node_[h] = next;
      next = add(next, mul(mul(n[0] - 1, n[1] - 1, "node"), n[2] - 1, "node"), "node");
    } else {
      cell_node_[h] = face_node_[t.elem_face[h]];  // a quad's interior is its face
    }
    element_first_[h + 1] = add(element_first_[h], mul(mul(n[0], n[1], "element"), n[2], "element"), "element");
  }
  DICER_ASSERT(v == nv && e == ne && f == nf, "Numbering: every entity has its owner, in owner order");
  num_nodes_ = next;
}

namespace {

// The shift that gives an IdGuide over H rows and `total` ids about two
// buckets per row, and the bucket count (the last covers ids up to total).
std::pair<int, size_t> guide_shape(Id H, Id total) {
  int shift = 0;
  while ((total >> shift) > 2 * H) ++shift;
  return {shift, static_cast<size_t>((total >> shift) + 2)};
}

// Fills the node-id guide g's buckets whose start lies on page p of a
// store's elements (ids index[p] .. index[p + 1], or past the last id for
// the last page): each
// gets the last row of the page whose first id is <= its start, the value
// guide_over would give (the page's first row starts at index[p], the
// next page's above the bucket). A page whose first row disagrees with
// the index fills nothing: its searches keep the page index's way, whose
// checks report the damage.
void fill_page_buckets(const LazyIdGuide& g, const RowReader& R, const MeshTables& t, Id p) {
  const std::vector<std::int64_t>& index = t.node_index;
  auto first = [&](Id r) { return R.node_first(r); };
  const Id rpp = t.elements.rows_per_page(), lo = p * rpp, hi = std::min(t.elements.rows(), lo + rpp);
  const bool last = static_cast<size_t>(p) + 1 >= index.size();
  const Id from = index[static_cast<size_t>(p)];
  const Id to = last ? t.fine_nodes : index[static_cast<size_t>(p) + 1];
  // Rows out of order or past the next page's start (a damaged store) fill
  // nothing either: the guide and the page's search could then disagree,
  // and a query's answer would depend on whether its bucket was filled.
  bool ordered = lo < hi && from >= 0 && to >= from && first(lo) == from;
  for (Id r = lo + 1; ordered && r < hi; ++r) ordered = first(r - 1) <= first(r) && first(r) <= to;
  if (ordered) {
    for (Id r = lo; r < hi; ++r) g.first[r].store(first(r), std::memory_order_relaxed);
    const Id step = Id{1} << g.shift;
    const size_t end = last ? g.buckets : to > from ? std::min(g.buckets, static_cast<size_t>((to - 1) / step + 1)) : 0;
    Id r = lo;
    for (size_t b = static_cast<size_t>(from / step + (from % step != 0)); b < end; ++b) {
      const Id start = static_cast<Id>(b) << g.shift;
      while (r + 1 < hi && first(r + 1) <= start) ++r;
      g.row[b].store(r, std::memory_order_relaxed);
    }
  }
  g.page_done[static_cast<size_t>(p)].store(true, std::memory_order_relaxed);
}

// Last element whose column value (node_first or element_first) is <= x:
// the page index picks the page, an interpolation search the row.
Id search_elements(const MeshTables& t, Id x, bool by_node, MeshCursor& cur) {
  const RowReader R(t, cur);
  const std::vector<std::int64_t>& index = by_node ? t.node_index : t.element_index;
  const Id rpp = t.elements.rows_per_page();
  Id lo = 0, hi = t.elements.rows();  // first row with value > x lies in [lo, hi]
  RowReader::SearchHints hints;
  const RowReader::SearchHints* hinted = nullptr;
  const IdGuide& guide = by_node ? t.node_guide : t.element_guide;
  // The guide was built with the dense columns; a table written to since
  // (Table::memory() drops those) may have outgrown it: search the rows.
  const bool guided = !guide.row.empty() && t.elements.in_memory() && !t.elements.derived_columns().empty();
  if (const auto b = static_cast<std::uint64_t>(x) >> guide.shift; guided && x >= 0 && b + 1 < guide.row.size()) {
    // Rows up to row[b] start at or below b << shift <= x; row[b + 1] + 1
    // (if any) starts above (b + 1) << shift > x.
    lo = guide.row[b] + 1;
    hi = std::min(t.elements.rows(), guide.row[b + 1] + 1);
    return R.search_first(lo, hi, x, by_node) - 1;
  }
  const LazyIdGuide* lazy = by_node ? t.node_row_guide.get() : nullptr;
  if (const auto b = static_cast<std::uint64_t>(x) >> (lazy ? lazy->shift : 0); lazy && x >= 0 && b + 1 < lazy->buckets) {
    // As the in-memory guide, once both buckets are filled: a few rows'
    // values from the guide's copy (all filled: a row's page was filled
    // with its own copy), more rows by search_first if they share a page.
    const Id r0 = lazy->row[b].load(std::memory_order_relaxed), r1 = lazy->row[b + 1].load(std::memory_order_relaxed);
    if (r0 >= 0 && r1 >= 0) {
      const Id glo = r0 + 1, ghi = std::min(t.elements.rows(), r1 + 1);
      if (glo >= ghi) return r0;
      if (ghi - glo <= 4) {
        Id r = glo;
        std::int64_t v = 0;
        while (r < ghi && (v = lazy->first[r].load(std::memory_order_relaxed)) >= 0 && v <= x) ++r;
        if (r == ghi || v >= 0) return r - 1;
      }
      if (ghi - glo <= t.elements.run(glo)) return R.search_first(glo, ghi, x, by_node) - 1;
    }
  }
  if (!index.empty()) {
    // The page: from the page guide, the last page starting at or below x
    // lies in [row[k], row[k + 1]] (bucket k = x >> shift), mostly one
    // page; without a guide (or an id past it), std::upper_bound without branches: random ids make
    // each comparison a coin toss, and a mispredicted branch per level cost
    // more than the (cached) loads; cmov instead.
    const IdGuide& pages = by_node ? t.node_page_guide : t.element_page_guide;
    Id p = -1;
    if (const auto k = static_cast<std::uint64_t>(x) >> pages.shift; x >= 0 && k + 1 < pages.row.size()) {
      // The first step without a branch (whether the id lies in the
      // bucket's first page or the next is a coin toss; no page past
      // row[k + 1] starts at or below x, so no bound but the index's); a
      // second step is rare.
      p = pages.row[k];
      const Id end = static_cast<Id>(index.size()), q = std::min(p + 1, end - 1);
      p += static_cast<Id>(q > p) & static_cast<Id>(index[static_cast<size_t>(q)] <= x);
      while (p + 1 < end && index[static_cast<size_t>(p + 1)] <= x) ++p;
    } else {
      const std::int64_t* b = index.data();  // the answer lies in [b, b + len]
      for (size_t len = index.size(); len > 1;) {
        const size_t half = len / 2;
        b = b[half] <= x ? b + half : b;
        len -= half;
      }
      p = static_cast<Id>(b - index.data()) + (*b <= x) - 1;
    }
    if (p < 0) return -1;
    if (lazy && !lazy->page_done[static_cast<size_t>(p)].load(std::memory_order_relaxed))
      fill_page_buckets(*lazy, R, t, p);
    lo = p * rpp;
    hi = std::min(t.elements.rows(), lo + rpp);
    // The page's first value and the next page's (past the last page: the
    // id count) steer the search's first probe, from the index alone.
    hints.at_lo = index[p];
    hints.at_hi = static_cast<size_t>(p + 1) < index.size() ? index[p + 1] : (by_node ? t.fine_nodes : t.fine_elements);
    hinted = &hints;
  }
  if (index.empty() && hi - lo > t.elements.run(lo)) {  // paged without an index: not a store we write
    while (lo < hi) {
      const Id mid = lo + (hi - lo) / 2;
      if ((by_node ? R.node_first(mid) : R.element_first(mid)) <= x) lo = mid + 1;
      else hi = mid;
    }
    return lo - 1;
  }
  return R.search_first(lo, hi, x, by_node, hinted) - 1;
}

}  // namespace

// An IdGuide over H increasing first ids first(0..H), `total` ids in all.
template <class First>
IdGuide guide_over(Id H, Id total, First first) {
  IdGuide g;
  if (H == 0 || total <= 0) return g;
  size_t buckets;
  std::tie(g.shift, buckets) = guide_shape(H, total);
  g.row.resize(buckets);
  Id r = -1;  // the last row whose first id is <= the bucket's start (-1: none)
  for (size_t b = 0; b < buckets; ++b) {
    const Id start = static_cast<Id>(b) << g.shift;
    while (r + 1 < H && first(r + 1) <= start) ++r;
    g.row[b] = r;
  }
  return g;
}

IdGuide build_id_guide(const MeshTables& t, bool by_node) {
  MeshCursor cur;
  const RowReader R(t, cur);
  return guide_over(t.elements.rows(), by_node ? t.fine_nodes : t.fine_elements,
                    [&](Id r) { return by_node ? R.node_first(r) : R.element_first(r); });
}

IdGuide build_page_guide(const std::vector<std::int64_t>& index, Id total) {
  return guide_over(static_cast<Id>(index.size()), total, [&](Id p) { return index[static_cast<size_t>(p)]; });
}

std::shared_ptr<const LazyIdGuide> make_lazy_guide(Id rows, Id total, Id pages) {
  if (rows == 0 || total <= 0 || pages <= 0) return nullptr;
  auto g = std::make_shared<LazyIdGuide>();
  std::tie(g->shift, g->buckets) = guide_shape(rows, total);
  g->row.reset(new std::atomic<std::int64_t>[g->buckets]);
  for (size_t b = 0; b < g->buckets; ++b) g->row[b].store(-1, std::memory_order_relaxed);
  g->first.reset(new std::atomic<std::int64_t>[static_cast<size_t>(rows)]);
  for (Id r = 0; r < rows; ++r) g->first[r].store(-1, std::memory_order_relaxed);
  g->page_done.reset(new std::atomic<bool>[static_cast<size_t>(pages)]);
  for (Id p = 0; p < pages; ++p) g->page_done[static_cast<size_t>(p)].store(false, std::memory_order_relaxed);
  return g;
}

Id owner_element(const MeshTables& t, Id id, MeshCursor& cur) {
  const Id h = search_elements(t, id, true, cur);
  const RowReader R(t, cur);
  if (h < 0) R.corrupt(RowTable::Elements, 0, "no element owns node " + std::to_string(id));
  // The page index chose the page: the next row must start after the node,
  // or the index lied (a node found "in" the wrong element may still match
  // one of its corners, a right answer by accident, not by the numbering).
  // (The guide's copy of that value, where filled: the same checked bytes.)
  const LazyIdGuide* lazy = t.node_row_guide.get();
  const std::int64_t copied = lazy && h + 1 < t.elements.rows() ? lazy->first[h + 1].load(std::memory_order_relaxed) : -1;
  if (h + 1 < t.elements.rows() && (copied >= 0 ? copied : R.node_first(h + 1)) <= id)
    R.corrupt(RowTable::Elements, h + 1,
              "node " + std::to_string(id) + " lies past the element the " +
                  (t.node_index.empty() ? std::string("id search") : std::string("page index (numbering/element_page_node)")) +
                  " leads to");
  return h;
}

NodeRef locate_node(const MeshTables& t, Id id, MeshCursor& cur, ElementRow* owner_row, NodeOwner* owner) {
  // A row of our own only when the caller gives none, in a call of its
  // own: GCC 12 hoisted an optional's zero-fill (544 bytes, rep stos) above
  // the test, into every caller's query.
  if (!owner_row) {
    ElementRow local;
    return locate_node(t, id, cur, &local, owner);
  }
  const Id hid = owner_element(t, id, cur);
  ElementRow& h = *owner_row;
  RowReader(t, cur).element(hid, h);
  return owned_node(t, hid, h, id, cur, owner);
}

NodeRef owned_node(const MeshTables& t, Id hid, const ElementRow& h, Id id, MeshCursor& cur, NodeOwner* owner) {
  const bool vol = t.mode == Mode::Volume;
  const int corners = vol ? 8 : 4, edges = vol ? 12 : 4, faces = vol ? 6 : 1;
  auto at = [&](int slot, NodeRef r) {
    if (owner) *owner = NodeOwner{hid, slot};
    return r;
  };
  if (vol && id >= h.cell_node && id - h.cell_node < ids::cell_nodes(h.n))
    return at(-1, NodeRef{EntityKind::Cell, hid, ids::cell_local(id - h.cell_node, h.n)});
  for (int k = 0; k < corners; ++k)
    if (h.corner_node[k] == id) return at(k, NodeRef{EntityKind::Vertex, h.corner[k], {0, 0, 0}});
  for (int k = 0; k < edges; ++k) {
    const Id n = h.n[vol ? k / 4 : k / 2];
    if (h.owns(h.edge_node[k]) && id >= h.edge_node[k] && id - h.edge_node[k] < ids::edge_nodes(n))
      return at(k, NodeRef{EntityKind::Edge, h.edge[k], {id - h.edge_node[k] + 1, 0, 0}});
  }
  for (int k = 0; k < faces; ++k) {
    const auto [nu, nv] = face_intervals(h, k, t.mode);
    if (h.owns(h.face_node[k]) && id >= h.face_node[k] && id - h.face_node[k] < ids::face_nodes(nu, nv)) {
      const auto uv = ids::face_local(id - h.face_node[k], nu);
      return at(k, NodeRef{EntityKind::Face, h.face[k], {uv[0], uv[1], 0}});
    }
  }
  RowReader(t, cur).corrupt(RowTable::Elements, hid,
                            "node " + std::to_string(id) + " is in none of the entities the element owns");
}

Id node_id(const MeshTables& t, const NodeRef& r, MeshCursor& cur) {
  const RowReader R(t, cur);
  switch (r.kind) {
    case EntityKind::Vertex: return R.vertex(r.entity).node;
    case EntityKind::Edge: return ids::edge_node(R.edge(r.entity).node, r.local[0]);
    case EntityKind::Face: {
      const FaceRow f = R.face(r.entity);
      return ids::face_node(f.node, f.nu, r.local[0], r.local[1]);
    }
    case EntityKind::Cell: {
      const ElementRow h = R.element(r.entity);
      return ids::cell_node(h.cell_node, h.n, r.local[0], r.local[1], r.local[2]);
    }
  }
  return -1;
}

Id locate_element(const MeshTables& t, Id id, std::array<Id, 3>& ijk, MeshCursor& cur, ElementRow* row_out,
                  bool grid_only) {
  if (!row_out) {  // as in locate_node
    ElementRow local;
    return locate_element(t, id, ijk, cur, &local, grid_only);
  }
  const Id h = search_elements(t, id, false, cur);
  const RowReader R(t, cur);
  if (h < 0) R.corrupt(RowTable::Elements, 0, "no coarse element holds fine element " + std::to_string(id));
  ElementRow& row = *row_out;
  grid_only ? R.element_grid(h, row) : R.element(h, row);
  const Id l = id - row.element_first;
  if (l < 0 || l >= row.n[0] * row.n[1] * row.n[2])
    R.corrupt(RowTable::Elements, h, "fine element " + std::to_string(id) + " lies past the element's own");
  ijk = ids::element_local(l, row.n);
  return h;
}

}  // namespace dicer
