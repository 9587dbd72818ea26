// Refusals of the core: meshes that read fine but cannot be diced, and bad
// interval requests. Each checks the kind of error and the message.
#include <gtest/gtest.h>

#include <cmath>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "dicer/topology.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

CoarseMesh unit_cubes(int count) {  // a row of unit cubes along x
  CoarseMesh m;
  m.source = "row.exo";
  for (int i = 0; i <= count; ++i)
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j) m.x.push_back(i), m.y.push_back(j), m.z.push_back(k);
  auto v = [](int i, int j, int k) { return static_cast<Id>(4 * i + 2 * k + j); };
  for (int i = 0; i < count; ++i) {
    const Id c[8] = {v(i, 0, 0), v(i + 1, 0, 0), v(i + 1, 1, 0), v(i, 1, 0),
                     v(i, 0, 1), v(i + 1, 0, 1), v(i + 1, 1, 1), v(i, 1, 1)};
    m.conn.insert(m.conn.end(), c, c + 8);
  }
  return m;
}

using test::error_of;

}  // namespace

TEST(BadCore, NonManifoldFaceIsRefusedNamingTheHexes) {
  CoarseMesh m = unit_cubes(2);
  // A third hex on the face x=1, mirrored into the first cube's space is
  // inverted; instead put it above the shared face's plane through new nodes.
  const Id base = m.num_vertices();
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j) m.x.push_back(1), m.y.push_back(j - 1.0), m.z.push_back(k + 0.0);
  // Hex using face (x=1) nodes 4,6,7,5 plus new nodes on the y<0 side: shares
  // the face (1,0,0)-(1,1,0)-(1,1,1)-(1,0,1) with both cubes.
  (void)base;
  const std::vector<Id> extra = {4, 6, 7, 5, base + 0, base + 2, base + 3, base + 1};
  m.conn.insert(m.conn.end(), extra.begin(), extra.end());
  m.element_file_id = {1, 2, 3};
  for (Id q = 0; q < m.num_vertices(); ++q) m.vertex_file_id.push_back(q + 1);
  const std::string msg = error_of(
      [&] {
        // Handedness may object first for this hand-made hex; skip validation
        // to reach topology directly.
        build_topology(m);
      },
      ErrorKind::BadInput);
  EXPECT_NE(msg.find("non-manifold"), std::string::npos) << msg;
  EXPECT_NE(msg.find("elements 1, 2, 3"), std::string::npos) << msg;
}

TEST(BadCore, MixedHandednessNamesTheOddElement) {
  CoarseMesh m = unit_cubes(3);
  // Make element 2 (file id 2) left-handed by mirroring its numbering.
  Id* c = &m.conn[8];
  std::swap(c[1], c[3]), std::swap(c[5], c[7]);
  const std::string msg = error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput);
  EXPECT_NE(msg.find("mixed handedness"), std::string::npos) << msg;
  EXPECT_NE(msg.find("element 2 is left-handed"), std::string::npos) << msg;
}

TEST(BadCore, WhollyLeftHandedMeshIsReorientedWithAWarning) {
  CoarseMesh m = unit_cubes(2);
  for (Id e = 0; e < 2; ++e) {
    Id* c = &m.conn[8 * e];
    std::swap(c[1], c[3]), std::swap(c[5], c[7]);
  }
  m.side_sets.push_back({1, "", {0}, {4}});  // side 5 (bottom, z=0) in left-handed numbering
  validate_coarse_mesh(m);
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("left-handed"), std::string::npos);
  // The bottom face is still side 4 (corners 0,3,2,1 contain z=0 only).
  const int s = m.side_sets[0].side[0];
  for (int q = 0; q < 4; ++q) EXPECT_EQ(m.z[m.conn[kHexSideCorners[s][q]]], 0.0);
}

TEST(BadCore, TangledHexIsRefused) {
  CoarseMesh m = unit_cubes(1);
  m.x[m.conn[6]] = -0.5;  // pull corner 6 through the hex
  m.y[m.conn[6]] = -0.5;
  const std::string msg = error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput);
  EXPECT_NE(msg.find("element 1 is inverted or degenerate"), std::string::npos) << msg;
}

