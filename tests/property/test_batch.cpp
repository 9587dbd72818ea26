// Batch iteration (batch.hpp) over random coarse meshes: consecutive id
// ranges that tile the chunk's own nodes and its elements exactly, and the
// same bits as node(id) and element(id), for every slab size, sub-range of
// coarse elements and choice of arrays.
#include <gtest/gtest.h>

#include <bit>
#include <algorithm>
#include <random>
#include <tuple>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "evaluate.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

void check_batches(const FineMesh& f, Id first, Id end, BatchOptions opt) {
  MeshCursor cur;
  const auto own = f.owned_nodes(first, end, cur);
  Id node = own[0];
  Id element = -1;
  Id prev_coarse = first - 1;
  BatchCursor c(f, first, end, opt);
  FineBatch b;
  while (c.next(b)) {
    ASSERT_GE(b.coarse_element, prev_coarse);
    ASSERT_LT(b.coarse_element, end);
    prev_coarse = b.coarse_element;
    ASSERT_EQ(b.node_begin, node) << "nodes follow on without a gap";
    ASSERT_GE(b.node_end, b.node_begin);
    node = b.node_end;
    if (element < 0) element = f.element(b.element_begin).id;
    ASSERT_EQ(b.element_begin, element) << "elements follow on without a gap";
    element = b.element_end;
    ASSERT_EQ(b.corners, f.corners());
    ASSERT_EQ(b.x.size(), opt.coords ? static_cast<size_t>(b.num_nodes()) : 0u);
    ASSERT_EQ(b.conn.size(), opt.conn ? static_cast<size_t>(b.num_elements() * b.corners) : 0u);
    for (Id id = b.node_begin; id < b.node_end && opt.coords; ++id) {
      const Vec3 p = f.node(id);
      const auto q = static_cast<size_t>(id - b.node_begin);
      ASSERT_TRUE(same_bits(p.x, b.x[q]) && same_bits(p.y, b.y[q]) && same_bits(p.z, b.z[q])) << "node " << id;
      ASSERT_EQ(owner_element(f.tables(), id, cur), b.coarse_element) << "node " << id << " in its owner's batch";
    }
    if (opt.grid) {  // every element's corners at its cell's grid points (batch.hpp's layout)
      const Id ni = b.n[0] + 1, nj = b.n[1] + 1;
      const Id planes = f.mode() == Mode::Volume ? b.num_elements() / (b.n[0] * b.n[1]) + 1 : 1;
      ASSERT_EQ(static_cast<Id>(b.grid.size()), ni * nj * planes);
      // Each row's interior one entity's ids at a constant step (batch.hpp).
      for (Id r = 0; r < nj * planes && b.n[0] >= 3; ++r) {
        const Id* row = b.grid.data() + r * ni;
        for (Id i = 2; i < b.n[0] - 1; ++i)
          ASSERT_EQ(row[i + 1] - row[i], row[2] - row[1]) << "coarse element " << b.coarse_element << " grid row " << r;
      }
      for (Id e = b.element_begin; e < b.element_end; ++e) {
        const FineElement el = f.element(e);
        const Id l = e - b.element_begin, i = l % b.n[0], j = (l / b.n[0]) % b.n[1], k = l / (b.n[0] * b.n[1]);
        for (int q = 0; q < b.corners; ++q) {
          const auto* c = kHexCorner[q];
          ASSERT_EQ(el.nodes[q], b.grid[static_cast<size_t>(i + c[0] + ni * (j + c[1] + nj * (k + c[2])))])
              << "element " << e << " corner " << q;
        }
      }
    }
    if (opt.lines) {  // each element's corners where its cell's grid rows put them (batch.hpp's lines)
      const Id n0 = b.n[0], nj = b.n[1] + 1;
      const Id planes = f.mode() == Mode::Volume ? b.num_elements() / (b.n[0] * b.n[1]) + 1 : 1;
      for (const auto* v : {&b.lines.start, &b.lines.first, &b.lines.step, &b.lines.end})
        ASSERT_EQ(static_cast<Id>(v->size()), nj * planes);
      for (Id r = 0; r < nj * planes; ++r) {
        if (n0 < 3) {
          ASSERT_EQ(b.lines.step[r], 0) << "row " << r;
        }
        if (n0 == 1) {
          ASSERT_EQ(b.lines.first[r], b.lines.end[r]) << "row " << r;
        }
      }
      auto id_at = [&](Id i, Id r) {
        return i == 0 ? b.lines.start[r] : i == n0 ? b.lines.end[r] : b.lines.first[r] + (i - 1) * b.lines.step[r];
      };
      for (Id e = b.element_begin; e < b.element_end; ++e) {
        const FineElement el = f.element(e);
        const Id l = e - b.element_begin, i = l % n0, j = (l / n0) % b.n[1], k = l / (n0 * b.n[1]);
        for (int q = 0; q < b.corners; ++q) {
          const auto* c = kHexCorner[q];
          ASSERT_EQ(el.nodes[q], id_at(i + c[0], j + c[1] + nj * (k + c[2]))) << "element " << e << " corner " << q;
        }
      }
    } else {
      ASSERT_TRUE(b.lines.start.empty() && b.lines.first.empty() && b.lines.step.empty() && b.lines.end.empty());
    }
    for (Id e = b.element_begin; e < b.element_end && opt.conn; ++e) {
      const FineElement el = f.element(e);
      ASSERT_EQ(el.coarse_element, b.coarse_element);
      for (int q = 0; q < b.corners; ++q)
        ASSERT_EQ(el.nodes[q], b.conn[static_cast<size_t>((e - b.element_begin) * b.corners + q)]) << "element " << e;
    }
  }
  EXPECT_EQ(node, own[1]) << "the batches end where the chunk's own nodes end";
  if (first < end) {
    // Elements [first fine element of `first`, first fine element of `end`).
    std::array<Id, 3> ijk;
    Id lo = 0, hi = f.num_elements();
    for (Id e = 0; e < f.num_elements(); ++e) {
      if (f.locate_element(e, ijk, cur) == first) {
        lo = e;
        break;
      }
    }
    for (Id e = lo; e < f.num_elements(); ++e)
      if (f.locate_element(e, ijk, cur) >= end) {
        hi = e;
        break;
      }
    EXPECT_EQ(element, hi) << "the batches end where the chunk's elements end";
    EXPECT_GE(lo, 0);
  }
}

}  // namespace

