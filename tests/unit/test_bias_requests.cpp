// Bias requests (intervals.hpp): parsing, the intervals file's objects,
// precedence and conflict notes, ratios derived from a cell length, --size
// with a bias, and the refusals. Expected intervals and cell lengths come
// from the series summed here in long double and searched by brute force.
#include <gtest/gtest.h>

#include <cmath>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/intervals.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

// A row of `count` unit cubes along x (y, z in [0, 1]), one block per cube.
CoarseMesh cubes(int count, double length = 1) {
  CoarseMesh m;
  m.source = "row.exo";
  for (int i = 0; i <= count; ++i)
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j) m.x.push_back(i * length), m.y.push_back(j), m.z.push_back(k);
  auto v = [](int i, int j, int k) { return static_cast<Id>(4 * i + 2 * k + j); };
  for (int i = 0; i < count; ++i) {
    const Id c[8] = {v(i, 0, 0), v(i + 1, 0, 0), v(i + 1, 1, 0), v(i, 1, 0),
                     v(i, 0, 1), v(i + 1, 0, 1), v(i + 1, 1, 1), v(i, 1, 1)};
    m.conn.insert(m.conn.end(), c, c + 8);
    m.blocks.push_back({10 + i, "cube" + std::to_string(i)});
    m.element_block.push_back(i);
  }
  validate_coarse_mesh(m);
  return m;
}

// The sheet of the x edges of cube i (their lower x is i * length).
Id x_sheet(const CoarseMesh& m, int i, double length = 1) {
  const Topology t = build_topology(m);
  const Sheets s = find_sheets(m, t);
  for (Id e = 0; e < t.num_edges(); ++e) {
    const Id a = t.edge_v[2 * e], b = t.edge_v[2 * e + 1];
    if (m.x[a] != m.x[b] && std::min(m.x[a], m.x[b]) == i * length) return s.edge_sheet[e];
  }
  return -1;
}

using test::error_of;

// Fine x positions along the x edge y = z = 0 of the diced row, sorted.
std::vector<double> xs(const FineMesh& f) {
  std::vector<double> out;
  NodeCursor c(f);
  Id id;
  Vec3 p;
  while (c.next(id, p))
    if (p.y == 0 && p.z == 0) out.push_back(p.x);
  std::sort(out.begin(), out.end());
  return out;
}

// Cells of a geometric series of ratio R over length L, from its start.
std::vector<long double> cells(long double L, Id n, long double R, bool dual = false) {
  std::vector<long double> h(static_cast<size_t>(n), 1);
  for (Id k = 1; k < n; ++k) h[k] = dual && 2 * k >= n ? h[n - 1 - k] : h[k - 1] * R;
  long double s = 0;
  for (auto x : h) s += x;
  for (auto& x : h) x *= L / s;
  return h;
}

}  // namespace

TEST(BiasRequests, ParseAndCheck) {
  auto b = parse_bias("f", "1.25", tfi::Spacing::Geometric);
  EXPECT_EQ(b.ratio, 1.25);
  EXPECT_FALSE(b.start);
  b = parse_bias("f", "0.8@345", tfi::Spacing::Geometric);
  EXPECT_EQ(b.ratio, 0.8);
  EXPECT_EQ(b.start, 345);
  b = parse_bias("f", "first:0.01@7", tfi::Spacing::Geometric);
  EXPECT_EQ(b.first_cell, 0.01);
  EXPECT_EQ(b.start, 7);
  b = parse_bias("f", "last:2", tfi::Spacing::Geometric);
  EXPECT_EQ(b.last_cell, 2);
  b = parse_bias("f", "first:0.1", tfi::Spacing::Dual);
  EXPECT_EQ(b.kind, tfi::Spacing::Dual);
  EXPECT_EQ(b.first_cell, 0.1);
  for (const char* bad : {"", "abc", "0", "-1.2", "1000", "nan", "1.2@", "1.2@x", "1.2@ 17", "first:", "first:-1", "last:0"})
    EXPECT_NE(error_of([&] { parse_bias("--sheet-bias 3=" + std::string(bad), bad, tfi::Spacing::Geometric); },
                       ErrorKind::Usage).find("--sheet-bias 3="),
              std::string::npos) << bad;
  EXPECT_NE(error_of([&] { parse_bias("d", "1.2@4", tfi::Spacing::Dual); }, ErrorKind::Usage).find("no start node"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_bias("d", "last:0.1", tfi::Spacing::Dual); }, ErrorKind::Usage).find("first:h"),
            std::string::npos);
  EXPECT_EQ(parse_entity("e", "2:15"), (EntityTag{2, 15}));
  EXPECT_EQ(parse_entity("e", "1:0"), (EntityTag{1, 0}));
  EXPECT_EQ(parse_entity("e", "3:-4"), (EntityTag{3, -4}));
  // Tags as Gmsh writes them: "2:05" would be a second key for 2:5.
  for (const char* bad : {"2", "0:3", "4:1", "2:", "2:x", "22:1", ":3", "2:05", "2:+5", "2: 5", "2:-", "2:-05"})
    EXPECT_NE(error_of([&] { parse_entity("e", bad); }, ErrorKind::Usage).find("DIM:TAG"), std::string::npos) << bad;
}

