// Export memory. `dicer export` streams (ChunkStream): its peak memory does
// not grow with the mesh, pinned here by running it on two stores 8x apart
// and reading each run's peak RSS. ExportChunk still holds a chunk whole
// (the Python module, box selections), so its prepare() refuses one whose
// estimate exceeds what the process can still allocate (MemAvailable,
// RLIMIT_AS), with a chunk count that fits, before building anything.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <thread>
#include <tuple>
#include <filesystem>
#include <map>
#include <sstream>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/store.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;

namespace {

// A box of k x k x k unit hexes, MSH 2.2: at k = 4, interval 500, a store
// of 8 x 10^9 fine elements, diced in a moment.
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

// Runs argv (no shell, output discarded); its exit status and peak
// resident memory in bytes (ru_maxrss of the child).
std::pair<int, double> run_measured(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {  // only async-signal-safe calls until exec
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1), ::dup2(null, 2);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  struct rusage ru {};
  if (pid < 0 || ::wait4(pid, &status, 0, &ru) != pid) return {-1, 0};
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128, static_cast<double>(ru.ru_maxrss) * 1024};
}

// Starts the CLI, sends SIGTERM 1.5 s later: it must end with 143 within
// a minute (a hang check, not a timing) and leave no `out`.
void expect_sigterm_ends(const std::vector<std::string>& args, const std::string& out) {
  const auto inherited = std::signal(SIGTERM, SIG_DFL);
  const pid_t pid = test::spawn_cli(args);
  std::signal(SIGTERM, inherited);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ::kill(pid, SIGTERM);
  int status = 0;
  bool ended = false;
  for (int t = 0; t < 600 && !ended; ++t) {
    ended = ::waitpid(pid, &status, WNOHANG) == pid;
    if (!ended) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (!ended) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    FAIL() << args[0] << " ignored SIGTERM for a minute";
  }
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 143);
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace

// The estimate counts what ExportChunk keeps: 8 B id + 4 B block +
// 8 corners x 8 B per hex, 8 B id + 3 x 8 B coordinates + 4 B owner + 4 B
// using blocks per node.
TEST(ExportMemory, EstimateCountsTheChunksArrays) {
  test::TempDir d;
  const std::string store = d.path("hex.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", box_msh(d, 1), "--interval", "10", "-o", store}).exit_code, 0);
  const FineMesh m = read_store(store);
  const ChunkRange whole{0, 1, 0, 1, m.num_elements()};
  EXPECT_EQ(estimate_chunk_bytes(m, whole), 1000u * (8 + 4 + 64) + 1331u * (8 + 24 + 4 + 4));
  ExportChunk c(m, whole);
  c.prepare({});
  // What prepare() built, counted the same way.
  const std::uint64_t held = c.element_global().size() * 8 + c.element_block().size() * 4 + c.connectivity().size() * 8 +
                             c.node_global().size() * 8 + (c.x().size() + c.y().size() + c.z().size()) * 8 +
                             c.node_owner().size() * 4 + c.node_users().size() * 4;
  EXPECT_EQ(estimate_chunk_bytes(m, whole), held);
}

