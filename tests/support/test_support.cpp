#include "test_support.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>

namespace dicer::test {

std::string data_path(const std::string& name) { return std::string(DICER_TEST_DATA) + "/" + name; }

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  std::random_device rd;
  dir_ = std::filesystem::temp_directory_path() /
         ("dicer-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
          std::to_string(rd() % 100000));
  std::filesystem::create_directories(dir_);
}
TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

const std::string& diced_store(const std::string& mesh, int interval) {
  static TempDir dir;
  static std::map<std::pair<std::string, int>, std::string> made;
  static std::mutex mu;
  std::lock_guard lock(mu);
  const auto key = std::make_pair(mesh, interval);
  if (auto it = made.find(key); it != made.end()) return it->second;
  const std::string p = dir.path(mesh + "." + std::to_string(interval) + ".dice.h5");
  const auto r = run_cli({"dice", data_path(mesh), "--interval", std::to_string(interval), "-o", p});
  if (r.exit_code != 0) throw std::runtime_error("cannot make the store: " + r.err);
  return made.emplace(key, p).first->second;
}

CliResult run_process(const std::vector<std::string>& argv, const std::map<std::string, std::string>& set,
                      const std::vector<std::string>& unset) {
  TempDir tmp;
  const std::string out_path = tmp.path("out"), err_path = tmp.path("err");
  // The child's environment and argv, built before fork (only
  // async-signal-safe calls after it).
  std::vector<std::string> env;
  for (char** e = environ; *e; ++e) {
    const std::string entry = *e, name = entry.substr(0, entry.find('='));
    if (std::find(unset.begin(), unset.end(), name) == unset.end() && !set.count(name)) env.push_back(entry);
  }
  for (const auto& [k, v] : set) env.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> copy = argv;
  std::vector<char*> args;
  for (auto& a : copy) args.push_back(a.data());
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int o = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int in = ::open("/dev/null", O_RDONLY);
    if (o < 0 || e < 0 || in < 0) ::_exit(126);
    ::dup2(o, 1), ::dup2(e, 2), ::dup2(in, 0);
    ::execve(args[0], args.data(), envp.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_file(out_path);
  r.err = read_file(err_path);
  return r;
}

pid_t spawn_cli(const std::vector<std::string>& args) {
  std::vector<std::string> copy{DICER_CLI};
  copy.insert(copy.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int null = ::open("/dev/null", O_RDWR);
    ::dup2(null, 0), ::dup2(null, 1), ::dup2(null, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

CliResult run_cli(const std::vector<std::string>& args) {
  std::vector<std::string> argv{DICER_CLI};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_process(argv);
}

}  // namespace dicer::test