// Handedness at any scale: cubes of side 1e-110 have corner determinants
// of 1e-330, which underflowed to 0 ("inverted or degenerate"); tangled
// ones are still refused there.
TEST(BadCore, HandednessHoldsAtTinyScales) {
  CoarseMesh m = unit_cubes(2);
  for (auto* a : {&m.x, &m.y, &m.z})
    for (double& v : *a) v *= 1e-110;
  CoarseMesh tangled = m;
  EXPECT_NO_THROW(validate_coarse_mesh(m));
  IntervalRequest two;
  two.global = 2;
  EXPECT_EQ(FineMesh::dice(m, two).num_elements(), 2 * 8);
  tangled.x[tangled.conn[6]] = -0.5e-110, tangled.y[tangled.conn[6]] = -0.5e-110;
  const std::string msg = error_of([&] { validate_coarse_mesh(tangled); }, ErrorKind::BadInput);
  EXPECT_NE(msg.find("element 1 is inverted or degenerate"), std::string::npos) << msg;
  // A flat parallelepiped in a tilted plane (e3 = e1 + e2, small whole
  // numbers: every corner determinant exactly 0). Scaling the edges must
  // not turn that 0 into rounding noise of either sign.
  CoarseMesh flat = unit_cubes(1);
  const double e1[3] = {1, 2, 3}, e3[3] = {2, 1, 5}, e4[3] = {3, 3, 8};  // corner 0's edges to 1, 3, 4
  const int use[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (int k = 0; k < 8; ++k) {
    double p[3];
    for (int d = 0; d < 3; ++d) p[d] = use[k][0] * e1[d] + use[k][1] * e3[d] + use[k][2] * e4[d];
    flat.x[flat.conn[k]] = p[0], flat.y[flat.conn[k]] = p[1], flat.z[flat.conn[k]] = p[2];
  }
  const std::string f = error_of([&] { validate_coarse_mesh(flat); }, ErrorKind::BadInput);
  EXPECT_NE(f.find("element 1 is inverted or degenerate"), std::string::npos) << f;
}

TEST(BadCore, RepeatedNodeDuplicateElementAndNaNAreRefused) {
  {
    CoarseMesh m = unit_cubes(1);
    m.conn[3] = m.conn[2];
    EXPECT_NE(error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput).find("appears twice"), std::string::npos);
  }
  {
    CoarseMesh m = unit_cubes(1);
    m.conn.insert(m.conn.end(), m.conn.begin(), m.conn.begin() + 8);
    EXPECT_NE(error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput).find("duplicates element 1"),
              std::string::npos);
  }
  {  // Two sets of one id: MSH would merge them, the Exodus library refuse them.
    CoarseMesh m = unit_cubes(2);
    m.side_sets = {{4, "inlet", {0}, {3}}, {4, "outlet", {1}, {1}}};
    EXPECT_NE(error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput).find("row.exo: two side sets have id 4"),
              std::string::npos);
    CoarseMesh n = unit_cubes(2);
    n.side_sets = {{4, "inlet", {0}, {3}}};
    n.node_sets = {{4, "a", {0}}, {7, "b", {1}}, {7, "c", {2}}};  // a side set and a node set may share one
    EXPECT_NE(error_of([&] { validate_coarse_mesh(n); }, ErrorKind::BadInput).find("two node sets have id 7"),
              std::string::npos);
  }
  {
    CoarseMesh m = unit_cubes(1);
    m.z[3] = std::nan("");
    EXPECT_NE(error_of([&] { validate_coarse_mesh(m); }, ErrorKind::BadInput).find("node 4: coordinate is not finite"),
              std::string::npos);
  }
}

TEST(BadCore, BadIntervalRequestsAreRefused) {
  CoarseMesh m = unit_cubes(2);
  validate_coarse_mesh(m);
  auto dice = [&](IntervalRequest r) { FineMesh::dice(m, r); };
  IntervalRequest zero;
  zero.global = 0;
  EXPECT_NE(error_of([&] { dice(zero); }, ErrorKind::Usage).find("whole number >= 1"), std::string::npos);
  IntervalRequest neg;
  neg.sheets = {{0, -3}};
  EXPECT_NE(error_of([&] { dice(neg); }, ErrorKind::Usage).find("sheet 0"), std::string::npos);
  IntervalRequest nosheet;
  nosheet.sheets = {{99, 2}};
  EXPECT_NE(error_of([&] { dice(nosheet); }, ErrorKind::Usage).find("no sheet 99"), std::string::npos);
  IntervalRequest noblock;
  noblock.blocks = {{"inlet", 2}};
  EXPECT_NE(error_of([&] { dice(noblock); }, ErrorKind::Usage).find("no block with id or name \"inlet\""),
            std::string::npos);
  {  // Two blocks named alike (Exodus allows it): the name is refused, not
     // taken for the first; each id still works.
    CoarseMesh two = unit_cubes(2);
    two.blocks = {{1, "right"}, {2, "right"}};
    two.element_block = {0, 1};
    validate_coarse_mesh(two);
    IntervalRequest by_name;
    by_name.blocks = {{"right", 3}};
    const std::string what = error_of([&] { FineMesh::dice(two, by_name); }, ErrorKind::Usage);
    EXPECT_NE(what.find("\"right\" names more than one block (block 1 (right), block 2 (right)); give the block's id"),
              std::string::npos) << what;
    IntervalRequest by_id;
    by_id.blocks = {{"2", 3}};
    // Block 2's three sheets get 3; its y and z sheets run through block 1
    // too, whose own x sheet keeps 1: 27 + 9 fine hexes.
    EXPECT_EQ(FineMesh::dice(two, by_id).num_elements(), 27 + 9);
    // "2" is block 2's id and block 1's name: the id wins, said in a note.
    two.blocks = {{1, "2"}, {2, "x"}};
    std::vector<std::string> notes;
    EXPECT_EQ(FineMesh::dice(two, by_id, &notes).num_elements(), 27 + 9);
    std::string all;
    for (const auto& n : notes) all += n + "\n";
    EXPECT_NE(all.find("\"2\" is the id of block 2 (x) and the name of block 1 (2): block 2 (x) was taken"),
              std::string::npos) << all;
  }
  IntervalRequest size;
  size.size = -1;
  EXPECT_NE(error_of([&] { dice(size); }, ErrorKind::Usage).find("--size"), std::string::npos);
  // A size too small for 2^40 intervals, which may come from an intervals
  // file: named by its value, not as "--size".
  size.size = 1e-300;
  const std::string tiny = error_of([&] { dice(size); }, ErrorKind::Overflow);
  EXPECT_NE(tiny.find("at size 1e-300 (its longest edge "), std::string::npos) << tiny;
  // (2^40 + 1)^3 grid points in one hex: more than any reader takes
  // (rows.hpp, kMaxElementPoints), refused at dice time with the numbers.
  IntervalRequest huge;
  huge.global = Id{1} << 40;
  const std::string msg = error_of([&] { dice(huge); }, ErrorKind::Overflow);
  EXPECT_NE(msg.find("1099511627776 x 1099511627776"), std::string::npos) << msg;
  // The boundary itself: 10320 intervals give 10321^3 < 2^40 points, 10321 give 10322^3 > 2^40.
  IntervalRequest edge;
  edge.global = 10321;
  EXPECT_NE(error_of([&] { dice(edge); }, ErrorKind::Overflow).find("2^40 grid points"), std::string::npos);
}