TEST(BiasRequests, TheIntervalsFileTakesObjectsAndPlainNumbers) {
  test::TempDir tmp;
  const std::string p = tmp.path("plan.json");
  test::write_file(p, R"({"global": 2, "sheets": {"17": {"interval": 12, "bias": 1.2, "start": 345}, "3": 5,
                          "4": {"dual_bias": 1.3}}, "blocks": {"wall": {"interval": 8, "bias": 1.1}, "2": 6,
                          "x": {"first": 0.01}}, "entities": {"2:5": 8, "1:7": {"last": 0.5, "start": 2}}})");
  const IntervalRequest r = read_interval_file(p);
  EXPECT_EQ(r.global, 2);
  EXPECT_EQ(r.sheets, (std::vector<std::pair<Id, Id>>{{17, 12}, {3, 5}}));
  ASSERT_EQ(r.sheet_bias.size(), 2u);
  EXPECT_EQ(r.sheet_bias[0].first, 17);
  EXPECT_EQ(r.sheet_bias[0].second, (BiasRequest{tfi::Spacing::Geometric, 1.2, 0, 0, 345}));
  EXPECT_EQ(r.sheet_bias[1].first, 4);
  EXPECT_EQ(r.sheet_bias[1].second, (BiasRequest{tfi::Spacing::Dual, 1.3, 0, 0, std::nullopt}));
  // (JSON objects have no order: keys come sorted)
  EXPECT_EQ(r.blocks, (std::vector<std::pair<std::string, Id>>{{"2", 6}, {"wall", 8}}));
  ASSERT_EQ(r.block_bias.size(), 2u);
  EXPECT_EQ(r.block_bias[0].first, "wall");
  EXPECT_EQ(r.block_bias[0].second.ratio, 1.1);
  EXPECT_EQ(r.block_bias[1].second.first_cell, 0.01);
  EXPECT_EQ(r.entities, (std::vector<std::pair<EntityTag, Id>>{{{2, 5}, 8}}));
  ASSERT_EQ(r.entity_bias.size(), 1u);
  EXPECT_EQ(r.entity_bias[0].second, (BiasRequest{tfi::Spacing::Geometric, 1, 0, 0.5, 2}));
  for (const auto& [text, want] : std::vector<std::pair<std::string, std::string>>{
           {R"({"sheets": {"1": {"bias": 1.2, "first": 0.1}}})", "one of bias"},
           {R"({"sheets": {"1": {"interval": 3, "ratio": 1.2}}})", "unknown key \"ratio\""},
           {R"({"sheets": {"1": {"start": 3}}})", "start needs a bias"},
           {R"({"sheets": {"1": {}}})", "an interval or a bias"},
           {R"({"sheets": {"1": {"dual_bias": 1.2, "start": 4}}})", "no start node"},
           {R"({"blocks": {"2": {"bias": 0}}})", "ratio must be between"},
           {R"({"entities": {"5:1": 3}})", "DIM:TAG"},
           {R"({"entity": {}})", "unknown key \"entity\""}}) {
    test::write_file(p, text);
    EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find(want), std::string::npos) << text;
  }
}

