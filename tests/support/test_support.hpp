#pragma once
// Helpers shared by the test binary: data paths, temp dirs, running the CLI.
#include <gtest/gtest.h>
#include <sys/types.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "dicer/error.hpp"

namespace dicer::test {

// Path of a file under tests/data (the bundled real meshes).
std::string data_path(const std::string& name);

// A fresh directory removed at scope exit.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

struct CliResult {
  int exit_code = -1;
  std::string out, err;
};

// A store of tests/data/MESH diced at `interval` by the built binary, made
// once per test process and kept until it exits; copy it to change it.
const std::string& diced_store(const std::string& mesh, int interval);

// Runs the built `dicer` binary with the given arguments (no shell).
CliResult run_cli(const std::vector<std::string>& args);

// Starts the built `dicer` binary in the background (stdout and stderr to
// /dev/null) and returns its pid, for tests that signal it mid-work.
pid_t spawn_cli(const std::vector<std::string>& args);

// Runs any program (argv[0] is its path; no shell, stdin from /dev/null);
// `set` / `unset` adjust the child's environment.
CliResult run_process(const std::vector<std::string>& argv, const std::map<std::string, std::string>& set = {},
                      const std::vector<std::string>& unset = {});

// Environment variables that make Debian's /usr/bin/python3 load the wrong
// site packages (the machine's default python is not Debian's).
inline const std::vector<std::string> kForeignPythonEnv = {"PYTHONPATH", "PYTHONHOME"};

// Under CI (CI=true, where .ci/run installs the independent readers) a
// missing reader is a failure, not a skip: those tests are the proof that
// real readers accept our files.
#define DICER_SKIP_OR_FAIL_IN_CI(message)   \
  do {                                      \
    if (std::getenv("CI") != nullptr) {     \
      FAIL() << message;                    \
    } else {                                \
      GTEST_SKIP() << message;              \
    }                                       \
  } while (0)

// Writes bytes to a file (bad-input fixtures made by the tests).
void write_file(const std::string& path, const std::string& bytes);
std::string read_file(const std::string& path);

// What f() throws: a dicer::Error of `kind` (a failed expectation
// otherwise), its message for the caller's checks.
template <class F>
std::string error_of(F&& f, ErrorKind kind) {
  try {
    f();
  } catch (const Error& e) {
    EXPECT_EQ(static_cast<int>(e.kind()), static_cast<int>(kind)) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no error thrown";
  return {};
}

}  // namespace dicer::test