TEST(Batches, TileTheChunkInIdOrderWithTheBitsOfNodeAndElement) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 3; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + trial, spec.b = 2, spec.c = 1 + trial % 2, spec.blocks = 2;
    const CoarseMesh m = test::random_box(spec, rng);
    IntervalRequest req;
    req.global = 3;
    req.sheets = {{0, 1}, {1, 4}, {2, 2}};
    const FineMesh f = FineMesh::dice(m, req);
    const Id H = f.num_coarse_elements();
    for (const Id slab : {Id{1}, Id{30}, kCursorSlabPoints}) {
      // (coords, conn, grid, lines): every array alone and together.
      for (const auto& [coords, conn, grid, lines] :
           {std::tuple{true, true, false, false}, std::tuple{true, false, true, false},
            std::tuple{false, true, false, false}, std::tuple{false, false, true, false},
            std::tuple{true, true, true, true}, std::tuple{true, false, false, false},
            std::tuple{true, false, false, true}, std::tuple{false, false, false, true}}) {
        BatchOptions opt;
        opt.coords = coords, opt.conn = conn, opt.slab_points = slab, opt.grid = grid, opt.lines = lines;
        check_batches(f, 0, H, opt);
        check_batches(f, 1, H - 1, opt);
        check_batches(f, H / 2, H / 2, opt);
      }
    }
  }
}

