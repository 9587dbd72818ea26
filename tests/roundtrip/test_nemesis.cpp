// Decomposed Exodus (Nemesis) written by `dicer export --chunks P --nemesis`,
// read back twice: with the Exodus library's Nemesis getters (compared
// with the Partition the files were made from) and with netCDF4-python
// (tests/roundtrip/nemesis_check.py: every element once, shared nodes
// symmetric and equal in coordinates).
#include <exodusII.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "dicer/partition.hpp"
#include "dicer/store.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

struct Exo {
  int id = -1;
  explicit Exo(const std::string& path) {
    int cpu = 8, io = 0;
    float version = 0;
    id = ex_open(path.c_str(), EX_READ, &cpu, &io, &version);
    if (id >= 0) ex_set_int64_status(id, EX_ALL_INT64_API);
  }
  ~Exo() {
    if (id >= 0) ex_close(id);
  }
};

}  // namespace

TEST(Nemesis, FilesCarryThePartitionsAndReadBackEverywhere) {
  test::TempDir tmp;
  const std::string store = tmp.path("prism.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_prism.exo"), "--interval", "2", "-o", store}).exit_code, 0);
  const FineMesh m = read_store(store);
  const StoreSets ss = read_store_sets(store);
  const MeshSets sets{ss.side_sets, ss.node_sets};
  for (Id P : {1, 2, 3, 4}) {
    SCOPED_TRACE("P = " + std::to_string(P));
    const std::string out = tmp.path("p" + std::to_string(P) + ".e");
    const auto r = test::run_cli({"export", store, "--format", "exodus", "--chunks", std::to_string(P), "--nemesis",
                                  "-o", out, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out)) << "only the OUT.P.r files";
    const auto plan = plan_chunks(m, P);
    const auto sharing = in_process_sharing(m, plan);
    for (Id rank = 0; rank < P; ++rank) {
      const std::string file = nemesis_path(out, P, rank);
      ASSERT_TRUE(std::filesystem::exists(file)) << file;
      const Partition part(m, plan, rank, sharing[static_cast<size_t>(rank)], sets);
      Exo e(file);
      ASSERT_GE(e.id, 0) << file;
      std::int64_t nodes_g = 0, elems_g = 0, blks_g = 0, ns_g = 0, ss_g = 0;
      ASSERT_EQ(ex_get_init_global(e.id, &nodes_g, &elems_g, &blks_g, &ns_g, &ss_g), 0);
      EXPECT_EQ(nodes_g, m.num_nodes());
      EXPECT_EQ(elems_g, m.num_elements());
      EXPECT_EQ(blks_g, static_cast<std::int64_t>(m.info().blocks.size()));
      EXPECT_EQ(ss_g, static_cast<std::int64_t>(sets.side_sets.size()));
      int procs = 0, in_file = 0;
      char ftype[2] = {0, 0};
      ASSERT_EQ(ex_get_init_info(e.id, &procs, &in_file, ftype), 0);
      EXPECT_EQ(procs, P);
      // The title counts chunks as --chunk K/N and the file names do: from 0.
      ex_init_params init{};
      ASSERT_EQ(ex_get_init_ext(e.id, &init), 0);
      EXPECT_EQ(std::string(init.title), "dicer: chunk " + std::to_string(rank) + "/" + std::to_string(P) +
                                             " from cardinal_prism.exo");
      std::int64_t ni = 0, nb = 0, nx = 0, ei = 0, eb = 0, ncm = 0, ecm = 0;
      ASSERT_EQ(ex_get_loadbal_param(e.id, &ni, &nb, &nx, &ei, &eb, &ncm, &ecm, static_cast<int>(rank)), 0);
      EXPECT_EQ(ni + nb, part.num_nodes());
      EXPECT_EQ(nx, 0);
      EXPECT_EQ(ei + eb, part.num_elements());
      ASSERT_EQ(ncm, static_cast<std::int64_t>(part.neighbors().size()));
      if (P == 1) {
        EXPECT_EQ(nb, 0);
      }
      std::vector<std::int64_t> ids(static_cast<size_t>(ncm) + 1), cnts(ids.size()), none(1);
      ASSERT_EQ(ex_get_cmap_params(e.id, ids.data(), cnts.data(), none.data(), none.data(), static_cast<int>(rank)), 0);
      for (std::int64_t k = 0; k < ncm; ++k) {
        EXPECT_EQ(ids[k], part.neighbors()[static_cast<size_t>(k)]);
        const auto& shared = part.shared_nodes()[static_cast<size_t>(k)];
        ASSERT_EQ(cnts[k], static_cast<std::int64_t>(shared.size()));
        std::vector<std::int64_t> nodes(shared.size()), procs_of(shared.size());
        ASSERT_EQ(ex_get_node_cmap(e.id, ids[k], nodes.data(), procs_of.data(), static_cast<int>(rank)), 0);
        for (size_t q = 0; q < shared.size(); ++q) {
          EXPECT_EQ(nodes[q] - 1, part.chunk_local(shared[q]));
          EXPECT_EQ(procs_of[q], ids[k]);
        }
      }
    }
    const auto py = test::run_process({"/usr/bin/python3", DICER_SOURCE_DIR "/tests/roundtrip/nemesis_check.py", out,
                                       std::to_string(P), std::to_string(m.num_nodes()), std::to_string(m.num_elements())},
                                      {}, test::kForeignPythonEnv);
    if (py.exit_code == 77) DICER_SKIP_OR_FAIL_IN_CI("netCDF4-python missing");
    EXPECT_EQ(py.exit_code, 0) << py.err;
  }
}

