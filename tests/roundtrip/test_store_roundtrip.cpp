// In-memory fine mesh -> store -> every query bit-identical; the real mesh
// corpus dices and verifies at several intervals.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <random>

#include "dicer/error.hpp"
#include "dicer/store.hpp"
#include "dicer/verify.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

TEST(StoreRoundTrip, EveryNodeAndElementIsBitIdentical) {
  std::mt19937_64 rng(2024);
  test::BoxSpec spec;
  spec.a = 3, spec.b = 2, spec.c = 2, spec.blocks = 2;
  CoarseMesh m = test::random_box(spec, rng);
  m.side_sets.push_back({7, "bottom", {0, 1}, {4, 4}});
  m.node_sets.push_back({3, "corner", {0}});
  IntervalRequest req;
  req.global = 3;
  req.blocks = {{"11", 4}};
  const FineMesh a = FineMesh::dice(m, req);
  test::TempDir tmp;
  const std::string path = tmp.path("box.dice.h5");
  write_store(a, path);
  const FineMesh b = read_store(path);
  ASSERT_EQ(a.num_nodes(), b.num_nodes());
  ASSERT_EQ(a.num_elements(), b.num_elements());
  for (Id id = 0; id < a.num_nodes(); ++id) ASSERT_EQ(a.node(id), b.node(id)) << id;
  for (Id id = 0; id < a.num_elements(); ++id) {
    const FineElement x = a.element(id), y = b.element(id);
    ASSERT_EQ(x.nodes, y.nodes);
    ASSERT_EQ(x.block, y.block);
    ASSERT_EQ(x.ijk, y.ijk);
  }
  ASSERT_EQ(b.info().blocks.size(), 2u);
  EXPECT_EQ(b.info().blocks[1].name, "slab1");
  EXPECT_EQ(b.info().block_fine_elements, a.info().block_fine_elements);
  EXPECT_EQ(b.sheet_intervals(), a.sheet_intervals());
  // Sets stay on disk until asked for; elements in the store's (reordered) numbering.
  const StoreSets sets = read_store_sets(path);
  ASSERT_EQ(sets.side_sets.size(), 1u);
  EXPECT_EQ(sets.side_sets[0].name, "bottom");
  EXPECT_EQ(sets.side_sets[0].side, (std::vector<std::int8_t>{4, 4}));
  EXPECT_EQ(sets.side_sets[0].element, a.coarse()->side_sets[0].element);
  ASSERT_EQ(sets.node_sets.size(), 1u);
  EXPECT_EQ(sets.node_sets[0].vertex, a.coarse()->node_sets[0].vertex);
  // Nothing but the final file is left in the folder.
  size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.dir())) ++files;
  EXPECT_EQ(files, 1u);
}

TEST(StoreRoundTrip, WriteFailureLeavesExistingStoreIntact) {
  std::mt19937_64 rng(1);
  const CoarseMesh m = test::random_box({}, rng);
  test::TempDir tmp;
  const std::string path = tmp.path("x.dice.h5");
  IntervalRequest req;
  req.global = 2;
  write_store(FineMesh::dice(m, req), path);
  const std::string before = test::read_file(path);
  // Writing into a folder that does not exist fails and touches nothing else.
  EXPECT_THROW(write_store(FineMesh::dice(m, req), tmp.path("missing/dir/y.dice.h5")), Error);
  EXPECT_EQ(test::read_file(path), before);
}

struct CorpusCase {
  const char* file;
  Mode mode;
  Id coarse_elements;  // from tests/data/PROVENANCE.md
};

class Corpus : public ::testing::TestWithParam<CorpusCase> {};