// Rows past the kernels' vector widths (progression_rows: 4 ids a store;
// the patch kernels: blocks of 8): intervals 9, 11 and 17, whose rows of
// 8, 10 and 16 points take more than one store each.
TEST(Batches, LongRowsToo) {
  std::mt19937_64 rng(13);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 1, spec.c = 1;
  const CoarseMesh m = test::random_box(spec, rng);
  IntervalRequest req;
  req.global = 11;
  req.sheets = {{0, 9}, {1, 17}};
  const FineMesh f = FineMesh::dice(m, req);
  for (const auto& [coords, conn, grid] : {std::tuple{true, true, true}, std::tuple{true, false, false}}) {
    BatchOptions opt;
    opt.coords = coords, opt.conn = conn, opt.grid = grid, opt.lines = grid;
    check_batches(f, 0, f.num_coarse_elements(), opt);
  }
}

// One straight coarse hex, which owns every entity, at interval 3: 4
// points a face, so a patch's slack (up to 7 values) covers the next
// face whole.
namespace {
FineMesh one_hex_at_interval_3() {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = spec.b = spec.c = 1;
  IntervalRequest req;
  req.global = 3;
  return FineMesh::dice(test::random_box(spec, rng), req);
}
}  // namespace

// A straight hex's owned faces and edges written where the batch wants
// them (detail::OwnedPlaces), here faces in the reverse of their local
// order and an edge right after the last: the faces must be filled in
// address order and before the edges, or a face's slack overwrites what
// was written after it. (Our own topology numbers an owner's entities in
// that order, so the batch tests above never see another.) Bits equal to
// the scratch path's.
TEST(Batches, PlacedFacesInAnyOrderKeepTheirPoints) {
  const FineMesh f = one_hex_at_interval_3();
  MeshCursor cur;
  const detail::Evaluator E(f.tables(), cur);
  const ElementRow h = E.R.element(0);
  ASSERT_FALSE(h.curved());
  FineBlock ref, placed;
  detail::element_boundary(E, h, 0, ref.scratch);
  const size_t pts = 4, edge_pts = 2;
  std::vector<double> buf[3];
  detail::OwnedPlaces to;
  for (int d = 0; d < 3; ++d) {
    buf[d].assign(6 * pts + edge_pts + detail::kPatchSlack, -1.0);
    for (int lf = 0; lf < 6; ++lf) to.face[lf][d] = buf[d].data() + (5 - lf) * pts;
    to.edge[0][d] = buf[d].data() + 6 * pts;  // an edge right after the last face: within its slack
  }
  const bool want_edge[12] = {true}, want_face[6] = {true, true, true, true, true, true};
  detail::element_boundary(E, h, 0, placed.scratch, want_edge, want_face, &to);
  for (int d = 0; d < 3; ++d) {
    for (int lf = 0; lf < 6; ++lf) {
      ASSERT_EQ(ref.scratch.face[lf][d].size(), pts + detail::kPatchSlack);
      for (size_t q = 0; q < pts; ++q)
        ASSERT_TRUE(same_bits(to.face[lf][d][q], ref.scratch.face[lf][d][q])) << "face " << lf << " coordinate " << d
                                                                               << " point " << q;
    }
    for (size_t q = 0; q < edge_pts; ++q)
      ASSERT_TRUE(same_bits(to.edge[0][d][q], ref.scratch.edge[0][d][q])) << "edge 0 coordinate " << d << " point " << q;
  }
}

// A row whose owned entities overlap (two faces at one id, a gap where
// the second was: every range in bounds, the counts adding up) is
// corrupt: the batch would otherwise hand out whatever the gap held.
TEST(Batches, OverlappingOwnedEntitiesAreCorrupt) {
  const FineMesh f = one_hex_at_interval_3();
  MeshTables t = f.tables();
  MeshCursor cur;
  ElementRow h = RowReader(t, cur).element(0);
  ASSERT_TRUE(h.owns(h.face_node[0]) && h.owns(h.face_node[1]));
  h.face_node[1] = h.face_node[0];
  write_row(t, 0, h);
  const FineMesh g(f.info(), std::move(t));
  BatchCursor c(g);
  FineBatch b;
  try {
    while (c.next(b)) {
    }
    ADD_FAILURE() << "a row with overlapping owned entities was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Corrupt) << e.what();
    EXPECT_NE(std::string(e.what()).find("share node ids"), std::string::npos) << e.what();
  }
}

