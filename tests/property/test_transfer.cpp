// Transfer operators between nested dicings (transfer.hpp), on random
// coarse meshes with random per-sheet intervals and factors, volume and
// surface, through stores on disk.
//
// Independent expectations: P's rows are recomputed here from every coarse
// element holding the node (not only its owner), with long double
// per-axis fractions and the ids of fill_block; P must reproduce linear
// functions of the physical coordinates (TFI of straight-edged elements is
// their trilinear map, so nested grids are sub-grids of it), and every
// trilinear function on axis-aligned boxes; a unit row must join two nodes
// with the same coordinate bits, and every coarse node must have exactly
// one such twin. The matrix-free apply is checked against the rows
// assembled here, P^T against the transpose assembled here.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "dicer/transfer.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

bool same_bits(const Vec3& a, const Vec3& b) {
  return std::bit_cast<std::uint64_t>(a.x) == std::bit_cast<std::uint64_t>(b.x) &&
         std::bit_cast<std::uint64_t>(a.y) == std::bit_cast<std::uint64_t>(b.y) &&
         std::bit_cast<std::uint64_t>(a.z) == std::bit_cast<std::uint64_t>(b.z);
}
bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

using Row = std::vector<std::pair<Id, double>>;

// Every row of P from its cursor, in id order (checked: consecutive batches
// tiling [0, rows)).
std::vector<Row> rows_of(const Prolongation& p, Id slab_rows = kCursorSlabPoints) {
  std::vector<Row> out;
  ProlongationCursor c(p, 0, -1, slab_rows);
  ProlongationBatch b;
  Id prev_element = -1;
  while (c.next(b)) {
    EXPECT_EQ(b.row_begin, static_cast<Id>(out.size())) << "batches follow on without a gap";
    EXPECT_GE(b.coarse_element, prev_element);
    prev_element = b.coarse_element;
    EXPECT_EQ(b.offsets.size(), static_cast<size_t>(b.num_rows() + 1));
    EXPECT_EQ(b.offsets[0], 0);
    for (Id r = 0; r < b.num_rows(); ++r) {
      Row row;
      for (Id e = b.offsets[r]; e < b.offsets[r + 1]; ++e) row.emplace_back(b.cols[e], b.weights[e]);
      out.push_back(row);
    }
  }
  EXPECT_EQ(static_cast<Id>(out.size()), p.rows());
  return out;
}

// The row of fine grid point (I, J, K) of coarse element h, computed here:
// per axis the coarse-store position X = I nc / nf, its cell and fraction
// in long double, the ids of both grids from fill_block.
Row expected_row(const FineBlock& fb, const FineBlock& cb, Id I, Id J, Id K, bool vol) {
  const Id P[3] = {I, J, K};
  Id cell[3];
  long double frac[3];
  for (int a = 0; a < 3; ++a) {
    if (!vol && a == 2) {
      cell[a] = 0, frac[a] = 0;
      continue;
    }
    const long double X = static_cast<long double>(P[a]) * cb.n[a] / fb.n[a];
    cell[a] = std::min<Id>(static_cast<Id>(std::floor(X)), cb.n[a] - 1);
    frac[a] = X - cell[a];
  }
  Row row;
  for (int dz = 0; dz < (vol ? 2 : 1); ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const long double w = (dx ? frac[0] : 1 - frac[0]) * (dy ? frac[1] : 1 - frac[1]) * (dz ? frac[2] : 1 - frac[2]);
        if (w == 0) continue;
        row.emplace_back(cb.node_id[static_cast<size_t>(cb.point_index(cell[0] + dx, cell[1] + dy, cell[2] + dz))],
                         static_cast<double>(w));
      }
  return row;
}

struct Pair {
  std::string coarse_path, fine_path;
  std::vector<Id> coarse_n, fine_n;
};

// One random coarse mesh diced twice into stores: per sheet a coarse
// interval in 1..3 and a factor in 1..3.
Pair nested_pair(const CoarseMesh& mesh, std::mt19937_64& rng, const test::TempDir& tmp, int trial) {
  IntervalRequest a;
  a.global = 1;
  const FineMesh probe = FineMesh::dice(mesh, a);
  Pair out;
  IntervalRequest rc, rf;
  std::uniform_int_distribution<Id> n(1, 3), m(1, 3);
  for (Id s = 0; s < probe.info().sheets; ++s) {
    const Id nc = n(rng), f = m(rng);
    rc.sheets.emplace_back(s, nc), rf.sheets.emplace_back(s, nc * f);
    out.coarse_n.push_back(nc), out.fine_n.push_back(nc * f);
  }
  out.coarse_path = tmp.path("coarse" + std::to_string(trial) + ".dice.h5");
  out.fine_path = tmp.path("fine" + std::to_string(trial) + ".dice.h5");
  write_store(FineMesh::dice(mesh, rc), out.coarse_path);
  write_store(FineMesh::dice(mesh, rf), out.fine_path);
  return out;
}