TEST_P(Corpus, DicesAndVerifiesAtSeveralIntervals) {
  const CorpusCase c = GetParam();
  const CoarseMesh m = read_coarse_mesh(test::data_path(c.file));
  EXPECT_EQ(m.mode, c.mode);
  EXPECT_EQ(m.num_elements(), c.coarse_elements);
  for (Id n : {1, 2, 3}) {
    IntervalRequest req;
    req.global = n;
    if (n == 3) req.sheets = {{0, 5}};  // mixed intervals
    const FineMesh f = FineMesh::dice(m, req);
    const VerifyReport r = verify(f);
    EXPECT_TRUE(r.ok()) << c.file << " interval " << n << ": " << (r.problems.empty() ? "" : r.problems[0]);
    if (n == 2) {
      const Id per = m.mode == Mode::Volume ? 8 : 4;
      EXPECT_EQ(f.num_elements(), per * c.coarse_elements);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, Corpus,
                         ::testing::Values(CorpusCase{"vtkdata_disk_out_ref.ex2", Mode::Volume, 7472},
                                           CorpusCase{"vtkdata_mug.e", Mode::Volume, 2476},
                                           CorpusCase{"cardinal_pincell.e", Mode::Volume, 5310},
                                           CorpusCase{"cardinal_cylinders.exo", Mode::Volume, 9128},
                                           CorpusCase{"cardinal_brick.e", Mode::Volume, 3486},
                                           CorpusCase{"cardinal_triso_solid.e", Mode::Volume, 3960},
                                           CorpusCase{"cardinal_sphere.e", Mode::Volume, 256},
                                           CorpusCase{"cardinal_prism.exo", Mode::Volume, 1863},
                                           CorpusCase{"libmesh_cylinder_shell.exo", Mode::Surface, 416},
                                           CorpusCase{"firedrake_cube_hex.msh", Mode::Volume, 768},
                                           CorpusCase{"dealii_grid_in_msh_01.3da.v41.msh", Mode::Volume, 200},
                                           CorpusCase{"dealii_step-49_example.msh", Mode::Surface, 744}),
                         [](const auto& info) {
                           std::string s = info.param.file;
                           for (char& ch : s)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return s;
                         });

// The paper's sheet traversal (BFS over opposite edges of every hex face),
// written independently of Topology, must give the same partition.
TEST(Sheets, MatchThePaperTraversalOnRealMeshes) {
  for (const char* file : {"cardinal_sphere.e", "vtkdata_mug.e", "cardinal_brick.e", "dealii_grid_in_msh_01.3da.v41.msh"}) {
    const CoarseMesh m = read_coarse_mesh(test::data_path(file));
    std::map<std::pair<Id, Id>, std::vector<std::pair<Id, Id>>> opposite;
    auto key = [](Id a, Id b) { return std::make_pair(std::min(a, b), std::max(a, b)); };
    static const int faces[6][4] = {{0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}, {0, 3, 2, 1}, {4, 5, 6, 7}};
    for (Id h = 0; h < m.num_elements(); ++h)
      for (const auto& f : faces) {
        const Id* c = &m.conn[8 * h];
        const auto e0 = key(c[f[0]], c[f[1]]), e2 = key(c[f[2]], c[f[3]]);
        const auto e1 = key(c[f[1]], c[f[2]]), e3 = key(c[f[3]], c[f[0]]);
        opposite[e0].push_back(e2), opposite[e2].push_back(e0);
        opposite[e1].push_back(e3), opposite[e3].push_back(e1);
      }
    std::map<std::pair<Id, Id>, int> sheet_of;
    int sheets = 0;
    for (const auto& [edge, _] : opposite) {
      if (sheet_of.count(edge)) continue;
      std::vector<std::pair<Id, Id>> todo{edge};
      sheet_of[edge] = sheets;
      while (!todo.empty()) {
        const auto e = todo.back();
        todo.pop_back();
        for (const auto& o : opposite[e])
          if (!sheet_of.count(o)) sheet_of[o] = sheets, todo.push_back(o);
      }
      ++sheets;
    }
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    ASSERT_EQ(s.num_sheets(), sheets) << file;
    ASSERT_EQ(static_cast<size_t>(t.num_edges()), sheet_of.size()) << file;
    // Same partition: the map sheet -> oracle sheet is a bijection.
    std::map<Id, int> to_oracle;
    for (Id e = 0; e < t.num_edges(); ++e) {
      const int o = sheet_of.at(key(t.edge_v[2 * e], t.edge_v[2 * e + 1]));
      auto [it, fresh] = to_oracle.emplace(s.edge_sheet[e], o);
      ASSERT_EQ(it->second, o) << file << ": edge " << e;
    }
    EXPECT_EQ(to_oracle.size(), static_cast<size_t>(sheets));
  }
}
