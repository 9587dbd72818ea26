// Graded sheets (intervals.hpp, tfi.hpp Series) over random coarse meshes:
// random biases, dual biases and start nodes, random vertex renumbering and
// hex rotations. Expected spacings come from the geometric series summed
// independently in long double, directions from the coordinates of the
// fine nodes, never from dicer's own tables.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/locate.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/tfi.hpp"
#include "dicer/verify.hpp"
#include "access_paths.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }
bool same_bits(const Vec3& a, const Vec3& b) { return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z); }

// The fine cell lengths of an edge of length L, from its start, as the
// series defines them (summed in long double, not with dicer's formula).
std::vector<long double> expected_lengths(long double L, Id n, tfi::Spacing kind, long double R) {
  std::vector<long double> h(static_cast<size_t>(n), 1.0L);
  if (kind == tfi::Spacing::Geometric)
    for (Id k = 1; k < n; ++k) h[k] = h[k - 1] * R;
  if (kind == tfi::Spacing::Dual)
    for (Id k = 1; k < n; ++k) h[k] = 2 * k < n ? h[k - 1] * R : h[n - 1 - k];  // mirrored past the middle
  long double sum = 0;
  for (long double x : h) sum += x;
  for (long double& x : h) x *= L / sum;
  return h;
}

double dist(const Vec3& a, const Vec3& b) { return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z); }

}  // namespace

// ---------------------------------------------------------------- Series

TEST(Grading, EqualSpacingIsExactlyTOverN) {
  for (Id n = 1; n <= 64; ++n) {
    const tfi::Series s(n, {});
    for (Id t = 0; t <= n; ++t) ASSERT_TRUE(same_bits(s.at(t), static_cast<double>(t) / static_cast<double>(n))) << t << "/" << n;
  }
}

TEST(Grading, GeometricAndDualSeriesMatchIndependentSums) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> lr(std::log(0.2), std::log(5.0));
  for (int trial = 0; trial < 400; ++trial) {
    const Id n = 1 + static_cast<Id>(rng() % 60);
    double R = std::exp(lr(rng));
    if (trial % 7 == 0) R = trial % 2 ? 1.0 + 1e-9 : tfi::kMaxRatio;  // near 1 and the limit
    if (n > 8 && R == tfi::kMaxRatio) R = 3;
    for (const tfi::Spacing kind : {tfi::Spacing::Geometric, tfi::Spacing::Dual}) {
      // Only series whose cells dicing accepts (at least kMinCell).
      const auto h1 = expected_lengths(1.0L, n, kind, std::max(R, 1 / R));
      if (*std::min_element(h1.begin(), h1.end()) < tfi::kMinCell) continue;
      SCOPED_TRACE("n " + std::to_string(n) + " R " + std::to_string(R) + " kind " + std::to_string(int(kind)));
      const tfi::Series s(n, {kind, false, R});
      const auto h = expected_lengths(1.0L, n, kind, R);
      long double x = 0;
      for (Id t = 0; t <= n; ++t) {
        const double v = s.at(t);
        ASSERT_NEAR(static_cast<double>(x), v, 4e-16) << "t " << t;
        // Every graded parameter is a multiple of 2^-53: 1 - s is exact.
        ASSERT_EQ(std::ldexp(v, 53), std::floor(std::ldexp(v, 53))) << "t " << t;
        if (t < n) x += h[t];
      }
      ASSERT_EQ(s.at(0), 0.0);
      ASSERT_EQ(s.at(n), 1.0);
      if (kind == tfi::Spacing::Geometric) {
        // The flipped series is the mirror, bit for bit.
        const tfi::Series f(n, {kind, true, R});
        for (Id t = 0; t <= n; ++t) ASSERT_TRUE(same_bits(f.at(t), 1.0 - s.at(n - t))) << "t " << t;
      } else {
        for (Id t = 0; t <= n; ++t) ASSERT_TRUE(same_bits(s.at(n - t), 1.0 - s.at(t))) << "symmetric at t " << t;
      }
      // Monotone, and cell() inverts it: at nodes and between them.
      for (Id t = 0; t < n; ++t) {
        ASSERT_LT(s.at(t), s.at(t + 1));
        ASSERT_EQ(s.cell(s.at(t)), t);
        const double mid = 0.5 * (s.at(t) + s.at(t + 1));
        ASSERT_EQ(s.cell(mid), t);
      }
      ASSERT_EQ(s.cell(-0.5), 0);
      ASSERT_EQ(s.cell(1.0), n - 1);
      double smallest = 1;
      for (Id t = 0; t < n; ++t) smallest = std::min(smallest, s.at(t + 1) - s.at(t));
      ASSERT_EQ(s.smallest_cell(), smallest);
    }
  }
}