CoarseMesh random_mesh(int trial, std::mt19937_64& rng) {
  if (trial % 3 == 2) return test::random_quad_sheet(2 + trial % 3, 2 + trial % 2, true, rng);
  test::BoxSpec spec;
  spec.a = 2 + trial % 2, spec.b = 1 + trial % 3, spec.c = 2;
  spec.blocks = 1 + trial % 2;
  return test::random_box(spec, rng);
}

// Values of a function at every node of a mesh, by node(id).
template <class F>
std::vector<double> at_nodes(const FineMesh& m, F&& f) {
  std::vector<double> v(static_cast<size_t>(m.num_nodes()));
  MeshCursor cur;
  for (Id id = 0; id < m.num_nodes(); ++id) v[static_cast<size_t>(id)] = f(m.node(id, cur));
  return v;
}

// A random nested pair (trial `trial` of random_mesh, seed `seed`), opened
// from its stores through small page caches.
struct Opened {
  test::TempDir tmp;
  std::mt19937_64 rng;
  Pair pair;
  FineMesh coarse, fine;
  Opened(int trial, unsigned seed) : rng(seed), pair(nested_pair(random_mesh(trial, rng), rng, tmp, trial)) {
    coarse = read_store(pair.coarse_path, StoreOptions{4ull << 20, 2});
    fine = read_store(pair.fine_path, StoreOptions{4ull << 20, 2});
  }
};

class RandomNested : public ::testing::TestWithParam<int> {};

TEST_P(RandomNested, RowsAreTheQ1WeightsOfTheCellAndReproduceLinearFunctions) {
  const int trial = GetParam();
  Opened o(trial, 1000 + trial);
  const FineMesh &coarse = o.coarse, &fine = o.fine;
  auto& rng = o.rng;
  const bool vol = fine.mode() == Mode::Volume;
  const Nesting n = check_nesting(coarse, fine);
  ASSERT_TRUE(n.nested) << n.message;
  EXPECT_EQ(n.rows, fine.num_nodes());
  EXPECT_EQ(n.cols, coarse.num_nodes());
  const Prolongation p(coarse, fine);
  const auto rows = rows_of(p, trial % 2 ? 7 : kCursorSlabPoints);  // small slabs too

  // Every row: at most 8 (4) entries in (0, 1], summing to 1; the count the
  // tables predict.
  Id nnz = 0, unit = 0;
  for (const Row& r : rows) {
    ASSERT_GE(r.size(), 1u);
    ASSERT_LE(static_cast<int>(r.size()), vol ? 8 : 4);
    double sum = 0;
    for (const auto& [c, w] : r) {
      ASSERT_GE(c, 0);
      ASSERT_LT(c, p.cols());
      ASSERT_GT(w, 0.0);
      ASSERT_LE(w, 1.0);
      sum += w;
    }
    ASSERT_NEAR(sum, 1.0, 1e-15);
    nnz += static_cast<Id>(r.size());
    unit += r.size() == 1;
  }
  EXPECT_EQ(nnz, p.nonzeros());

  // The same row from every coarse element holding the node, in its own
  // frame (owners and non-owners alike): P is well defined, and the rows
  // the cursor emitted (from owners only) are those.
  std::vector<char> seen(rows.size(), 0);
  FineBlock fb, cb;
  for (Id h = 0; h < fine.num_coarse_elements(); ++h) {
    fine.fill_block(h, fb, true);
    coarse.fill_block(h, cb, true);
    for (Id K = 0; K <= (vol ? fb.n[2] : 0); ++K)
      for (Id J = 0; J <= fb.n[1]; ++J)
        for (Id I = 0; I <= fb.n[0]; ++I) {
          const Id id = fb.node_id[static_cast<size_t>(fb.point_index(I, J, K))];
          const Row want = expected_row(fb, cb, I, J, K, vol);
          const Row& got = rows[static_cast<size_t>(id)];
          ASSERT_EQ(got.size(), want.size()) << "node " << id << " seen from coarse element " << h;
          std::map<Id, double> g(got.begin(), got.end());
          for (const auto& [c, w] : want) {
            ASSERT_TRUE(g.count(c)) << "node " << id << " lacks column " << c;
            ASSERT_NEAR(g[c], w, 2e-16) << "node " << id << " column " << c;
          }
          seen[static_cast<size_t>(id)] = 1;
        }
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(rows.size()));

  // Unit rows join nodes with the same bits, and every coarse node has
  // exactly one fine twin.
  std::vector<int> twins(static_cast<size_t>(p.cols()), 0);
  MeshCursor cc, fc;
  for (Id r = 0; r < p.rows(); ++r) {
    const Row& row = rows[static_cast<size_t>(r)];
    if (row.size() != 1) continue;
    ASSERT_EQ(row[0].second, 1.0);
    ASSERT_TRUE(same_bits(fine.node(r, fc), coarse.node(row[0].first, cc)))
        << "fine node " << r << " and coarse node " << row[0].first;
    ++twins[static_cast<size_t>(row[0].first)];
  }
  EXPECT_EQ(unit, p.cols());
  EXPECT_TRUE(std::all_of(twins.begin(), twins.end(), [](int t) { return t == 1; }));

  // Linear functions of the physical coordinates, to 1e-12 relative.
  for (int k = 0; k < 3; ++k) {
    std::uniform_real_distribution<double> u(-2, 2);
    const double a = u(rng), b = u(rng), c = u(rng), d = u(rng);
    auto f = [&](const Vec3& x) { return a + b * x.x + c * x.y + d * x.z; };
    const auto xc = at_nodes(coarse, f), yf = at_nodes(fine, f);
    std::vector<double> y(yf.size());
    p.apply(xc, y, 1 + k % 2);
    double worst = 0, scale = 0;
    for (size_t i = 0; i < y.size(); ++i) worst = std::max(worst, std::fabs(y[i] - yf[i])), scale = std::max(scale, std::fabs(yf[i]));
    EXPECT_LE(worst, 1e-12 * scale) << "linear function " << k;
  }
}

