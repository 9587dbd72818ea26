// The coarse-mesh and intervals readers through the real `dicer` binary:
// what the user sees on stderr (warnings, refusals) for inputs that are odd
// rather than broken. Every run is under `timeout`, so an input that would
// block the reader fails the test instead of hanging it.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/intervals.hpp"
#include "test_support.hpp"

namespace {

using dicer::test::CliResult;
using dicer::test::TempDir;

// `dicer ARGS...` killed after 30 s (exit 124 then).
CliResult run_cli_bounded(const std::vector<std::string>& args) {
  std::vector<std::string> argv{"/usr/bin/timeout", "-k", "5", "30", DICER_CLI};
  argv.insert(argv.end(), args.begin(), args.end());
  return dicer::test::run_process(argv);
}

std::vector<std::string> lines_with(const std::string& text, const std::string& what) {
  std::vector<std::string> out;
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(at, end - at);
    if (line.find(what) != std::string::npos) out.push_back(line);
    at = end + 1;
  }
  return out;
}

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Two hexes stacked in z, the second in no physical group: a reader warning.
const std::string kOrphanHex =
    "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    "$Nodes\n12\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n"
    "9 0 0 2\n10 1 0 2\n11 1 1 2\n12 0 1 2\n$EndNodes\n"
    "$Elements\n2\n1 5 2 8 1 1 2 3 4 5 6 7 8\n2 5 2 0 8 5 6 7 8 9 10 11 12\n$EndElements\n";

}  // namespace

// A warning names the file once: the reader's text has no path, the
// command prefixes it (coarse_mesh.hpp, CoarseMesh::warnings).
TEST(ReaderCli, WarningNamesTheFileOnce) {
  TempDir d;
  const std::string in = d.path("orphan.msh");
  dicer::test::write_file(in, kOrphanHex);
  const std::vector<std::pair<std::string, std::vector<std::string>>> runs = {
      {"dicer sheets", {"sheets", in}}, {"dicer dice", {"dice", in, "--quiet", "-o", d.path("out.dice.h5")}}};
  for (const auto& [command, args] : runs) {
    SCOPED_TRACE(command);
    const CliResult r = run_cli_bounded(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto warnings = lines_with(r.err, "warning");
    ASSERT_EQ(warnings.size(), 1u) << r.err;
    EXPECT_EQ(warnings[0].rfind(command + ": warning: " + in + ": 1 hexahedra are in no physical group", 0), 0u)
        << warnings[0];
    EXPECT_EQ(occurrences(warnings[0], in), 1u) << warnings[0];
  }
}

// Three quads on one edge (a fin on a plate): refused like a face shared by
// three hexes, naming the edge by the file's node tags and the quads by
// their element tags.
TEST(ReaderCli, NonManifoldSurfaceEdgeIsRefused) {
  TempDir d;
  const std::string in = d.path("fin.msh");
  dicer::test::write_file(in,
                          "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
                          "$Nodes\n8\n10 0 0 0\n20 1 0 0\n30 1 1 0\n40 0 1 0\n50 2 0 0\n60 2 1 0\n70 1 0 1\n80 1 1 1\n"
                          "$EndNodes\n"
                          "$Elements\n3\n100 3 2 1 1 10 20 30 40\n200 3 2 1 1 20 50 60 30\n300 3 2 1 2 20 70 80 30\n"
                          "$EndElements\n");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"sheets", in}, std::vector<std::string>{"dice", in, "-o", d.path("fin.dice.h5")}}) {
    const CliResult r = run_cli_bounded(args);
    SCOPED_TRACE(args[0]);
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(in + ": non-manifold edge (nodes 20 30) is shared by more than two quadrilaterals: "
                              "elements 100, 200, 300"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

// Inputs that are not regular files. A FIFO used to block `dice` and
// `sheets` in open() for ever (exit 124 from `timeout` here); a directory
// read as an empty file. The command line refuses them before any reader
// opens them (exit 2, a usage error: the user named something that is not
// a file); the readers refuse them too (next test).
TEST(ReaderCli, FifoOrDirectoryAsMeshOrIntervalsFileIsRefused) {
  TempDir d;
  const std::string fifo = d.path("pipe.msh");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string dir = d.path("folder.e");
  std::filesystem::create_directory(dir);
  const std::string mesh = dicer::test::data_path("cardinal_sphere.e");
  const std::string out = d.path("out.dice.h5");
  struct Run {
    std::vector<std::string> args;
    std::string path, says;
  };
  const std::vector<Run> runs = {
      {{"dice", fifo, "-o", out}, fifo, "is a FIFO (named pipe), not a regular file"},
      {{"sheets", fifo}, fifo, "is a FIFO (named pipe), not a regular file"},
      {{"dice", mesh, "--intervals-file", fifo, "-o", out}, fifo, "is a FIFO (named pipe), not a regular file"},
      {{"sheets", mesh, "--intervals-file", fifo}, fifo, "is a FIFO (named pipe), not a regular file"},
      {{"dice", dir, "-o", out}, dir, "is a directory, not a regular file"},
      {{"sheets", mesh, "--intervals-file", dir}, dir, "is a directory, not a regular file"},
  };
  for (const Run& run : runs) {
    std::string command;
    for (const auto& a : run.args) command += " " + a;
    SCOPED_TRACE(command);
    const CliResult r = run_cli_bounded(run.args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(run.path), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(run.says), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(out));
}

TEST(ReaderCli, DirectoryIsAnIoErrorInTheLibrary) {
  TempDir d;
  const std::string dir = d.dir().string();
  for (auto read : {+[](const std::string& p) { dicer::read_coarse_mesh(p); },
                    +[](const std::string& p) { dicer::read_msh(p); },
                    +[](const std::string& p) { dicer::read_interval_file(p); }}) {
    try {
      read(dir);
      ADD_FAILURE() << "no error";
    } catch (const dicer::Error& e) {
      EXPECT_EQ(e.kind(), dicer::ErrorKind::Io) << e.what();
      EXPECT_EQ(std::string(e.what()), dir + ": is a directory, not a regular file; dicer reads only regular files");
    }
  }
}
