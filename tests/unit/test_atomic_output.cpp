// AtomicOutput: one test per promise of include/dicer/atomic_output.hpp,
// and the writers that use it, through the real binary.
#include <gtest/gtest.h>
#include <limits.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/error.hpp"
#include "test_support.hpp"

using namespace dicer;
namespace fs = std::filesystem;

namespace {

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::vector<std::string> names(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

// A pid that is certainly not running: a child that has exited and been reaped.
pid_t dead_pid() {
  const pid_t p = ::fork();
  if (p == 0) ::_exit(0);
  ::waitpid(p, nullptr, 0);
  return p;
}

}  // namespace

TEST(AtomicOutput, CommitReplacesAndTheOldFileSurvivesAFailure) {
  test::TempDir tmp;
  const std::string target = tmp.path("out.txt");
  std::ofstream(target) << "old";
  {
    AtomicOutput out(target);
    EXPECT_EQ(fs::path(out.temp_path()).parent_path(), fs::path(target).parent_path());
    std::ofstream(out.temp_path()) << "half";
    // destroyed without commit: an exception, a cancellation
  }
  EXPECT_EQ(slurp(target), "old");
  EXPECT_EQ(names(tmp.dir()), (std::vector<std::string>{"out.txt"}));
  {
    AtomicOutput out(target);
    std::ofstream(out.short_path()) << "new";  // the /proc/self/fd name is the same file
    EXPECT_LT(out.short_path().size(), 64u);
    out.commit();
    EXPECT_TRUE(out.committed());
  }
  EXPECT_EQ(slurp(target), "new");
  EXPECT_EQ(names(tmp.dir()), (std::vector<std::string>{"out.txt"}));
}

TEST(AtomicOutput, NamesUpToNameMaxGetATemporaryThatFits) {
  test::TempDir tmp;
  for (const size_t len : {size_t{200}, size_t{243}, size_t{NAME_MAX}}) {
    const std::string target = tmp.path(std::string(len, 'a'));
    AtomicOutput out(target);
    EXPECT_LE(fs::path(out.temp_path()).filename().string().size(), static_cast<size_t>(NAME_MAX));
    std::ofstream(out.temp_path()) << len;
    ASSERT_TRUE(fs::exists(out.temp_path())) << "length " << len;
    out.commit();
    EXPECT_EQ(slurp(target), std::to_string(len));
  }
  // Two long names that share their first 200 characters get different temporaries.
  const std::string a = tmp.path(std::string(240, 'b') + "1" + std::string(14, 'c'));
  const std::string b = tmp.path(std::string(240, 'b') + "2" + std::string(14, 'c'));
  AtomicOutput oa(a), ob(b);
  EXPECT_NE(oa.temp_path(), ob.temp_path());
}

TEST(AtomicOutput, StaleTemporariesOfDeadProcessesAreRemovedLiveOnesKept) {
  test::TempDir tmp;
  const std::string dead = tmp.path(".out.h5.tmp-" + std::to_string(dead_pid()));
  const std::string live = tmp.path(".out.h5.tmp-1");  // pid 1 always runs
  const std::string other = tmp.path(".other.h5.tmp-" + std::to_string(dead_pid()));
  for (const auto& p : {dead, live, other}) std::ofstream(p) << "x";
  AtomicOutput out(tmp.path("out.h5"));
  EXPECT_FALSE(fs::exists(dead));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(other)) << "only temporaries of the same output name are touched";
}

TEST(AtomicOutput, RefusesADirectoryAndNamesAMissingFolder) {
  test::TempDir tmp;
  fs::create_directories(tmp.path("d"));
  try {
    AtomicOutput out(tmp.path("d"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos);
  }
  try {
    AtomicOutput out(tmp.path("missing/x.h5"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io);
    EXPECT_EQ(std::string(e.what()).rfind(tmp.path("missing/x.h5") + ": cannot open the output folder", 0), 0u);
  }
  EXPECT_EQ(names(tmp.dir()), (std::vector<std::string>{"d"}));
}

TEST(AtomicOutput, RemoveUncommittedIsForSignalHandlers) {
  test::TempDir tmp;
  AtomicOutput a(tmp.path("a.h5")), b(tmp.path("b.h5"));
  std::ofstream(a.temp_path()) << "a";
  std::ofstream(b.temp_path()) << "b";
  b.commit();
  AtomicOutput::remove_uncommitted();
  EXPECT_FALSE(fs::exists(a.temp_path()));
  EXPECT_TRUE(fs::exists(tmp.path("b.h5")));
}

// Parked outputs (a Nemesis set held until all its files are written) hold
// no file descriptor each, are committed or removed like the others, and
// a signal handler still finds them: 1500 at once, more than the default
// limit of 1024 descriptors and the 64 slots remove_uncommitted had.
TEST(AtomicOutput, ParkedOutputsHoldNoDescriptorAndStillCommitOrVanish) {
  test::TempDir tmp;
  auto open_fds = [] {
    return std::distance(fs::directory_iterator("/proc/self/fd"), fs::directory_iterator{});
  };
  const auto fds = open_fds();
  constexpr int kFiles = 1500;
  std::vector<std::unique_ptr<AtomicOutput>> outs;
  for (int i = 0; i < kFiles; ++i) {
    outs.push_back(std::make_unique<AtomicOutput>(tmp.path("set." + std::to_string(i))));
    std::ofstream(outs.back()->temp_path()) << i;
    outs.back()->park();
  }
  EXPECT_LE(open_fds(), fds + 2);
  for (int i = 0; i < kFiles; i += 2) outs[static_cast<size_t>(i)]->flush();
  for (int i = 0; i < kFiles; i += 2) outs[static_cast<size_t>(i)]->commit();
  EXPECT_LE(open_fds(), fds + 2);  // committing opened the folder for its call only
  outs[1].reset();  // destroyed parked: removed
  AtomicOutput::remove_uncommitted();  // every other odd one, as a signal handler would
  // Only the committed files are left: no temporary, not even past slot 64.
  EXPECT_EQ(names(tmp.dir()).size(), static_cast<size_t>(kFiles / 2));
  for (int i = 0; i < kFiles; i += 2) {
    SCOPED_TRACE(i);
    EXPECT_EQ(slurp(tmp.path("set." + std::to_string(i))), std::to_string(i));
  }
  outs.clear();
  EXPECT_EQ(names(tmp.dir()).size(), static_cast<size_t>(kFiles / 2));
}

// Every writer goes through AtomicOutput: outputs with names of 243..255
// characters (the temporary's prefix and suffix would pass NAME_MAX) are
// written, by dice and by each exporter, and nothing else is left.
TEST(AtomicOutput, EveryWriterTakesLongNames) {
  test::TempDir tmp;
  const std::string store = tmp.path(std::string(NAME_MAX - 8, 's') + ".dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", store}).exit_code, 0);
  for (const char* format : {"msh", "exodus", "vtkhdf"}) {
    const std::string out = tmp.path(std::string(NAME_MAX - 4, format[0]) + "." + format[0] + format[1]);
    const test::CliResult r = test::run_cli({"export", store, "--format", format, "-o", out});
    EXPECT_EQ(r.exit_code, 0) << format << ": " << r.err;
    EXPECT_TRUE(fs::exists(out)) << format;
  }
  for (const auto& n : names(tmp.dir())) EXPECT_EQ(n.find(".tmp-"), std::string::npos) << n;
}