TEST_P(RandomNested, MatrixFreeEqualsAssembledAndIsTheSameForEveryThreadCountAndRange) {
  const int trial = GetParam();
  Opened o(trial, 2000 + trial);
  const FineMesh &coarse = o.coarse, &fine = o.fine;
  auto& rng = o.rng;
  const Prolongation p(coarse, fine);
  const auto rows = rows_of(p);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> x(static_cast<size_t>(p.cols())), y(static_cast<size_t>(p.rows()));
  for (double& v : x) v = u(rng);
  for (double& v : y) v = u(rng);

  // P x against the assembled rows (same entry order: the same bits), P^T y
  // against the assembled transpose (another order: 1e-14).
  std::vector<double> px(y.size()), ptx(x.size(), 0.0), want_px(y.size()), want_pty(x.size(), 0.0);
  for (size_t r = 0; r < rows.size(); ++r) {
    double s = 0;
    for (const auto& [c, w] : rows[r]) s += w * x[static_cast<size_t>(c)], want_pty[static_cast<size_t>(c)] += w * y[r];
    want_px[r] = s;
  }
  p.apply(x, px, 1);
  for (size_t r = 0; r < px.size(); ++r) ASSERT_TRUE(same_bits(px[r], want_px[r])) << "row " << r;
  std::vector<double> pty(x.size());
  p.apply_transpose(y, pty, 1);
  double worst = 0, scale = 0;
  for (size_t c = 0; c < pty.size(); ++c)
    worst = std::max(worst, std::fabs(pty[c] - want_pty[c])), scale = std::max(scale, std::fabs(want_pty[c]));
  EXPECT_LE(worst, 1e-14 * scale);

  // Threads: the same bits, for P and P^T.
  for (unsigned t : {2u, 3u, 5u}) {
    std::vector<double> a(y.size()), b(x.size());
    p.apply(x, a, t);
    p.apply_transpose(y, b, t);
    for (size_t r = 0; r < a.size(); ++r) ASSERT_TRUE(same_bits(a[r], px[r])) << t << " threads, row " << r;
    for (size_t c = 0; c < b.size(); ++c) ASSERT_TRUE(same_bits(b[c], pty[c])) << t << " threads, column " << c;
  }

  // Ranges (an MPI rank's view): each range applies its rows from its owned
  // columns and ghosts; P^T shares go down to the owners, ranges in order.
  const Id H = fine.num_coarse_elements();
  std::vector<Id> cut = {0, H};
  std::uniform_int_distribution<Id> pick(0, H);
  for (int k = 0; k < 3; ++k) cut.push_back(pick(rng));
  std::sort(cut.begin(), cut.end());
  std::vector<double> by_range(y.size()), t_range(x.size(), 0.0);
  std::vector<std::vector<std::pair<Id, double>>> lower(cut.size());
  for (size_t q = 0; q + 1 < cut.size(); ++q) {
    const Id a = cut[q], b = cut[q + 1];
    const auto r = p.owned_rows(a, b), c = p.owned_cols(a, b);
    const std::vector<Id> ghosts = p.ghost_cols(a, b);
    ASSERT_TRUE(std::is_sorted(ghosts.begin(), ghosts.end()));
    std::vector<double> xl(x.begin() + c[0], x.begin() + c[1]);
    for (Id g : ghosts) xl.push_back(x[static_cast<size_t>(g)]);
    p.apply_range(a, b, ghosts, xl, std::span<double>(by_range).subspan(static_cast<size_t>(r[0]), static_cast<size_t>(r[1] - r[0])));
    p.apply_transpose_range(a, b, std::span<const double>(y).subspan(static_cast<size_t>(r[0]), static_cast<size_t>(r[1] - r[0])),
                            std::span<double>(t_range).subspan(static_cast<size_t>(c[0]), static_cast<size_t>(c[1] - c[0])),
                            lower[q]);
    for (const auto& [col, v] : lower[q]) {
      ASSERT_LT(col, c[0]) << "a share goes to an earlier owner";
      ASSERT_TRUE(std::binary_search(ghosts.begin(), ghosts.end(), col)) << "a share's column is a ghost";
    }
  }
  for (const auto& l : lower)
    for (const auto& [col, v] : l) t_range[static_cast<size_t>(col)] += v;
  for (size_t r = 0; r < px.size(); ++r) ASSERT_TRUE(same_bits(by_range[r], px[r])) << "row " << r;
  for (size_t c = 0; c < pty.size(); ++c) ASSERT_TRUE(same_bits(t_range[c], pty[c])) << "column " << c;
}