// A held chunk of 8e9 elements needs ~800 GiB: refused up front with a
// chunk count that fits, nothing built.
TEST(ExportMemory, HeldChunkThatCannotFitIsRefusedWithAChunkCount) {
  test::TempDir d;
  const std::string store = d.path("big.dice.h5");
  {
    const auto r = test::run_cli({"dice", box_msh(d, 4), "--interval", "500", "-o", store});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const FineMesh m = read_store(store);
  ASSERT_EQ(m.num_elements(), Id{8000000000});
  for (Id n : {1, 4}) {
    ExportChunk c(m, plan_chunks(m, n)[0]);
    try {
      c.prepare({});
      FAIL() << "a chunk of " << m.num_elements() / n << " elements was built";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.kind(), ErrorKind::Usage) << what;
      EXPECT_NE(what.find("GiB of memory"), std::string::npos) << what;
      const auto at = what.find("N >= ");
      if (at == std::string::npos) {
        // A coarse element alone needs 500^3 x 76 + 501^3 x 40 B = 13.5
        // GiB (the estimate's rates, above): with less free no N helps, and
        // none is offered (a count past the 64 elements was, and "64 would
        // not fit" was said with up to 27 GiB free, where 64 fit).
        EXPECT_NE(what.find("a chunk holds whole coarse elements, and coarse element "), std::string::npos) << what;
        EXPECT_NE(what.find(" alone needs about 13.5 GiB: stream it instead"), std::string::npos) << what;
      } else {
        // Each of N chunks holds 1/N of the estimate: at most half of what is available.
        const double chunks = std::stod(what.substr(at + 5));
        EXPECT_GE(chunks, 8e9 * 76 / (64.0 * (1ull << 30))) << what;  // no machine here has 64 GiB free per chunk
        EXPECT_LE(chunks, 64) << what;
      }
    }
    EXPECT_EQ(c.num_elements(), 0);
  }
}

// `dicer export` streams: on a mesh 8x larger its peak memory stays put in
// every format (a held chunk would grow by ~120 B per element: 220 MiB
// here). Release only: sanitizers add their own memory per allocation.
TEST(ExportMemory, StreamingExportPeakMemoryDoesNotGrowWithTheMesh) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation (the Release suite runs this)";
#endif
  test::TempDir d;
  const std::string mesh = box_msh(d, 2);
  std::map<Id, std::string> stores;  // fine elements -> store
  for (const char* interval : {"32", "64"}) {
    const std::string store = d.path(std::string("box") + interval + ".dice.h5");
    const auto r = test::run_cli({"dice", mesh, "--interval", interval, "-o", store});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    stores[read_store(store).num_elements()] = store;
  }
  ASSERT_EQ(stores.begin()->first * 8, stores.rbegin()->first);
  const FineMesh big = read_store(stores.rbegin()->second);
  const double held_growth = 7.0 / 8.0 * static_cast<double>(estimate_chunk_bytes(big, plan_chunks(big, 1)[0]));
  ASSERT_GT(held_growth, 200.0 * (1 << 20)) << "the larger export must be one a held chunk could not hide";
  for (const std::vector<std::string>& how :
       {std::vector<std::string>{"--format", "msh"}, std::vector<std::string>{"--format", "exodus"},
        std::vector<std::string>{"--format", "vtkhdf"}, std::vector<std::string>{"--format", "vtkhdf", "--deflate", "1"},
        std::vector<std::string>{"--format", "exodus", "--chunk", "1/2"}}) {
    std::string label;
    for (const auto& a : how) label += a + " ";
    double peak[2] = {0, 0};
    int k = 0;
    for (const auto& [elements, store] : stores) {
      std::vector<std::string> argv{DICER_CLI, "export", store, "-o", d.path("out"), "--quiet"};
      argv.insert(argv.end(), how.begin(), how.end());
      const auto [status, rss] = run_measured(argv);
      ASSERT_EQ(status, 0) << label << elements;
      ASSERT_GT(rss, 0) << label;
      peak[k++] = rss;
      std::filesystem::remove(d.path("out"));
    }
    EXPECT_LT(peak[1] - peak[0], 8.0 * (1 << 20)) << label << ": peak RSS " << peak[0] / (1 << 20) << " -> "
                                                  << peak[1] / (1 << 20) << " MiB for 8x the elements";
    EXPECT_LT(peak[1], 96.0 * (1 << 20)) << label << ": peak RSS " << peak[1] / (1 << 20) << " MiB";
  }
}