TEST(Grading, MalformedGradingsAreRefused) {
  EXPECT_TRUE(tfi::grading_ok({}));
  EXPECT_TRUE(tfi::grading_ok({tfi::Spacing::Geometric, true, 1.5}));
  EXPECT_TRUE(tfi::grading_ok({tfi::Spacing::Dual, false, 0.5}));
  for (const double bad : {std::nan(""), 0.0, -1.2, 1.0, 1e300, double(INFINITY), 1.0 / 1000})
    for (const tfi::Spacing kind : {tfi::Spacing::Geometric, tfi::Spacing::Dual})
      EXPECT_FALSE(tfi::grading_ok({kind, false, bad})) << bad;
  EXPECT_FALSE(tfi::grading_ok({tfi::Spacing::Dual, true, 1.5}));      // a dual series has no direction
  EXPECT_FALSE(tfi::grading_ok({tfi::Spacing::Equal, false, 1.5}));    // equal: ratio 1
  EXPECT_FALSE(tfi::grading_ok({tfi::Spacing::Equal, true, 1.0}));
  EXPECT_FALSE(tfi::grading_ok({static_cast<tfi::Spacing>(3), false, 1.5}));
}

// ---------------------------------------------------------------- meshes

namespace {

struct GradedCase {
  CoarseMesh mesh;
  IntervalRequest req;
  std::map<Id, BiasRequest> bias;  // by sheet
};

// Random intervals 1..5, and per sheet: a geometric bias (R in [0.6, 1.8],
// from a random node of the sheet or the default), a dual one, or none.
GradedCase random_case(std::mt19937_64& rng, bool perturb = true, int size = 3) {
  test::BoxSpec spec;
  spec.a = 1 + static_cast<int>(rng() % size), spec.b = 1 + static_cast<int>(rng() % 2), spec.c = 1 + static_cast<int>(rng() % 2);
  spec.perturb = perturb ? 0.15 : 0.0;
  GradedCase g;
  g.mesh = test::random_box(spec, rng);
  const Topology t = build_topology(g.mesh);
  const Sheets s = find_sheets(g.mesh, t);
  std::uniform_real_distribution<double> ratio(0.6, 1.8);
  for (Id q = 0; q < s.num_sheets(); ++q) {
    g.req.sheets.emplace_back(q, 1 + static_cast<Id>(rng() % 5));
    const int pick = static_cast<int>(rng() % 4);
    if (pick == 3) continue;
    BiasRequest b;
    b.kind = pick == 2 ? tfi::Spacing::Dual : tfi::Spacing::Geometric;
    b.ratio = ratio(rng);
    if (pick == 1) {
      std::vector<Id> on;
      for (Id e = 0; e < t.num_edges(); ++e)
        if (s.edge_sheet[e] == q) on.push_back(t.edge_v[2 * e + (rng() & 1)]);
      b.start = g.mesh.vertex_file_id[on[rng() % on.size()]];
    }
    g.bias[q] = b;
    g.req.sheet_bias.emplace_back(q, b);
  }
  return g;
}

// The points of store edge e, t = 0..n.
std::vector<Vec3> edge_points(const FineMesh& f, Id e, MeshCursor& cur) {
  const RowReader R(f.tables(), cur);
  const EdgeRow row = R.edge(e);
  std::vector<Vec3> p{R.xyz(row.lo)};
  for (Id t = 1; t < row.n; ++t) p.push_back(f.node(NodeRef{EntityKind::Edge, e, {t, 0, 0}}, cur));
  p.push_back(R.xyz(row.hi));
  return p;
}

// Checks every coarse edge's spacing against its sheet's series (to 1e-12
// of each cell), that each face's opposite sides run the same way, and that
// every geometric sheet starts where it was asked to (or at the lower file
// node id of its first edge).
void expect_series_on_edges(const GradedCase& g, const FineMesh& f) {
  MeshCursor cur;
  const RowReader R(f.tables(), cur);
  const Id E = f.tables().edges.rows();
  // starts_at_lo[e]: 1 the series starts at lo, 0 at hi, -1 either (symmetric).
  std::vector<int> starts_at_lo(static_cast<size_t>(E), -1);
  for (Id e = 0; e < E; ++e) {
    const EdgeRow row = R.edge(e);
    const auto p = edge_points(f, e, cur);
    const Id n = row.n;
    const long double L = dist(p.front(), p.back());
    const auto it = g.bias.find(row.sheet);
    const tfi::Spacing kind = it == g.bias.end() ? tfi::Spacing::Equal : it->second.kind;
    const long double Rr = it == g.bias.end() ? 1.0L : it->second.ratio;
    const auto h = expected_lengths(L, n, kind, Rr);
    auto matches = [&](bool forward) {
      for (Id k = 0; k < n; ++k) {
        const long double want = h[forward ? k : n - 1 - k];
        if (std::fabs(dist(p[k], p[k + 1]) - want) > 1e-12L * want) return false;
      }
      return true;
    };
    const bool fw = matches(true), bw = matches(false);
    ASSERT_TRUE(fw || bw) << "edge " << e << " (sheet " << row.sheet << ", n " << n << ") is not spaced like its series";
    // The nodes lie on the straight edge, in order.
    for (Id k = 1; k < n; ++k) {
      const double s = dist(p.front(), p[k]) + dist(p[k], p.back());
      ASSERT_NEAR(s, static_cast<double>(L), 1e-12 * static_cast<double>(L)) << "edge " << e << " node " << k;
    }
    if (kind == tfi::Spacing::Geometric && fw != bw) starts_at_lo[e] = fw ? 1 : 0;
  }
  // Across every face, opposite sides run the same way (v0 -> v1 and v3 -> v2; v0 -> v3 and v1 -> v2).
  for (Id fi = 0; fi < f.tables().faces.rows(); ++fi) {
    const FaceRow fr = R.face(fi);
    for (int axis = 0; axis < 2; ++axis) {
      int from_first[2];
      for (int q = 0; q < 2; ++q) {
        const int k = 2 * axis + q;
        const Id e = fr.e[k];
        const Id a = fr.v[kQuadEdge[k][0]];  // the side's first corner in the face's frame
        from_first[q] = starts_at_lo[e] < 0 ? -1 : (starts_at_lo[e] == 1) == (R.edge(e).lo == a);
      }
      if (from_first[0] >= 0 && from_first[1] >= 0) {
        ASSERT_EQ(from_first[0], from_first[1]) << "face " << fi << ": opposite sides graded opposite ways";
      }
    }
  }
  // Starts: the node asked for, else the lower file id of the sheet's first edge (input numbering).
  const Topology t0 = build_topology(g.mesh);
  const Sheets s0 = find_sheets(g.mesh, t0);
  const CoarseMesh& c = *f.coarse();
  for (const auto& [sheet, b] : g.bias) {
    if (b.kind != tfi::Spacing::Geometric || f.sheet_intervals()[sheet] < 2) continue;
    Id start = -1;
    if (b.start) {
      start = *b.start;
    } else {
      for (Id e = 0; e < t0.num_edges() && start < 0; ++e)
        if (s0.edge_sheet[e] == sheet)
          start = std::min(g.mesh.vertex_file_id[t0.edge_v[2 * e]], g.mesh.vertex_file_id[t0.edge_v[2 * e + 1]]);
    }
    EXPECT_EQ(f.sheet_gradings()[sheet].start, start);
    int checked = 0;
    for (Id e = 0; e < E; ++e) {
      const EdgeRow row = R.edge(e);
      if (row.sheet != sheet || starts_at_lo[e] < 0) continue;
      const Id lo = c.vertex_file_id[row.lo], hi = c.vertex_file_id[row.hi];
      if (lo != start && hi != start) continue;
      EXPECT_EQ(starts_at_lo[e] == 1, lo == start) << "sheet " << sheet << " starts at node " << start;
      ++checked;
    }
    EXPECT_GT(checked, 0) << "sheet " << sheet;
  }
}

}  // namespace