INSTANTIATE_TEST_SUITE_P(Transfer, RandomNested, ::testing::Range(0, 9));

// Coincident nodes of nested stores: the same bits on every access path of
// each store (random access, blocks, batches, node cursor, export chunks).
TEST(Transfer, CoincidentNodesAreBitIdenticalOnEveryAccessPath) {
  std::mt19937_64 rng(31);
  test::TempDir tmp;
  test::BoxSpec spec;
  spec.a = 3, spec.b = 2, spec.c = 2;
  const Pair pair = nested_pair(test::random_box(spec, rng), rng, tmp, 0);
  const FineMesh coarse = read_store(pair.coarse_path, StoreOptions{2ull << 20, 1});
  const FineMesh fine = read_store(pair.fine_path, StoreOptions{2ull << 20, 1});
  const Prolongation p(coarse, fine);
  std::map<Id, Id> twin;  // fine -> coarse, from the unit rows
  for (Id r = 0; const Row& row : rows_of(p)) {
    if (row.size() == 1) twin[r] = row[0].first;
    ++r;
  }
  ASSERT_EQ(static_cast<Id>(twin.size()), coarse.num_nodes());
  // Coordinates of every node of a mesh by each path.
  auto by_batches = [](const FineMesh& m) {
    std::vector<Vec3> v(static_cast<size_t>(m.num_nodes()));
    BatchCursor c(m, 0, -1, BatchOptions{true, false, 50, 0});
    for (FineBatch b; c.next(b);)
      for (Id i = 0; i < b.num_nodes(); ++i) v[static_cast<size_t>(b.node_begin + i)] = {b.x[i], b.y[i], b.z[i]};
    return v;
  };
  auto by_blocks = [](const FineMesh& m) {
    std::vector<Vec3> v(static_cast<size_t>(m.num_nodes()));
    FineBlock b;
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b, true);
      for (Id g = 0; g < b.num_points(); ++g) v[static_cast<size_t>(b.node_id[g])] = {b.x[g], b.y[g], b.z[g]};
    }
    return v;
  };
  auto by_cursor = [](const FineMesh& m) {
    std::vector<Vec3> v(static_cast<size_t>(m.num_nodes()));
    NodeCursor c(m);
    Id id;
    Vec3 x;
    while (c.next(id, x)) v[static_cast<size_t>(id)] = x;
    return v;
  };
  auto by_chunks = [](const FineMesh& m) {
    std::vector<Vec3> v(static_cast<size_t>(m.num_nodes()));
    for (const ChunkRange& r : plan_chunks(m, 3)) {
      ExportChunk c(m, r);
      c.prepare({});
      for (Id i = 0; i < c.num_nodes(); ++i) v[static_cast<size_t>(c.node_global()[i])] = {c.x()[i], c.y()[i], c.z()[i]};
    }
    return v;
  };
  auto by_id = [](const FineMesh& m) {
    std::vector<Vec3> v(static_cast<size_t>(m.num_nodes()));
    for (Id id = 0; id < m.num_nodes(); ++id) v[static_cast<size_t>(id)] = m.node(id);
    return v;
  };
  const std::vector<std::vector<Vec3>> c_paths = {by_id(coarse), by_blocks(coarse), by_batches(coarse), by_cursor(coarse), by_chunks(coarse)};
  const std::vector<std::vector<Vec3>> f_paths = {by_id(fine), by_blocks(fine), by_batches(fine), by_cursor(fine), by_chunks(fine)};
  for (const auto& [f, c] : twin)
    for (const auto& cp : c_paths)
      for (const auto& fp : f_paths)
        ASSERT_TRUE(same_bits(fp[static_cast<size_t>(f)], cp[static_cast<size_t>(c)])) << "fine " << f << " coarse " << c;
}