TEST(BiasRequests, PrecedenceAndConflictsAreReported) {
  const CoarseMesh m = cubes(2);
  const Topology t = build_topology(m);
  const Sheets s = find_sheets(m, t);
  const Id x0 = x_sheet(m, 0);
  IntervalRequest r;
  r.global = 4;
  // y and z sheets cross both cubes: the blocks disagree, the first one's wins.
  r.block_bias = {{"cube0", BiasRequest{tfi::Spacing::Geometric, 1.5, 0, 0, std::nullopt}},
                  {"11", BiasRequest{tfi::Spacing::Dual, 1.2, 0, 0, std::nullopt}}};
  r.sheet_bias = {{x0, BiasRequest{tfi::Spacing::Dual, 1.4, 0, 0, std::nullopt}}};
  const IntervalPlan p = resolve_intervals(m, t, s, r);
  int overrides = 0, first = 0;
  for (const auto& n : p.notes) {
    overrides += n.find("sheet " + std::to_string(x0) + ": its dual bias 1.4 overrides its blocks") != std::string::npos;
    first += n.find("using the first, block 10 (cube0)'s") != std::string::npos;
  }
  EXPECT_EQ(overrides, 1) << ::testing::PrintToString(p.notes);
  EXPECT_EQ(first, 2) << ::testing::PrintToString(p.notes);  // the y and the z sheet
  for (Id q = 0; q < s.num_sheets(); ++q) {
    const tfi::Grading g = p.sheet_grading[q];
    if (q == x0) EXPECT_EQ(g, (tfi::Grading{tfi::Spacing::Dual, false, 1.4}));
    else if (q == x_sheet(m, 1)) EXPECT_EQ(g, (tfi::Grading{tfi::Spacing::Dual, false, 1.2}));  // cube 1's own
    else EXPECT_EQ(g, (tfi::Grading{tfi::Spacing::Geometric, false, 1.5}));
  }
  // Ratio 1: equal spacing.
  IntervalRequest unit;
  unit.global = 4;
  unit.sheet_bias = {{x0, parse_bias("t", "1", tfi::Spacing::Geometric)}};
  EXPECT_EQ(resolve_intervals(m, t, s, unit).sheet_grading[x0], tfi::Grading{});
  // Interval 1 (or a dual bias over 2): nothing to grade, said so.
  IntervalRequest one;
  one.sheet_bias = {{x0, BiasRequest{}}};
  one.sheet_bias[0].second.ratio = 1.3;
  const IntervalPlan q = resolve_intervals(m, t, s, one);
  EXPECT_EQ(q.sheet_grading[x0].kind, tfi::Spacing::Equal);
  ASSERT_EQ(q.notes.size(), 1u);
  EXPECT_NE(q.notes[0].find("changes nothing"), std::string::npos) << q.notes[0];
}

// first:h and last:h: the ratio that makes that cell of the sheet's longest
// edge h long; the fine nodes then sit at the series with that cell.
TEST(BiasRequests, CellLengthsGiveTheRatio) {
  const double L = 2.5;
  const CoarseMesh m = cubes(1, L);
  const Id x0 = x_sheet(m, 0, L);
  for (const auto& [text, kind] : std::vector<std::pair<std::string, tfi::Spacing>>{
           {"first:0.01", tfi::Spacing::Geometric}, {"last:0.05", tfi::Spacing::Geometric},
           {"first:0.9", tfi::Spacing::Geometric}, {"first:0.02", tfi::Spacing::Dual}}) {
    SCOPED_TRACE(text);
    IntervalRequest r;
    r.sheets = {{x0, 9}};
    BiasRequest b = parse_bias("t", text, kind);
    b.start = m.vertex_file_id[0];  // x = 0 (geometric)
    if (kind == tfi::Spacing::Dual) b.start.reset();
    r.sheet_bias = {{x0, b}};
    const FineMesh f = FineMesh::dice(m, r);
    const auto x = xs(f);
    ASSERT_EQ(x.size(), 10u);
    const double want = b.first_cell > 0 ? b.first_cell : b.last_cell;
    const double got = b.first_cell > 0 ? x[1] - x[0] : x[9] - x[8];
    EXPECT_NEAR(got, want, 1e-12 * want);
    // And the rest follows the series of the ratio dicer derived, summed here.
    const double R = f.sheet_gradings()[x0].grading.ratio;
    const auto h = cells(L, 9, R, kind == tfi::Spacing::Dual);
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(x[k + 1] - x[k], static_cast<double>(h[k]), 1e-12 * static_cast<double>(h[k]));
  }
  // A cell no ratio in [0.01, 100] reaches at that interval.
  IntervalRequest r;
  r.sheets = {{x0, 3}};
  r.sheet_bias = {{x0, parse_bias("t", "first:1e-9", tfi::Spacing::Geometric)}};
  EXPECT_NE(error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage).find("no ratio between"), std::string::npos);
}