TEST(GradedMeshes, ConformingBitIdenticalAndSpacedLikeTheSeries) {
  std::mt19937_64 rng(4242);
  for (int trial = 0; trial < 24; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const GradedCase g = random_case(rng);
    std::vector<std::string> notes;
    const FineMesh f = FineMesh::dice(g.mesh, g.req, &notes);
    const VerifyReport r = verify(f);
    ASSERT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
    EXPECT_GT(r.min_scaled_jacobian, 0.0);
    expect_series_on_edges(g, f);
    test::TempDir dir;
    test::expect_paths_bit_identical(f, dir.path("g.dice.h5"));
  }
}

// The sweep's checksum is the sum of the terms of node(id) and element(id)
// (sweep.hpp), in memory and from the store with two threads; export
// chunks carry node(id)'s bits, and MSH written and read back (dicer's own
// MSH reader, binary float64) too.
TEST(GradedMeshes, SweepAndExportSeeNodeIdsBits) {
  std::mt19937_64 rng(31);
  const GradedCase g = random_case(rng);
  const FineMesh f = FineMesh::dice(g.mesh, g.req);
  std::uint64_t want = 0;
  for (Id id = 0; id < f.num_nodes(); ++id) want += node_checksum_term(id, f.node(id));
  for (Id e = 0; e < f.num_elements(); ++e) want += element_checksum_term(f.element(e));
  EXPECT_EQ(sweep(f, 1).checksum, want);
  test::TempDir dir;
  write_store(f, dir.path("g.dice.h5"));
  const FineMesh stored = read_store(dir.path("g.dice.h5"));
  EXPECT_EQ(sweep(stored, 2).checksum, want);
  const auto plan = plan_chunks(stored, 2);
  for (size_t k = 0; k < plan.size(); ++k) {
    ExportChunk chunk(stored, plan[k]);
    chunk.prepare(MeshSets{});
    for (Id i = 0; i < chunk.num_nodes(); ++i)
      ASSERT_TRUE(same_bits({chunk.x()[i], chunk.y()[i], chunk.z()[i]}, f.node(chunk.node_global()[i]))) << "chunk " << k;
    const std::string msh = dir.path("c" + std::to_string(k) + ".msh");
    write_msh(chunk, msh, true);
    const CoarseMesh back = read_msh(msh);
    ASSERT_EQ(back.num_vertices(), chunk.num_nodes());
    for (Id v = 0; v < back.num_vertices(); ++v)
      ASSERT_TRUE(same_bits(back.vertex(v), f.node(back.vertex_file_id[v] - 1))) << "msh node tag " << back.vertex_file_id[v];
  }
}