// On axis-aligned boxes (no jitter; random local numberings), P reproduces
// every trilinear function of the physical coordinates.
TEST(Transfer, TrilinearFunctionsAreReproducedOnBoxes) {
  std::mt19937_64 rng(5);
  test::TempDir tmp;
  test::BoxSpec spec;
  spec.a = 3, spec.b = 2, spec.c = 2, spec.perturb = 0;
  const Pair pair = nested_pair(test::random_box(spec, rng), rng, tmp, 0);
  const FineMesh coarse = read_store(pair.coarse_path), fine = read_store(pair.fine_path);
  const Prolongation p(coarse, fine);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int k = 0; k < 4; ++k) {
    double a[8];
    for (double& v : a) v = u(rng);
    auto f = [&](const Vec3& x) {
      return a[0] + a[1] * x.x + a[2] * x.y + a[3] * x.z + a[4] * x.x * x.y + a[5] * x.y * x.z + a[6] * x.x * x.z +
             a[7] * x.x * x.y * x.z;
    };
    const auto xc = at_nodes(coarse, f), yf = at_nodes(fine, f);
    std::vector<double> y(yf.size());
    p.apply(xc, y, 2);
    double worst = 0, scale = 0;
    for (size_t i = 0; i < y.size(); ++i) worst = std::max(worst, std::fabs(y[i] - yf[i])), scale = std::max(scale, std::fabs(yf[i]));
    EXPECT_LE(worst, 1e-12 * scale) << "trilinear function " << k;
  }
  // A non-trilinear function is not reproduced (the test can fail).
  auto g = [](const Vec3& x) { return x.x * x.x; };
  const auto xc = at_nodes(coarse, g), yf = at_nodes(fine, g);
  std::vector<double> y(yf.size());
  p.apply(xc, y);
  double worst = 0;
  for (size_t i = 0; i < y.size(); ++i) worst = std::max(worst, std::fabs(y[i] - yf[i]));
  EXPECT_GT(worst, 1e-3);
}

TEST(Transfer, TheFirstSheetThatIsNotNestedIsNamedAndNoOperatorIsBuilt) {
  std::mt19937_64 rng(8);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 2, spec.c = 2;
  const CoarseMesh mesh = test::random_box(spec, rng);
  IntervalRequest rc, rf;
  rc.global = 2, rf.global = 4;
  rf.sheets = {{4, 5}, {2, 3}};  // sheets 2 and 4 are not multiples of 2: 2 is named
  const FineMesh coarse = FineMesh::dice(mesh, rc), fine = FineMesh::dice(mesh, rf);
  const Nesting n = check_nesting(coarse, fine);
  EXPECT_FALSE(n.nested);
  EXPECT_EQ(n.sheet, 2);
  EXPECT_EQ(n.coarse_interval, 2);
  EXPECT_EQ(n.fine_interval, 3);
  EXPECT_NE(n.message.find("sheet 2"), std::string::npos) << n.message;
  try {
    const Prolongation p(coarse, fine);
    FAIL() << "built an operator between stores that are not nested";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::BadInput);
    EXPECT_NE(std::string(e.what()).find("sheet 2"), std::string::npos) << e.what();
  }
  // The other way round (fine as coarse) is not nested either.
  EXPECT_FALSE(check_nesting(fine, coarse).nested);
  // Equal intervals are nested (factor 1: P is a permutation... the identity).
  const Prolongation same(coarse, coarse);
  EXPECT_EQ(same.nonzeros(), coarse.num_nodes());
}

