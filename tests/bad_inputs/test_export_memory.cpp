// A chunk that cannot fit in memory: until exports stream, ExportChunk
// holds the whole chunk, so prepare() refuses one whose estimate exceeds
// what the process can still allocate (MemAvailable, RLIMIT_AS), with a
// chunk count that fits, before building anything.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

#include "dicer/export.hpp"
#include "dicer/store.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;

namespace {

// A box of k x k x k unit hexes, MSH 2.2: at k = 2, interval 500, a store
// of 10^9 fine elements, diced in a moment.
std::string box_msh(const test::TempDir& d, int k) {
  const std::string p = d.path("box" + std::to_string(k) + ".msh");
  auto node = [k](int i, int j, int l) { return 1 + i + (k + 1) * (j + (k + 1) * l); };
  std::ostringstream s;
  s << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" << (k + 1) * (k + 1) * (k + 1) << "\n";
  for (int l = 0; l <= k; ++l)
    for (int j = 0; j <= k; ++j)
      for (int i = 0; i <= k; ++i) s << node(i, j, l) << " " << i << " " << j << " " << l << "\n";
  s << "$EndNodes\n$Elements\n" << k * k * k << "\n";
  int e = 0;
  for (int l = 0; l < k; ++l)
    for (int j = 0; j < k; ++j)
      for (int i = 0; i < k; ++i)
        s << ++e << " 5 2 1 1 " << node(i, j, l) << " " << node(i + 1, j, l) << " " << node(i + 1, j + 1, l) << " "
          << node(i, j + 1, l) << " " << node(i, j, l + 1) << " " << node(i + 1, j, l + 1) << " "
          << node(i + 1, j + 1, l + 1) << " " << node(i, j + 1, l + 1) << "\n";
  s << "$EndElements\n";
  test::write_file(p, s.str());
  return p;
}

}  // namespace

// The estimate counts what ExportChunk keeps: 8 B id + 4 B block +
// 8 corners x 8 B per hex, 8 B id + 3 x 8 B coordinates + 4 B owner per node.
TEST(ExportMemory, EstimateCountsTheChunksArrays) {
  test::TempDir d;
  const std::string store = d.path("hex.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", box_msh(d, 1), "--interval", "10", "-o", store}).exit_code, 0);
  const FineMesh m = read_store(store);
  const ChunkRange whole{0, 1, 0, 1, m.num_elements()};
  EXPECT_EQ(estimate_chunk_bytes(m, whole), 1000u * (8 + 4 + 64) + 1331u * (8 + 24 + 4));
  ExportChunk c(m, whole);
  c.prepare({});
  // What prepare() built, counted the same way.
  const std::uint64_t held = c.element_global().size() * 8 + c.element_block().size() * 4 + c.connectivity().size() * 8 +
                             c.node_global().size() * 8 + (c.x().size() + c.y().size() + c.z().size()) * 8 +
                             c.node_owner().size() * 4;
  EXPECT_EQ(estimate_chunk_bytes(m, whole), held);
}

// A whole-mesh export of 10^9 elements needs ~100 GiB: refused up front
// (the old code ran for 20 s to 7.6 GiB and died, exit 70), also under an
// address-space limit, with a chunk count that fits; nothing written.
TEST(ExportMemory, ChunkThatCannotFitIsRefusedWithAChunkCount) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build (the Release suite runs this)";
#endif
  if (!fs::exists("/usr/bin/prlimit")) DICER_SKIP_OR_FAIL_IN_CI("needs prlimit (util-linux)");
  test::TempDir d;
  const std::string store = d.path("billion.dice.h5");
  {
    const auto r = test::run_cli({"dice", box_msh(d, 2), "--interval", "500", "-o", store});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const std::string out = d.path("out.msh");
  for (const std::vector<std::string>& extra : {std::vector<std::string>{}, std::vector<std::string>{"--chunk", "0/4"}}) {
    std::vector<std::string> argv{"/usr/bin/timeout", "-s", "KILL", "60", "/usr/bin/prlimit", "--as=4294967296", "--",
                                  DICER_CLI, "export", store, "--format", "msh", "-o", out, "--quiet"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const auto r = test::run_process(argv);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("GiB of memory"), std::string::npos) << r.err;
    const auto at = r.err.find("N >= ");
    ASSERT_NE(at, std::string::npos) << r.err;
    // Each of N chunks holds 1/N of the estimate: at most half the limit.
    const double n = std::stod(r.err.substr(at + 5));
    EXPECT_GE(n * 2.0 * (1ull << 32), 1e9 * 76 + 1.003e9 * 36) << r.err;
    EXPECT_LE(n, 1000) << r.err;
    EXPECT_FALSE(fs::exists(out));
  }
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(d.dir())) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"billion.dice.h5", "box2.msh"}));
}