// Counts and ids do not depend on the grading: the same request without
// biases gives the same numbering, element by element.
TEST(GradedMeshes, NumberingIsTheUngradedOne) {
  std::mt19937_64 rng(51);
  for (int trial = 0; trial < 6; ++trial) {
    GradedCase g = random_case(rng);
    const FineMesh graded = FineMesh::dice(g.mesh, g.req);
    g.req.sheet_bias.clear();
    const FineMesh plain = FineMesh::dice(g.mesh, g.req);
    ASSERT_EQ(graded.num_nodes(), plain.num_nodes());
    ASSERT_EQ(graded.num_elements(), plain.num_elements());
    for (Id e = 0; e < plain.num_elements(); ++e) ASSERT_EQ(graded.element(e).nodes, plain.element(e).nodes);
  }
}

// On an undistorted box every fine node is a point of the tensor grid of
// the sheets' graded coordinates (faces and interiors follow the edges'
// parameters): computed here per axis from the slabs and their series.
TEST(GradedMeshes, AnUndistortedBoxIsTheTensorGridOfItsSeries) {
  std::mt19937_64 rng(77);
  for (int trial = 0; trial < 6; ++trial) {
    const GradedCase g = random_case(rng, false, 4);
    const FineMesh f = FineMesh::dice(g.mesh, g.req);
    const Topology t = build_topology(g.mesh);
    const Sheets s = find_sheets(g.mesh, t);
    std::set<double> grid[3];
    for (Id q = 0; q < s.num_sheets(); ++q) {
      // The sheet's axis and slab, and which end of it its series starts at.
      Id e = 0;
      while (s.edge_sheet[e] != q) ++e;
      const Vec3 a = g.mesh.vertex(t.edge_v[2 * e]), b = g.mesh.vertex(t.edge_v[2 * e + 1]);
      const double d[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
      const int axis = static_cast<int>(std::max_element(d, d + 3, [](double x, double y) { return std::fabs(x) < std::fabs(y); }) - d);
      const double lo = std::min((&a.x)[axis], (&b.x)[axis]), hi = std::max((&a.x)[axis], (&b.x)[axis]);
      const Id n = f.sheet_intervals()[q];
      const auto it = g.bias.find(q);
      const tfi::Spacing kind = it == g.bias.end() ? tfi::Spacing::Equal : it->second.kind;
      bool from_lo = true;
      if (kind == tfi::Spacing::Geometric && n >= 2) {
        // The start node asked for (or the default, checked by the test above).
        const Id start = it->second.start ? *it->second.start : f.sheet_gradings()[q].start;
        const auto v = std::find(g.mesh.vertex_file_id.begin(), g.mesh.vertex_file_id.end(), start) - g.mesh.vertex_file_id.begin();
        ASSERT_LT(v, g.mesh.num_vertices());
        const double at = axis == 0 ? g.mesh.x[v] : axis == 1 ? g.mesh.y[v] : g.mesh.z[v];
        from_lo = std::fabs(at - lo) < 1e-9;
      }
      const auto h = expected_lengths(static_cast<long double>(hi - lo), n, kind, it == g.bias.end() ? 1 : it->second.ratio);
      long double x = from_lo ? lo : hi;
      grid[axis].insert(lo), grid[axis].insert(hi);
      for (Id k = 0; k + 1 < n; ++k) {
        x += from_lo ? h[k] : -h[k];
        grid[axis].insert(static_cast<double>(x));
      }
    }
    NodeCursor c(f);
    Id id;
    Vec3 p;
    Id seen = 0;
    while (c.next(id, p)) {
      const double xyz[3] = {p.x, p.y, p.z};
      for (int d = 0; d < 3; ++d) {
        const auto it = grid[d].lower_bound(xyz[d] - 1e-12);
        ASSERT_TRUE(it != grid[d].end() && std::fabs(*it - xyz[d]) <= 1e-12) << "node " << id << " axis " << d << " at " << xyz[d];
      }
      ++seen;
    }
    ASSERT_EQ(seen, static_cast<Id>(grid[0].size() * grid[1].size() * grid[2].size()));
  }
}

// ---------------------------------------------------------------- twisted sheets

namespace {

// A ring of hexes around the z axis whose square cross-section turns by
// half a turn on the way round: both sheets across the section come back
// reversed (Moebius-like); the sheet of the ring's own edges does not.
CoarseMesh twisted_ring(int segments) {
  CoarseMesh m;
  m.source = "twisted_ring";
  m.mode = Mode::Volume;
  const double r0 = 3.0;
  for (int j = 0; j < segments; ++j) {
    const double th = 2 * std::numbers::pi * j / segments, ph = std::numbers::pi * j / segments;
    for (int c = 0; c < 4; ++c) {
      const double u = (c == 1 || c == 2) ? 0.5 : -0.5, w = (c >= 2) ? 0.5 : -0.5;
      const double ru = u * std::cos(ph) - w * std::sin(ph), wz = u * std::sin(ph) + w * std::cos(ph);
      m.x.push_back((r0 + ru) * std::cos(th)), m.y.push_back((r0 + ru) * std::sin(th)), m.z.push_back(wz);
    }
  }
  // Section `segments` is section 0 turned by half a turn: corner c -> c + 2.
  auto v = [&](int j, int c) { return j < segments ? Id{4} * j + c : Id{(c + 2) % 4}; };
  for (int j = 0; j < segments; ++j) {
    const int cs[4] = {0, 1, 2, 3};
    for (int c : cs) m.conn.push_back(v(j, c));
    for (int c : cs) m.conn.push_back(v(j + 1, c));
    m.element_block.push_back(0);
  }
  m.blocks = {{1, "ring"}};
  validate_coarse_mesh(m);
  return m;
}

// A Moebius strip of quads: one row of `segments` quads across a band whose
// width turns by half a turn.
CoarseMesh moebius_strip(int segments) {
  CoarseMesh m;
  m.source = "moebius_strip";
  m.mode = Mode::Surface;
  for (int j = 0; j < segments; ++j) {
    const double th = 2 * std::numbers::pi * j / segments, ph = std::numbers::pi * j / segments;
    for (int c = 0; c < 2; ++c) {
      const double u = c ? 0.5 : -0.5;
      m.x.push_back((3 + u * std::cos(ph)) * std::cos(th)), m.y.push_back((3 + u * std::cos(ph)) * std::sin(th));
      m.z.push_back(u * std::sin(ph));
    }
  }
  auto v = [&](int j, int c) { return j < segments ? Id{2} * j + c : Id{1 - c}; };
  for (int j = 0; j < segments; ++j) {
    m.conn.insert(m.conn.end(), {v(j, 0), v(j, 1), v(j + 1, 1), v(j + 1, 0)});
    m.element_block.push_back(0);
  }
  m.blocks = {{1, "strip"}};
  validate_coarse_mesh(m);
  return m;
}

}  // namespace

TEST(GradedMeshes, ATwistedSheetRefusesABiasAndTakesADualOne) {
  for (const bool volume : {true, false}) {
    SCOPED_TRACE(volume ? "twisted ring of hexes" : "Moebius strip of quads");
    const CoarseMesh m = volume ? twisted_ring(8) : moebius_strip(8);
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    const SheetDirections d = orient_sheets(t, s);
    int twisted = 0;
    for (Id q = 0; q < s.num_sheets(); ++q) twisted += d.twisted[q];
    EXPECT_EQ(twisted, volume ? 2 : 1);
    for (Id q = 0; q < s.num_sheets(); ++q) {
      IntervalRequest req;
      req.global = 4;
      BiasRequest b;
      b.ratio = 1.3;
      req.sheet_bias = {{q, b}};
      if (d.twisted[q]) {
        try {
          FineMesh::dice(m, req);
          ADD_FAILURE() << "a bias on twisted sheet " << q << " was accepted";
        } catch (const Error& e) {
          EXPECT_EQ(e.kind(), ErrorKind::Usage);
          const std::string w = e.what();
          EXPECT_NE(w.find("sheet " + std::to_string(q) + " closes on itself reversed"), std::string::npos) << w;
          EXPECT_NE(w.find("dual"), std::string::npos) << w;
        }
        b.kind = tfi::Spacing::Dual;
        req.sheet_bias = {{q, b}};
      }
      const FineMesh f = FineMesh::dice(m, req);
      if (volume) {  // (verify refuses a one-sided surface whatever its grading)
        const VerifyReport r = verify(f);
        EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
      }
      test::TempDir dir;
      test::expect_paths_bit_identical(f, dir.path("t.dice.h5"), volume);
    }
  }
}

// ---------------------------------------------------------------- locate

// Points at random xi inside random fine cells of graded meshes: point
// location finds that cell and that xi, however thin the cell.
TEST(GradedMeshes, PointLocationFindsTheCellAndXi) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int trial = 0; trial < 8; ++trial) {
    GradedCase g = random_case(rng);
    for (auto& [q, b] : g.req.sheet_bias) b.ratio = b.ratio > 1 ? 3.5 : 0.3;  // strong: thin cells
    for (auto& [q, n] : g.req.sheets) n += 3;
    const FineMesh f = FineMesh::dice(g.mesh, g.req);
    for (int k = 0; k < 60; ++k) {
      const Id id = static_cast<Id>(rng() % static_cast<std::uint64_t>(f.num_elements()));
      const FineElement el = f.element(id);
      std::array<std::array<double, 3>, 8> x;
      for (int q = 0; q < 8; ++q) {
        const Vec3 p = f.node(el.nodes[q]);
        x[q] = {p.x, p.y, p.z};
      }
      const std::array<double, 3> xi{u(rng), u(rng), u(rng)};
      const auto p = trilinear(x, xi);
      const Located l = locate_point(f, p);
      ASSERT_EQ(l.element, id) << "trial " << trial;
      for (int d = 0; d < 3; ++d) ASSERT_NEAR(l.xi[d], xi[d], 1e-9) << "trial " << trial << " axis " << d;
    }
  }
}