TEST(Batches, SurfaceMeshesToo) {
  std::mt19937_64 rng(11);
  const CoarseMesh m = test::random_quad_sheet(4, 3, true, rng);
  IntervalRequest req;
  req.global = 3;
  const FineMesh f = FineMesh::dice(m, req);
  for (const auto& [coords, conn, grid] : {std::tuple{true, true, false}, std::tuple{false, true, false},
                                           std::tuple{true, false, false}, std::tuple{true, false, true},
                                           std::tuple{false, false, true}}) {
    BatchOptions opt;
    opt.coords = coords, opt.conn = conn, opt.grid = grid, opt.lines = !conn;
    check_batches(f, 0, f.num_coarse_elements(), opt);
    check_batches(f, 2, 5, opt);
  }
}

// Batches from any layer of any element (first_layer, what the cursors
// use), on elements one and two intervals thin along each axis: the
// coordinates written straight into the batch, the connectivity, the grid
// and its lines equal node(id) and element(id).
TEST(Batches, FromAnyLayerOfThinElements) {
  std::mt19937_64 rng(29);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 2, spec.c = 2;
  for (const auto& sheets : {std::vector<std::pair<Id, Id>>{{0, 1}, {1, 2}, {2, 3}},
                             std::vector<std::pair<Id, Id>>{{0, 3}, {1, 1}, {2, 1}}}) {
    IntervalRequest req;
    req.global = 4;
    req.sheets = sheets;
    const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
    FineBatch b;
    for (Id h = 0; h < f.num_coarse_elements(); ++h) {
      BatchCursor probe(f, h, h + 1);
      ASSERT_TRUE(probe.next(b));
      const std::array<Id, 3> n = b.n;
      for (Id layer = 0; layer < n[2]; ++layer)
        for (const Id slab : {Id{1}, Id{60}}) {
          BatchOptions opt;
          opt.first_layer = layer, opt.slab_points = slab, opt.grid = true, opt.lines = true;
          BatchCursor c(f, h, h + 1, opt);
          while (c.next(b)) {
            for (Id id = b.node_begin; id < b.node_end; ++id) {
              const Vec3 p = f.node(id);
              const auto q = static_cast<size_t>(id - b.node_begin);
              ASSERT_TRUE(same_bits(p.x, b.x[q]) && same_bits(p.y, b.y[q]) && same_bits(p.z, b.z[q]))
                  << "element " << h << " layer " << layer << " node " << id;
            }
            const Id ni = b.n[0] + 1, nj = b.n[1] + 1;
            for (Id e = b.element_begin; e < b.element_end; ++e) {
              const FineElement el = f.element(e);
              const Id l = e - b.element_begin, i = l % b.n[0], j = (l / b.n[0]) % b.n[1], k = l / (b.n[0] * b.n[1]);
              for (int q = 0; q < 8; ++q) {
                ASSERT_EQ(el.nodes[q], b.conn[static_cast<size_t>(8 * l + q)]) << "element " << e;
                const auto* c3 = kHexCorner[q];
                ASSERT_EQ(el.nodes[q], b.grid[static_cast<size_t>(i + c3[0] + ni * (j + c3[1] + nj * (k + c3[2])))]);
                const auto r = static_cast<size_t>(j + c3[1] + nj * (k + c3[2]));
                const Id at = i + c3[0];
                ASSERT_EQ(el.nodes[q], at == 0        ? b.lines.start[r]
                                       : at == b.n[0] ? b.lines.end[r]
                                                      : b.lines.first[r] + (at - 1) * b.lines.step[r])
                    << "element " << e << " corner " << q << " from the lines";
              }
            }
          }
        }
    }
  }
}