TEST(BadCore, IntervalConflictsAreReportedBySheetAndBlock) {
  CoarseMesh m = unit_cubes(2);
  m.blocks = {{2, "left"}, {3, "right"}};
  m.element_block = {0, 1};
  validate_coarse_mesh(m);
  IntervalRequest r;
  r.blocks = {{"2", 4}, {"right", 6}};
  std::vector<std::string> notes;
  const FineMesh f = FineMesh::dice(m, r, &notes);
  // Sheets along y and z cross both blocks: they take the larger, 6, and say so.
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes[0].find("block 2 (left) asks 4"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("block 3 (right) asks 6"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("using the largest, 6"), std::string::npos) << notes[0];
  // x sheets: left cube 4, right cube 6; y and z: 6. Elements: (4*6*6) + (6*6*6).
  EXPECT_EQ(f.num_elements(), 4 * 36 + 216);
}

TEST(BadCore, IntervalFileErrors) {
  test::TempDir tmp;
  const std::string p = tmp.path("plan.json");
  test::write_file(p, "{\"global\": 4, \"sheet\": {}}");
  EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find("unknown key \"sheet\""), std::string::npos);
  test::write_file(p, "{\"global\": 4,");
  EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find("not valid JSON"), std::string::npos);
  test::write_file(p, "{\"blocks\": {\"2\": 2.5}}");
  EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find("whole number"), std::string::npos);
  // A key twice (nlohmann keeps the last, silently), in the file or in a
  // nested object; sheet ids that strtoll would bend (" 2", "+2", past 2^63).
  for (const char* twice : {"{\"global\": 4, \"global\": 7}", "{\"sheets\": {\"2\": 3, \"2\": 5}}",
                            "{\"blocks\": {\"1\": {\"interval\": 2, \"interval\": 3}}}"}) {
    test::write_file(p, twice);
    EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find("appears twice in one object"),
              std::string::npos)
        << twice;
  }
  for (const char* bent : {" 2", "+2", "99999999999999999999", "2 ", "02"}) {
    test::write_file(p, std::string("{\"sheets\": {\"") + bent + "\": 3}}");
    EXPECT_NE(error_of([&] { read_interval_file(p); }, ErrorKind::Usage).find("is not a sheet id"), std::string::npos)
        << bent;
  }
  test::write_file(p, "{\"global\": 3, \"size\": 0.5, \"blocks\": {\"2\": 6, \"inlet\": 3}, \"sheets\": {\"17\": 12}}");
  const IntervalRequest r = read_interval_file(p);
  EXPECT_EQ(r.global, 3);
  EXPECT_EQ(r.size, 0.5);
  EXPECT_EQ(r.blocks.size(), 2u);
  ASSERT_EQ(r.sheets.size(), 1u);
  EXPECT_EQ(r.sheets[0], (std::pair<Id, Id>{17, 12}));
}

// Programmer errors are assertions that stay on in release builds: they
// throw InternalError (not a dicer::Error, so the CLI says "internal
// error", exit 70), never abort.
TEST(BadCore, AssertionsStayOnAndThrowInternalError) {
  const CoarseMesh m = unit_cubes(3);
  const Topology sorted = build_topology(m);  // not in owner order
  std::vector<Id> n(static_cast<size_t>(sorted.num_edges()), 2);
  EXPECT_THROW(Numbering(sorted, n), InternalError);
  try {
    Numbering bad(sorted, n);
  } catch (const InternalError& e) {
    EXPECT_NE(std::string(e.what()).find("owner order"), std::string::npos) << e.what();
  }
}