// `dicer dice` without --geometry writes the tables' rows as it makes them
// (DicedRows): its peak grows by the coarse mesh, topology and numbering,
// ~1.2 KB a coarse hex, where compiling the tables first added ~1.4 KB
// more (2.7 KB a hex measured from 8,000 to 64,000 hexes before). Release
// only, as above.
TEST(ExportMemory, DiceStraightToAStoreHoldsNoTables) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation (the Release suite runs this)";
#endif
  test::TempDir d;
  double peak[2] = {0, 0};
  const int k[2] = {20, 40};
  for (int q = 0; q < 2; ++q) {
    const auto [status, rss] =
        run_measured({DICER_CLI, "dice", box_msh(d, k[q]), "--interval", "2", "-o", d.path("box.dice.h5"), "--quiet"});
    ASSERT_EQ(status, 0) << k[q];
    peak[q] = rss;
  }
  const double per_hex = (peak[1] - peak[0]) / (k[1] * k[1] * k[1] - k[0] * k[0] * k[0]);
  EXPECT_LT(per_hex, 1700) << "peak RSS " << peak[0] / (1 << 20) << " -> " << peak[1] / (1 << 20)
                           << " MiB: bytes per coarse hex";
  EXPECT_GT(per_hex, 200) << "the coarse mesh itself is more than this: is the measure working?";
}

// A box query meeting one coarse element of interval 300 (2.7e7 fine
// elements) held the element's whole grid, ~2.6 GB (a probe saw 6.1 GB at
// interval 400); it is read in slabs of grid planes now, O(n^2). The count
// is the unit cube's: centroids (i + 1/2) / 300 in [0.49, 0.51] for i =
// 147..152 on each axis.
TEST(ExportMemory, BoxQueryOfOneHugeElementHoldsSlabsNotTheElement) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation and take no address-space limit (the Release suite runs this)";
#endif
  test::TempDir d;
  const std::string store = d.path("one.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", box_msh(d, 1), "--interval", "300", "-o", store}).exit_code, 0);
  const std::string box = "0.49,0.49,0.49,0.51,0.51,0.51";
  const auto q = test::run_cli({"query", store, "--box", box, "--count"});
  ASSERT_EQ(q.exit_code, 0) << q.err;
  EXPECT_EQ(std::stoll(q.out), 6 * 6 * 6);
  for (const std::vector<std::string>& argv :
       {std::vector<std::string>{DICER_CLI, "query", store, "--box", box, "--count"},
        std::vector<std::string>{DICER_CLI, "query", store, "--box", box},
        std::vector<std::string>{DICER_CLI, "export", store, "--box", box, "-o", d.path("cut.vtkhdf")}}) {
    const auto [code, rss] = run_measured(argv);
    EXPECT_EQ(code, 0) << argv[1];
    EXPECT_LT(rss, 200.0 * (1 << 20)) << argv[1] << ": peak RSS " << rss / (1 << 20) << " MiB";
  }
}

// Two quads: each is checked by verify whole (~0.35 GB at interval 1000)
// and swept a plane at a time. What the command holds from the first is
// reused for the second; the check counted it as spent, and refused the
// second element as if it needed memory anew (verify under 700 MiB; a
// sweep at interval 3000, ~1.2 GB an element, under 1.9 GB: the first
// element had fitted).
TEST(ExportMemory, AnElementAsLargeAsTheLastReusesItsMemory) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation and take no address-space limit (the Release suite runs this)";
#endif
  if (!fs::exists("/usr/bin/prlimit")) GTEST_SKIP() << "needs prlimit (util-linux)";
  test::TempDir d;
  const std::string msh = d.path("two.msh");
  test::write_file(msh, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n6\n1 0 0 0\n2 1 0 0\n3 2 0 0\n4 0 1 0\n"
                        "5 1 1 0\n6 2 1 0\n$EndNodes\n$Elements\n2\n1 3 2 1 1 1 2 5 4\n2 3 2 1 1 2 3 6 5\n"
                        "$EndElements\n");
  for (const auto& [interval, limit, cmd] :
       {std::tuple<int, const char*, const char*>{1000, "734003200", "verify"}, {3000, "1900000000", "sweep"}}) {
    const std::string store = d.path("two" + std::to_string(interval) + ".dice.h5");
    ASSERT_EQ(test::run_cli({"dice", msh, "--interval", std::to_string(interval), "-o", store}).exit_code, 0);
    std::vector<std::string> argv{"/usr/bin/prlimit", std::string("--as=") + limit, "--", DICER_CLI, cmd, store, "--quiet"};
    if (std::string(cmd) == "sweep") argv.insert(argv.end(), {"--threads", "1"});
    const auto r = test::run_process(argv);
    EXPECT_EQ(r.exit_code, 0) << cmd << ": " << r.err;
  }
}