// --size H with a bias: the smallest interval whose cells on the longest
// edge are all at most H, found here by trying every n.
TEST(BiasRequests, SizeCombinesWithBias) {
  const double L = 3;
  const CoarseMesh m = cubes(1, L);
  const Id x0 = x_sheet(m, 0, L);
  auto brute = [&](double H, const std::function<long double(Id, std::vector<long double>&)>& series) {
    for (Id n = 1; n < 100000; ++n) {
      std::vector<long double> h;
      if (series(n, h) < 0) continue;
      if (*std::max_element(h.begin(), h.end()) <= H) return n;
    }
    return Id{-1};
  };
  {  // a ratio
    IntervalRequest r;
    r.size = 0.4;
    r.sheet_bias = {{x0, parse_bias("t", "1.1", tfi::Spacing::Geometric)}};
    const FineMesh f = FineMesh::dice(m, r);
    const Id want = brute(0.4, [&](Id n, std::vector<long double>& h) { h = cells(L, n, 1.1L); return 0.0L; });
    EXPECT_EQ(f.sheet_intervals()[x0], want);
    EXPECT_EQ(f.sheet_intervals()[x0 == 0 ? 1 : 0], 3);  // the others, unbiased: ceil(1 / 0.4)
  }
  {  // a first cell: R follows from h at each n (bisection on R here, in long double)
    IntervalRequest r;
    r.size = 0.5;
    r.sheet_bias = {{x0, parse_bias("t", "first:0.02", tfi::Spacing::Geometric)}};
    const FineMesh f = FineMesh::dice(m, r);
    const Id want = brute(0.5, [&](Id n, std::vector<long double>& h) {
      long double lo = 0.01L, hi = 100;
      if (cells(L, n, hi)[0] > 0.02L || cells(L, n, lo)[0] < 0.02L) return -1.0L;  // out of reach
      for (int it = 0; it < 200; ++it) {
        const long double mid = std::sqrt(lo * hi);
        (cells(L, n, mid)[0] > 0.02L ? lo : hi) = mid;
      }
      h = cells(L, n, std::sqrt(lo * hi));
      return 0.0L;
    });
    EXPECT_EQ(f.sheet_intervals()[x0], want);
    const auto x = xs(f);
    EXPECT_NEAR(x[1] - x[0], 0.02, 1e-12);
    double largest = 0;
    for (size_t k = 0; k + 1 < x.size(); ++k) largest = std::max(largest, x[k + 1] - x[k]);
    EXPECT_LE(largest, 0.5);
  }
  {  // a ratio whose last cell never falls under H: refused, naming the sheet
    IntervalRequest r;
    r.size = 0.5;
    r.sheet_bias = {{x0, parse_bias("t", "2", tfi::Spacing::Geometric)}};  // last cell > L / 2 for every n
    const std::string e = error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage);
    EXPECT_NE(e.find("sheet " + std::to_string(x0) + ": with its bias 2, no interval"), std::string::npos) << e;
  }
}