TEST(Batches, RangeOutsideTheMeshIsAUsageError) {
  std::mt19937_64 rng(3);
  const FineMesh f = FineMesh::dice(test::random_box({}, rng), IntervalRequest{});
  EXPECT_THROW(BatchCursor(f, 0, f.num_coarse_elements() + 1), Error);
  EXPECT_THROW(BatchCursor(f, 2, 1), Error);
  EXPECT_THROW(BatchCursor(f, -1, 1), Error);
}

// The cursors run on the batches and may start anywhere: inside a coarse
// element's own boundary nodes, inside its interior (mid-slab), at the last
// node or element; each gives node(id) and element(id), bit for bit.
TEST(Batches, CursorsFromAnyIdEqualTheQueries) {
  std::mt19937_64 rng(21);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 3, spec.c = 2;
  IntervalRequest req;
  req.global = 4;
  req.sheets = {{0, 5}, {1, 3}};
  const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
  std::uniform_int_distribution<Id> pick_node(0, f.num_nodes() - 1), pick_element(0, f.num_elements() - 1);
  for (const Id slab : {Id{1}, Id{40}, kCursorSlabPoints}) {
    for (int trial = 0; trial < 12; ++trial) {
      const Id a = trial == 0 ? f.num_nodes() - 1 : pick_node(rng), b = std::min(f.num_nodes(), a + 1 + pick_node(rng) % 400);
      NodeCursor c(f, a, b, slab);
      Id id, want = a;
      Vec3 p;
      while (c.next(id, p)) {
        ASSERT_EQ(id, want++);
        const Vec3 q = f.node(id);
        ASSERT_TRUE(same_bits(p.x, q.x) && same_bits(p.y, q.y) && same_bits(p.z, q.z)) << "node " << id << " from " << a;
      }
      EXPECT_EQ(want, b);
      const Id e0 = trial == 0 ? f.num_elements() - 1 : pick_element(rng),
               e1 = std::min(f.num_elements(), e0 + 1 + pick_element(rng) % 300);
      ElementCursor ec(f, e0, e1, slab);
      FineElement el;
      Id next = e0;
      while (ec.next(el)) {
        ASSERT_EQ(el.id, next++);
        const FineElement ref = f.element(el.id);
        ASSERT_EQ(el.nodes, ref.nodes) << "element " << el.id << " from " << e0;
        ASSERT_EQ(el.ijk, ref.ijk);
        ASSERT_EQ(el.coarse_element, ref.coarse_element);
        ASSERT_EQ(el.block, ref.block);
      }
      EXPECT_EQ(next, e1);
    }
  }
}

// nodes(ids) / elements(ids): a size mismatch, and a bad id anywhere in the
// list, give the Usage error of one call for the lowest bad id; no ids is
// no work.
TEST(BatchedQueries, BadIdsAndSizesAreUsageErrors) {
  std::mt19937_64 rng(5);
  const FineMesh f = FineMesh::dice(test::random_box({}, rng), IntervalRequest{});
  MeshCursor cur;
  std::vector<Vec3> pts(3);
  std::vector<FineElement> els(3);
  auto message = [&](auto&& call) -> std::string {
    try {
      call();
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Usage);
      return e.what();
    }
    return "no error";
  };
  const std::vector<Id> nodes_bad = {2, f.num_nodes(), -1};
  EXPECT_NE(message([&] { f.nodes(nodes_bad, pts, cur); }).find("node id -1 is out of range"), std::string::npos);
  const std::vector<Id> nodes_past = {f.num_nodes() + 5, 0, f.num_nodes()};
  EXPECT_NE(message([&] { f.nodes(nodes_past, pts, cur); }).find("node id " + std::to_string(f.num_nodes()) + " is"),
            std::string::npos);
  const std::vector<Id> elements_bad = {0, f.num_elements(), 1};
  EXPECT_NE(message([&] { f.elements(elements_bad, els, cur); })
                .find("element id " + std::to_string(f.num_elements()) + " is out of range"),
            std::string::npos);
  const std::vector<Id> two = {0, 1};
  EXPECT_NE(message([&] { f.nodes(two, pts, cur); }).find("2 ids but room for 3 results"), std::string::npos);
  EXPECT_NE(message([&] { f.elements(two, els, cur); }).find("2 ids but room for 3 results"), std::string::npos);
  f.nodes({}, {}, cur);
  f.elements({}, {}, cur);
  // A sorted list with repeats (no index sort) gives node(id)'s bits.
  const std::vector<Id> sorted = {0, 0, f.num_nodes() / 2, f.num_nodes() - 1};
  std::vector<Vec3> four(4);
  f.nodes(sorted, four, cur);
  for (size_t q = 0; q < 4; ++q) {
    const Vec3 p = f.node(sorted[q]);
    EXPECT_TRUE(same_bits(p.x, four[q].x) && same_bits(p.y, four[q].y) && same_bits(p.z, four[q].z)) << q;
  }
}