TEST(GradedMeshes, SurfacePointLocationFindsTheCellAndXi) {
  std::mt19937_64 rng(19);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int trial = 0; trial < 6; ++trial) {
    const CoarseMesh m = test::random_quad_sheet(2 + trial % 3, 2, true, rng);
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    IntervalRequest req;
    for (Id q = 0; q < s.num_sheets(); ++q) {
      req.sheets.emplace_back(q, 3 + static_cast<Id>(rng() % 4));
      BiasRequest b;
      b.kind = q % 2 ? tfi::Spacing::Dual : tfi::Spacing::Geometric;
      b.ratio = q % 3 ? 2.5 : 0.4;
      req.sheet_bias.emplace_back(q, b);
    }
    const FineMesh f = FineMesh::dice(m, req);
    ASSERT_TRUE(verify(f).ok());
    for (int k = 0; k < 40; ++k) {
      const Id id = static_cast<Id>(rng() % static_cast<std::uint64_t>(f.num_elements()));
      const FineElement el = f.element(id);
      std::array<std::array<double, 3>, 4> x;
      for (int q = 0; q < 4; ++q) {
        const Vec3 p = f.node(el.nodes[q]);
        x[q] = {p.x, p.y, p.z};
      }
      const std::array<double, 3> xi{u(rng), u(rng), 0};
      const auto p = bilinear(x, xi);
      const Located l = locate_point(f, p);
      ASSERT_EQ(l.element, id) << "trial " << trial;
      for (int d = 0; d < 2; ++d) ASSERT_NEAR(l.xi[d], xi[d], 1e-9) << "trial " << trial << " axis " << d;
      EXPECT_LT(l.distance, 1e-9);
    }
  }
}