TEST(BiasRequests, BadBiasesAreRefusedNamingTheSheet) {
  const CoarseMesh m = cubes(2);
  const Id x0 = x_sheet(m, 0);
  IntervalRequest r;
  r.global = 4;
  r.sheet_bias = {{x0, parse_bias("t", "1.5@12", tfi::Spacing::Geometric)}};  // node 12: x = 2, not on cube 0
  std::string e = error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage);
  EXPECT_NE(e.find("sheet " + std::to_string(x0) + ": node 12 is on none of its edges"), std::string::npos) << e;
  r.sheet_bias = {{99, parse_bias("t", "1.5", tfi::Spacing::Geometric)}};
  EXPECT_NE(error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage).find("no sheet 99"), std::string::npos);
  r.global = 2000;
  r.sheet_bias = {{x0, parse_bias("t", "1.05", tfi::Spacing::Geometric)}};  // 1.05^2000: cells below 2^-40
  e = error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage);
  EXPECT_NE(e.find("smallest cell"), std::string::npos) << e;
  r.global = 4;
  r.sheet_bias.clear();
  r.entities = {{{2, 1}, 3}};
  EXPECT_NE(error_of([&] { FineMesh::dice(m, r); }, ErrorKind::Usage).find("classified on geometric entities"),
            std::string::npos);
}

// Without a model topology (MSH 2.2, a mesh built in memory), an edge lies
// on its ends' common entity, or on the higher-dimensional of the two.
TEST(BiasRequests, EdgeEntitiesFromTheNodesAlone) {
  CoarseMesh m = cubes(1);
  m.vertex_geo_dim.assign(8, 2);
  m.vertex_geo_tag.assign(8, 1);
  for (Id v = 0; v < 8; ++v)
    if (m.x[v] == 1) m.vertex_geo_tag[v] = 2;  // face x = 1 is surface 2
  m.vertex_geo_dim[0] = 0;                        // a point
  const Topology t = build_topology(m);
  const auto on = edge_entities(m, t);
  for (Id e = 0; e < t.num_edges(); ++e) {
    const Id a = t.edge_v[2 * e], b = t.edge_v[2 * e + 1];
    // On face x = 0 or 1: that surface (the point's edges too); the x edges
    // from surface 1 to surface 2 are unknown, but the point's is surface 2's.
    std::int64_t want = -1;
    if (m.x[a] == m.x[b]) want = pack_owner(2, m.x[a] == 1 ? 2 : 1);
    else if (a == 0 || b == 0) want = pack_owner(2, 2);
    EXPECT_EQ(on[e], want) << "edge " << a << "-" << b;
  }
  m.vertex_geo_dim.clear();
  EXPECT_EQ(edge_entities(m, t), std::vector<std::int64_t>(static_cast<size_t>(t.num_edges()), -1));
}

// The parsers read the whole text: a NUL inside (a Python str) ended
// strtod and strtoll early ("1.2\0junk" was 1.2), and strtoll's leading
// blanks made " 2" a sheet id.
TEST(BiasRequests, ParsersReadTheWholeText) {
  const std::string nul("1.2\0junk", 8);
  EXPECT_THROW(parse_real("--size", nul), Error);
  EXPECT_THROW(parse_bias("--sheet-bias 0=x", nul, tfi::Spacing::Geometric), Error);
  EXPECT_THROW(parse_bias("--sheet-bias 0=x", std::string("1.2@17\0", 7), tfi::Spacing::Geometric), Error);
  EXPECT_THROW(parse_whole("--interval", std::string("2\0", 2)), Error);
  EXPECT_THROW(parse_whole("--interval", " 2"), Error);
  EXPECT_THROW(parse_entity("--entity-interval", std::string("2:5\0", 4)), Error);
  EXPECT_EQ(parse_whole("--interval", "+2"), 2);
  EXPECT_EQ(parse_real("--size", "1.5"), 1.5);
  EXPECT_EQ(parse_entity("--entity-interval", "2:5"), (EntityTag{2, 5}));
  IntervalOptionText text;
  text.sheet_interval = {std::string("0=3\0", 4)};
  EXPECT_THROW(parse_interval_options(text), Error);
}