// One coarse hex at interval 10,000 (10^12 fine elements; dice accepts
// it): a cursor's slab of one grid plane and the element's boundary is
// ~24 GiB. A few ids are answered one by one in O(1) memory; what must
// read the element in slabs (sweep, footprint, a long id range) or whole
// (verify) is refused up front naming the element, not killed by the OS
// or failed with a bare "out of memory"; an export's id pass answers a
// signal inside the element.
TEST(ExportMemory, AHugeCoarseElementIsAnsweredOrRefusedByName) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation and take no address-space limit (the Release suite runs this)";
#endif
  if (!fs::exists("/usr/bin/prlimit")) GTEST_SKIP() << "needs prlimit (util-linux)";
  test::TempDir d;
  const std::string store = d.path("huge.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", box_msh(d, 1), "--interval", "10000", "-o", store}).exit_code, 0);
  // Node 0 is a corner of the unit cube, and element 10^12 - 1 the last.
  auto r = test::run_cli({"query", store, "--node", "0", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("\"xyz\":[0.0,0.0,0.0]"), std::string::npos) << r.out;
  r = test::run_cli({"query", store, "--elements", "999999999998:999999999999"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("element 999999999998 "), std::string::npos) << r.out;
  for (const std::vector<std::string>& q :
       {std::vector<std::string>{"--node", "0"}, std::vector<std::string>{"--nodes", "0:4000"},
        std::vector<std::string>{"--element", "999999999999"}}) {
    std::vector<std::string> argv{DICER_CLI, "query", store};
    argv.insert(argv.end(), q.begin(), q.end());
    const auto [code, rss] = run_measured(argv);
    EXPECT_EQ(code, 0) << q[0];
    EXPECT_LT(rss, 200.0 * (1 << 20)) << q[0] << ": peak RSS " << rss / (1 << 20) << " MiB";
  }
  // Under a 4 GiB address space, whatever the machine has free.
  for (const std::vector<std::string>& cmd :
       {std::vector<std::string>{"sweep", store}, std::vector<std::string>{"footprint", store},
        std::vector<std::string>{"verify", store}, std::vector<std::string>{"query", store, "--nodes", "0:100000"},
        std::vector<std::string>{"export", store, "-o", d.path("x.vtkhdf")},
        // Box queries and box exports read the element in slabs with its
        // whole boundary (~32 GiB here): they ended "out of memory", exit 70.
        std::vector<std::string>{"query", store, "--box", "0.4,0.4,0.4,0.6,0.6,0.6", "--count"},
        std::vector<std::string>{"export", store, "--box", "0.4,0.4,0.4,0.6,0.6,0.6", "-o", d.path("x.vtkhdf")}}) {
    std::vector<std::string> argv{"/usr/bin/prlimit", "--as=4294967296", "--", DICER_CLI};
    argv.insert(argv.end(), cmd.begin(), cmd.end());
    r = test::run_process(argv);
    EXPECT_EQ(r.exit_code, 2) << cmd[0] << ": " << r.err;
    EXPECT_NE(r.err.find("huge.dice.h5: coarse element 0 (intervals 10000 x 10000 x 10000)"), std::string::npos)
        << cmd[0] << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd[0] << ": " << r.err;
  }
  EXPECT_FALSE(fs::exists(d.path("x.vtkhdf")));
  // The MSH export's first pass (ids only) runs through the element for
  // hours; SIGTERM ended it only at the next element.
  const std::string out = d.path("x.msh");
  expect_sigterm_ends({"export", store, "--format", "msh", "-o", out}, out);
  for (const auto& e : fs::directory_iterator(d.dir()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << "left behind: " << e.path();
}

// A side set on a huge coarse element: its fine faces are held while an
// MSH or Exodus export writes them (9-25 bytes each). One face at interval
// 8000 is 8000^2 = 6.4e7 fine faces, about 1.5 GiB: under a 1 GiB address
// space the export is refused at once, naming them; VTKHDF gathers no sets
// (it reaches the element's own refusal). At interval 4000 the side's
// faces are found in O(n^2), not by visiting the element's n^3 cells
// (which took minutes without answering SIGTERM).
TEST(ExportMemory, SideSetsOfAHugeElementAreCountedAndRefusedByName) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation and take no address-space limit (the Release suite runs this)";
#endif
  if (!fs::exists("/usr/bin/prlimit")) GTEST_SKIP() << "needs prlimit (util-linux)";
  test::TempDir d;
  const std::string msh = d.path("side.msh");
  // One unit hex and the quad of its face z = 0 in physical group 7.
  test::write_file(msh, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n8\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 1 1 0\n"
                        "5 0 0 1\n6 1 0 1\n7 0 1 1\n8 1 1 1\n$EndNodes\n$Elements\n2\n1 5 2 1 1 1 2 4 3 5 6 8 7\n"
                        "2 3 2 7 2 1 2 4 3\n$EndElements\n");
  const std::string big = d.path("side8000.dice.h5"), mid = d.path("side4000.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", msh, "--interval", "8000", "-o", big}).exit_code, 0);
  ASSERT_EQ(test::run_cli({"dice", msh, "--interval", "4000", "-o", mid}).exit_code, 0);
  auto limited = [&](std::vector<std::string> args) {
    std::vector<std::string> argv{"/usr/bin/prlimit", "--as=1073741824", "--", DICER_CLI};
    argv.insert(argv.end(), args.begin(), args.end());
    return test::run_process(argv);
  };
  for (const char* format : {"exodus", "msh"}) {
    const auto r = limited({"export", big, "--format", format, "-o", d.path("x.out")});
    EXPECT_EQ(r.exit_code, 2) << format << ": " << r.err;
    EXPECT_NE(r.err.find("side8000.dice.h5: the side sets of coarse elements 0..1 hold 6.4e+07 fine faces"),
              std::string::npos)
        << format << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  auto r = limited({"export", big, "-o", d.path("x.vtkhdf")});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(r.err.find("side sets"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("coarse element 0 (intervals 8000 x 8000 x 8000)"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(d.path("x.out")));
  EXPECT_FALSE(fs::exists(d.path("x.vtkhdf")));
  // SIGTERM answered while the MSH export of the interval-4000 store runs.
  const std::string out = d.path("mid.msh");
  expect_sigterm_ends({"export", mid, "--format", "msh", "-o", out}, out);
}

// Out of memory is exit 70 with the limit met named ("out of memory" alone
// left a user with a 4 GiB ulimit -v guessing): 216,000 coarse hexes do
// not dice in a 160 MiB address space.
TEST(ExportMemory, OutOfMemoryNamesTheLimit) {
#ifdef DICER_SANITIZER_BUILD
  GTEST_SKIP() << "sanitizer builds shadow every allocation and take no address-space limit (the Release suite runs this)";
#endif
  if (!fs::exists("/usr/bin/prlimit")) GTEST_SKIP() << "needs prlimit (util-linux)";
  test::TempDir d;
  const std::string store = d.path("b.dice.h5");
  // ~270 MB to dice (a 40^3 box, 95 MB since dice streams its rows, fits).
  const auto r = test::run_process({"/usr/bin/prlimit", "--as=167772160", "--", DICER_CLI, "dice", box_msh(d, 60),
                                    "-o", store, "--quiet"});
  EXPECT_EQ(r.exit_code, 70) << r.err;
  EXPECT_NE(r.err.find("out of memory: the command needs more than this process's address-space limit, 160.0 MiB "
                       "(ulimit -v) allows"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(store));
}
