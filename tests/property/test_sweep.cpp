// The sweep checksum: independent of thread count and cache budget, and
// equal to the same sum computed through node(id) and element(id).
#include <gtest/gtest.h>

#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "test_support.hpp"

using namespace dicer;

TEST(Sweep, ChecksumIsTheSameForEveryThreadCountAndCacheBudget) {
  IntervalRequest r;
  r.global = 3;
  const FineMesh mem = FineMesh::dice(read_coarse_mesh(test::data_path("vtkdata_mug.e")), r);
  // Independent: the sum over node(id) and element(id), in id order.
  std::uint64_t expected = 0;
  for (Id id = 0; id < mem.num_nodes(); ++id) expected += node_checksum_term(id, mem.node(id));
  for (Id id = 0; id < mem.num_elements(); ++id) expected += element_checksum_term(mem.element(id));
  test::TempDir tmp;
  write_store(mem, tmp.path("m.dice.h5"));
  for (unsigned threads : {1u, 2u, 3u, 7u}) {
    const SweepResult a = sweep(mem, threads);
    EXPECT_EQ(a.checksum, expected) << threads << " threads, in memory";
    EXPECT_EQ(a.nodes, mem.num_nodes());
    EXPECT_EQ(a.elements, mem.num_elements());
    for (std::uint64_t mb : {1, 5, 64}) {  // 1 MiB: one thread; 5 MiB: two
      const FineMesh s = read_store(tmp.path("m.dice.h5"), StoreOptions{mb << 20, 4});
      const SweepResult b = sweep(s, threads);
      EXPECT_EQ(b.checksum, expected) << threads << " threads, " << mb << " MiB";
      EXPECT_LE(store_cache(s)->stats().peak_resident_bytes, store_cache(s)->budget());
      EXPECT_EQ(b.threads, std::min<unsigned>(threads, mb == 1 ? 1 : mb == 5 ? 2 : threads));
    }
  }
  // The command line prints the same checksum, whatever --threads says.
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(expected));
  for (const char* t : {"1", "2"}) {
    const auto c = test::run_cli({"sweep", tmp.path("m.dice.h5"), "--threads", t, "--json"});
    ASSERT_EQ(c.exit_code, 0) << c.err;
    EXPECT_NE(c.out.find(std::string("\"checksum\":\"") + hex + "\""), std::string::npos) << c.out;
    EXPECT_NE(c.out.find("\"nodes_per_s\":"), std::string::npos);
  }
}