// Ids over more than one radix digit (visit_order sorts 11 bits a pass):
// every id of a 4,913-node mesh, shuffled, gives node(id)'s bits.
TEST(BatchedQueries, ShuffledIdsOverSeveralSortPasses) {
  std::mt19937_64 rng(17);
  test::BoxSpec spec;
  spec.a = 4, spec.b = 4, spec.c = 4;
  IntervalRequest req;
  req.global = 4;
  const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
  ASSERT_GT(f.num_nodes(), Id{1} << 12);
  std::vector<Id> ids(static_cast<size_t>(f.num_nodes()));
  for (size_t q = 0; q < ids.size(); ++q) ids[q] = static_cast<Id>(q);
  std::shuffle(ids.begin(), ids.end(), rng);
  std::vector<Vec3> pts(ids.size());
  MeshCursor cur;
  f.nodes(ids, pts, cur);
  for (size_t q = 0; q < ids.size(); ++q) {
    const Vec3 p = f.node(ids[q]);
    ASSERT_TRUE(same_bits(p.x, pts[q].x) && same_bits(p.y, pts[q].y) && same_bits(p.z, pts[q].z)) << ids[q];
  }
}

// A hex cell's corner ids by region maps (Evaluator::hex_cell_node_ids,
// what element(id) uses for cells that touch the boundary) against each
// corner's own entity lookup (grid_node_id), for every cell of every
// element of random boxes whose hexes are numbered at random (every face
// code, reversed edges) and whose intervals differ per axis (1 included:
// a cell touching both sides of an axis).
TEST(Batches, HexCellCornerIdsEqualEachCornersOwnLookup) {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 4; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + trial % 2, spec.b = 2, spec.c = 2;
    const CoarseMesh m = test::random_box(spec, rng);
    IntervalRequest req;
    req.global = 3 + trial;
    req.sheets = {{0, 1}, {1, 2 + trial}};
    const FineMesh f = FineMesh::dice(m, req);
    MeshCursor cur;
    const detail::Evaluator E(f.tables(), cur);
    Id cells = 0;
    for (Id hid = 0; hid < f.num_coarse_elements(); ++hid) {
      const ElementRow h = E.R.element(hid);
      for (Id k = 0; k < h.n[2]; ++k)
        for (Id j = 0; j < h.n[1]; ++j)
          for (Id i = 0; i < h.n[0]; ++i, ++cells) {
            Id got[8];
            E.hex_cell_node_ids(h, i, j, k, got);
            for (int q = 0; q < 8; ++q) {
              const auto* c = kHexCorner[q];
              ASSERT_EQ(got[q], E.grid_node_id(h, i + c[0], j + c[1], k + c[2]))
                  << "coarse element " << hid << " cell (" << i << ", " << j << ", " << k << ") corner " << q;
            }
          }
    }
    EXPECT_EQ(cells, f.num_elements());
  }
}