// A graded sheet in either store: not nested (P's weights assume equal
// spacing), the first graded sheet named, no operator built.
TEST(Transfer, GradedSheetsAreNotNested) {
  std::mt19937_64 rng(9);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 2, spec.c = 2;
  const CoarseMesh mesh = test::random_box(spec, rng);
  IntervalRequest rc, rf;
  rc.global = 2, rf.global = 4;
  BiasRequest bias;
  bias.ratio = 1.25;
  rf.sheet_bias = {{1, bias}};
  const FineMesh coarse = FineMesh::dice(mesh, rc), fine = FineMesh::dice(mesh, rf);
  IntervalRequest plain = rf;
  plain.sheet_bias.clear();
  ASSERT_TRUE(check_nesting(coarse, FineMesh::dice(mesh, plain)).nested);  // the intervals alone nest
  for (const auto& [a, b] : {std::pair{&coarse, &fine}, std::pair{&fine, &fine}}) {
    const Nesting n = check_nesting(*a, *b);
    EXPECT_FALSE(n.nested);
    EXPECT_TRUE(n.graded);
    EXPECT_EQ(n.sheet, 1);
    EXPECT_NE(n.message.find("sheet 1 is graded"), std::string::npos) << n.message;
    EXPECT_THROW(Prolongation(*a, *b), Error);
  }
}

// Different coarse meshes, or the same one in another order, are refused
// by content.
TEST(Transfer, StoresOfDifferentCoarseMeshesAreRefusedByContent) {
  auto refused = [](const FineMesh& a, const FineMesh& b, const std::string& what) {
    try {
      check_nesting(a, b);
      ADD_FAILURE() << what << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::BadInput) << what;
      EXPECT_NE(std::string(e.what()).find("not dicings of one coarse mesh"), std::string::npos) << e.what();
    }
  };
  test::BoxSpec spec;
  spec.a = 4, spec.b = 3, spec.c = 2;
  IntervalRequest one, two;
  one.global = 1, two.global = 2;
  std::mt19937_64 r1(3), r2(3), r3(4);
  const CoarseMesh m = test::random_box(spec, r1);
  const FineMesh base = FineMesh::dice(m, one);
  EXPECT_TRUE(check_nesting(base, FineMesh::dice(test::random_box(spec, r2), two)).nested);  // the same mesh again
  refused(base, FineMesh::dice(test::random_box(spec, r3), two), "another random box");
  const FineMesh file_order = FineMesh::dice(m, two, nullptr, false);
  MeshCursor c1, c2;
  bool other_order = false;
  for (Id h = 0; h < base.num_coarse_elements(); ++h)
    other_order |= RowReader(base.tables(), c1).element(h).file_id != RowReader(file_order.tables(), c2).element(h).file_id;
  ASSERT_TRUE(other_order) << "the Morton order of this box is its file order";
  refused(base, file_order, "the same mesh in file order");
  CoarseMesh moved = m;
  moved.x[0] = std::nextafter(moved.x[0], 1e9);  // one coordinate, one ulp
  refused(base, FineMesh::dice(moved, two), "one vertex moved by one ulp");
  CoarseMesh reordered = m;  // elements 0 and 1 swapped in the file: other file ids
  std::swap_ranges(reordered.conn.begin(), reordered.conn.begin() + 8, reordered.conn.begin() + 8);
  refused(base, FineMesh::dice(reordered, two), "elements renumbered");
  CoarseMesh renumbered = m;  // two vertex ids swapped: sheets numbered otherwise
  std::swap(renumbered.x[0], renumbered.x[1]), std::swap(renumbered.y[0], renumbered.y[1]);
  std::swap(renumbered.z[0], renumbered.z[1]);
  for (Id& v : renumbered.conn) v = v == 0 ? 1 : v == 1 ? 0 : v;
  refused(base, FineMesh::dice(renumbered, two), "vertices renumbered");
  std::mt19937_64 r4(9);
  refused(base, FineMesh::dice(test::random_quad_sheet(3, 2, false, r4), two), "a surface mesh");
}

}  // namespace