TEST(Nemesis, RefusedWithoutChunksOrWithAnotherFormat) {
  test::TempDir tmp;
  const std::string store = tmp.path("s.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "1", "-o", store}).exit_code, 0);
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"export", store, "--format", "exodus", "--nemesis", "-o", tmp.path("a.e")},
        {"export", store, "--format", "msh", "--chunks", "2", "--nemesis", "-o", tmp.path("a.msh")}}) {
    const auto r = test::run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("--nemesis"), std::string::npos) << r.err;
  }
}

// The files written are OUT.N.r: one of them that is the store itself is
// refused before anything is written, and the store is left as it was.
TEST(Nemesis, AnOutputFileThatIsTheStoreIsRefused) {
  test::TempDir tmp;
  const std::string store = tmp.path("p.e.2.1");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "1", "-o", store}).exit_code, 0);
  const std::string before = test::read_file(store);
  const auto r = test::run_cli({"export", store, "--format", "exodus", "--chunks", "2", "--nemesis", "-o", tmp.path("p.e")});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("same file as STORE"), std::string::npos) << r.err;
  EXPECT_EQ(test::read_file(store), before);
  EXPECT_FALSE(std::filesystem::exists(tmp.path("p.e.2.0")));
}

// More chunks than coarse elements is refused, as --chunk K/N is, not
// quietly cut (a job expecting OUT.N.* for N ranks would not find them).
TEST(Nemesis, MoreChunksThanCoarseElementsIsRefused) {
  test::TempDir tmp;
  const std::string store = tmp.path("s.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "1", "-o", store}).exit_code, 0);
  const Id coarse = read_store(store).num_coarse_elements();
  const std::string too_many = std::to_string(coarse + 1);
  for (const std::string fmt : {"exodus", "vtkhdf"}) {
    std::vector<std::string> args{"export", store, "--format", fmt, "--chunks", too_many, "-o", tmp.path("x." + fmt)};
    if (fmt == "exodus") args.push_back("--nemesis");
    const auto r = test::run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << fmt << ": " << r.err;
    EXPECT_NE(r.err.find("only " + std::to_string(coarse) + " coarse elements"), std::string::npos) << r.err;
  }
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(tmp.dir()), std::filesystem::directory_iterator()), 1);
  const auto r = test::run_cli({"export", store, "--chunks", std::to_string(coarse), "-o", tmp.path("all.vtkhdf")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("in " + std::to_string(coarse) + " chunks"), std::string::npos) << r.out;
}
