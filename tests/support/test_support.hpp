#pragma once
// Helpers shared by the test binary: data paths, temp dirs, running the CLI.
#include <filesystem>
#include <string>
#include <vector>

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

// Runs the built `dicer` binary with the given arguments (no shell).
CliResult run_cli(const std::vector<std::string>& args);

// Writes bytes to a file (bad-input fixtures made by the tests).
void write_file(const std::string& path, const std::string& bytes);
std::string read_file(const std::string& path);

}  // namespace dicer::test
