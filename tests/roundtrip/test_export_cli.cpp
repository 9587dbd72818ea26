// The export command end to end: every format from the command line, chunk
// and box arguments, refusals, and Ctrl-C leaving nothing behind.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <stdexcept>
#include <filesystem>
#include <thread>

#include "test_support.hpp"

using namespace dicer;

TEST(ExportCli, EveryFormatChunkAndBoxFromTheCommandLine) {
  test::TempDir tmp;
  const std::string store = tmp.path("m.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("vtkdata_mug.e"), "--interval", "2", "-o", store}).exit_code, 0);
  for (const auto& [fmt, file] : std::vector<std::pair<std::string, std::string>>{
           {"vtkhdf", "a.vtkhdf"}, {"msh", "b.msh"}, {"msh-ascii", "c.msh"}, {"exodus", "d.exo"}}) {
    auto r = test::run_cli({"export", store, "--format", fmt, "--chunk", "1/3", "-o", tmp.path(file), "--quiet"});
    EXPECT_EQ(r.exit_code, 0) << fmt << ": " << r.err;
    EXPECT_TRUE(std::filesystem::exists(tmp.path(file))) << fmt;
  }
  auto r = test::run_cli({"export", store, "--format", "msh", "--box", "-10,-10,-10,10,10,10", "-o", tmp.path("box.msh")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("19808 fine elements"), std::string::npos) << r.out;  // a box around everything: 2476 x 8
  r = test::run_cli({"query", store, "--box", "-10,-10,-10,10,10,10", "--count"});
  EXPECT_EQ(r.out, "19808\n");
  // Refusals: chunk out of range, malformed box, unknown format; nothing written.
  const std::string never = tmp.path("never.msh");
  EXPECT_EQ(test::run_cli({"export", store, "--format", "msh", "--chunk", "3/3", "-o", never}).exit_code, 2);
  {
    const auto bad = test::run_cli({"export", store, "--format", "msh", "--chunk", "1/2/3", "-o", never});
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("\"1/2/3\" is not K/N"), std::string::npos) << bad.err;
  }
  EXPECT_EQ(test::run_cli({"export", store, "--format", "msh", "--box", "0,0,1", "-o", never}).exit_code, 2);
  EXPECT_EQ(test::run_cli({"export", store, "--format", "stl", "-o", never}).exit_code, 2);
  // --deflate: VTKHDF only, levels 0..9.
  EXPECT_EQ(test::run_cli({"export", store, "--format", "msh", "--deflate", "1", "-o", never}).exit_code, 2);
  EXPECT_EQ(test::run_cli({"export", store, "--format", "vtkhdf", "--deflate", "10", "-o", never}).exit_code, 2);
  EXPECT_EQ(test::run_cli({"export", store, "--format", "vtkhdf", "--deflate", "x", "-o", never}).exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(never));
  r = test::run_cli({"export", store, "--format", "vtkhdf", "--deflate", "1", "-o", tmp.path("z.vtkhdf"), "--quiet"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_LT(std::filesystem::file_size(tmp.path("z.vtkhdf")), std::filesystem::file_size(tmp.path("a.vtkhdf")) * 3);
  r = test::run_cli({"export", "--help"});
  EXPECT_NE(r.out.find("--deflate LEVEL"), std::string::npos) << r.out;
}

// A surface store's side sets on shell faces (sides 0, 1: the quads
// themselves) have no MSH element: said on stderr, not dropped silently,
// --quiet or not (data left out is not progress).
TEST(ExportCli, ShellFaceSidesNotWrittenToMshAreSaid) {
  test::TempDir tmp;
  const std::string store = tmp.path("shell.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("libmesh_cylinder_shell.exo"), "--interval", "1", "-o", store}).exit_code, 0);
  auto r = test::run_cli({"export", store, "-o", tmp.path("s.msh")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("note: side set 11: the face sides of"), std::string::npos) << r.err;
  r = test::run_cli({"export", store, "-o", tmp.path("s.e")});
  EXPECT_EQ(r.err.find("note:"), std::string::npos) << r.err;
  r = test::run_cli({"export", store, "-o", tmp.path("q.msh"), "--quiet"});
  EXPECT_NE(r.err.find("note: side set 11"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
}

// MSH has no node sets: an export of a mesh with some says which it leaves
// out (the mug's sets 1 and 2), under --quiet too; Exodus keeps them.
TEST(ExportCli, NodeSetsNotWrittenToMshAreSaid) {
  test::TempDir tmp;
  const std::string store = test::diced_store("vtkdata_mug.e", 1);
  auto r = test::run_cli({"export", store, "-o", tmp.path("m.msh"), "--quiet"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const auto at = r.err.find("note: node sets ");
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string line = r.err.substr(at, r.err.find('\n', at) - at);
  EXPECT_TRUE(line.find("node sets 2, 1 ") != std::string::npos || line.find("node sets 1, 2 ") != std::string::npos)
      << line;
  r = test::run_cli({"export", store, "-o", tmp.path("m.e"), "--quiet"});
  EXPECT_EQ(r.err, "");
}

// A box that holds no element writes a valid empty file (a script may want
// it), and says so, --quiet or not: it is rarely what was meant.
TEST(ExportCli, AnEmptyBoxIsSaid) {
  test::TempDir tmp;
  const std::string store = test::diced_store("cardinal_prism.exo", 1);
  for (const std::string name : {"e.vtkhdf", "e.msh", "e.e"}) {
    SCOPED_TRACE(name);
    const auto r = test::run_cli({"export", store, "--box", "100,100,100,101,101,101", "-o", tmp.path(name), "--quiet"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("note: the box holds no fine element"), std::string::npos) << r.err;
    EXPECT_TRUE(std::filesystem::exists(tmp.path(name)));
  }
  const auto r = test::run_cli({"export", store, "--box", "-100,-100,-100,100,100,100", "-o", tmp.path("f.msh"), "--quiet"});
  EXPECT_EQ(r.err, "");
}

// Without --format the extension of OUT names it: the same file, byte for
// byte (exports are reproducible), as with the format given; the format
// given wins over the extension.
TEST(ExportCli, FormatFromTheOutputsExtension) {
  test::TempDir tmp;
  const std::string store = tmp.path("m.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", store}).exit_code, 0);
  auto exported = [&](const std::string& file, const std::vector<std::string>& more) {
    std::vector<std::string> args{"export", store, "-o", tmp.path(file), "--quiet"};
    args.insert(args.end(), more.begin(), more.end());
    const auto r = test::run_cli(args);
    EXPECT_EQ(r.exit_code, 0) << file << ": " << r.err;
    return test::read_file(tmp.path(file));
  };
  for (const auto& [ext, fmt] : std::vector<std::pair<std::string, std::string>>{
           {".vtkhdf", "vtkhdf"}, {".hdf", "vtkhdf"}, {".msh", "msh"}, {".e", "exodus"}, {".exo", "exodus"},
           {".ex2", "exodus"}, {".g", "exodus"}}) {
    SCOPED_TRACE(ext);
    const std::string inferred = exported("inferred" + ext, {});
    EXPECT_FALSE(inferred.empty());
    EXPECT_EQ(inferred, exported("given" + ext, {"--format", fmt}));
  }
  // --format wins: ASCII MSH into a .vtkhdf name is ASCII MSH.
  EXPECT_EQ(exported("ascii.vtkhdf", {"--format", "msh-ascii"}).rfind("$MeshFormat\n4.1 0 8", 0), 0u);
  EXPECT_EQ(exported("binary.msh", {}).rfind("$MeshFormat\n4.1 1 8", 0), 0u);
}

// Ctrl-C, SIGTERM (a scheduler's stop) and SIGHUP (a closed terminal) stop
// the export cleanly with 128 + the signal, leaving nothing behind.
struct SignalCase {
  int signal, exit_code;  // the code README and `dicer --help` give
  const char* name;
};
class ExportSignal : public ::testing::TestWithParam<SignalCase> {};

TEST_P(ExportSignal, StopsCleanlyWithNoPartialOutput) {
  const int sig = GetParam().signal;
  static test::TempDir tmp;
  static const std::string store = [] {
    const std::string p = tmp.path("big.dice.h5");
    // 7472 hexes at interval 12: 12.9M fine elements, several seconds of
    // ASCII export (binary streams too fast to interrupt reliably).
    const auto r = test::run_cli({"dice", test::data_path("vtkdata_disk_out_ref.ex2"), "--interval", "12", "-o", p});
    if (r.exit_code != 0) throw std::runtime_error(r.err);
    return p;
  }();
  const std::string out = tmp.path("whole.msh");
  // dicer keeps ignoring a signal it inherits ignored (nohup): start it with
  // the default action whatever ran this test.
  const auto inherited = std::signal(sig, SIG_DFL);
  const pid_t pid = test::spawn_cli({"export", store, "--format", "msh-ascii", "-o", out});
  std::signal(sig, inherited);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ::kill(pid, sig);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "the export should stop cleanly on signal " << sig;
  EXPECT_EQ(WEXITSTATUS(status), GetParam().exit_code);
  EXPECT_FALSE(std::filesystem::exists(out));
  for (const auto& e : std::filesystem::directory_iterator(tmp.dir()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << "left behind: " << e.path();
}

INSTANTIATE_TEST_SUITE_P(Signals, ExportSignal,
                         ::testing::Values(SignalCase{SIGINT, 130, "SIGINT"}, SignalCase{SIGTERM, 143, "SIGTERM"},
                                           SignalCase{SIGHUP, 129, "SIGHUP"}),
                         [](const ::testing::TestParamInfo<SignalCase>& i) { return std::string(i.param.name); });
