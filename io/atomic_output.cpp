// Write-to-temporary, fsync, rename, fsync-the-folder (atomic_output.hpp).
#include "dicer/atomic_output.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>

#include "dicer/error.hpp"

namespace dicer {
namespace {

// Live temporaries, for remove_uncommitted(): fixed slots of absolute
// paths, claimed and released with atomics so a signal handler can read
// them without locks. The states apart from the paths: a scan touches 16
// KiB, and only the path pages in use are ever backed by memory.
constexpr int kSlots = 4096;  // a Nemesis set of that many files pending at once
std::atomic<int> g_state[kSlots];  // 0 free, 1 being filled, 2 live
char g_path[kSlots][PATH_MAX + 1];

int claim_slot(const std::string& path) {
  if (path.size() > PATH_MAX) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (g_state[i].compare_exchange_strong(expected, 1)) {
      std::memcpy(g_path[i], path.c_str(), path.size() + 1);
      g_state[i].store(2);
      return i;
    }
  }
  return -1;  // more than kSlots outputs at once: only signal cleanup misses them
}

void release_slot(int i) {
  if (i >= 0) g_state[i].store(0);
}

std::string errno_text() { return std::strerror(errno); }

// ".NAME.tmp-PID", within NAME_MAX: a long NAME is cut and tagged with a
// hash of the whole name so two long names do not share a temporary.
std::string temp_name_for(const std::string& name, long pid) {
  const std::string suffix = ".tmp-" + std::to_string(pid);
  std::string t = "." + name + suffix;
  if (t.size() <= NAME_MAX) return t;
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016zx", std::hash<std::string>{}(name));
  const size_t keep = NAME_MAX - 1 - 1 - 16 - suffix.size();
  return "." + name.substr(0, keep) + "~" + hash + suffix;
}

// Stale temporaries of `name` whose process is gone.
void remove_stale(int dir_fd, const std::string& name) {
  const int fd = ::dup(dir_fd);
  if (fd < 0) return;
  DIR* d = ::fdopendir(fd);
  if (!d) {
    ::close(fd);
    return;
  }
  const std::string exact = "." + name + ".tmp-";
  while (const dirent* e = ::readdir(d)) {
    const std::string n = e->d_name;
    if (n.rfind(exact, 0) != 0) continue;
    const std::string digits = n.substr(exact.size());
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
    const long pid = std::stol(digits);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) ::unlinkat(dir_fd, n.c_str(), 0);
  }
  ::closedir(d);
}

}  // namespace

AtomicOutput::AtomicOutput(const std::string& final_path) : final_(final_path) {
  namespace fs = std::filesystem;
  const fs::path p(final_path);
  name_ = p.filename().string();
  std::error_code ec;
  if (name_.empty() || name_ == "." || name_ == ".." || fs::is_directory(p, ec))
    throw Error(ErrorKind::Usage, final_path + ": is a directory; give a file name to write");
  dir_ = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  dir_fd_ = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd_ < 0) throw Error(ErrorKind::Io, final_path + ": cannot open the output folder " + dir_ + ": " + errno_text());
  // Said here, in these words, rather than by whichever library then fails
  // to create the temporary (netCDF blamed netCDF-4 support, MPI-IO said
  // MPI_ERR_OTHER): permissions, a read-only file system, an immutable folder.
  // (Real ids, flags 0: glibc then calls faccessat, not faccessat2, which
  // older container seccomp profiles refuse with EPERM.)
  if (::faccessat(dir_fd_, ".", W_OK, 0) != 0) {
    const std::string why = errno_text();
    ::close(dir_fd_);
    dir_fd_ = -1;
    throw Error(ErrorKind::Io, final_path + ": cannot write in the output folder " + dir_ + ": " + why);
  }
  remove_stale(dir_fd_, name_);
  temp_name_ = temp_name_for(name_, static_cast<long>(::getpid()));
  temp_ = (fs::path(dir_) / temp_name_).string();
  short_ = "/proc/self/fd/" + std::to_string(dir_fd_) + "/" + temp_name_;
  // A temporary of ours from an earlier failed attempt in this process.
  ::unlinkat(dir_fd_, temp_name_.c_str(), 0);
  std::string absolute = temp_;
  if (!fs::path(absolute).is_absolute()) absolute = (fs::current_path(ec) / temp_).string();
  slot_ = claim_slot(absolute);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) {
    if (dir_fd_ >= 0) ::unlinkat(dir_fd_, temp_name_.c_str(), 0);
    else ::unlink(temp_.c_str());  // parked
  }
  release_slot(slot_);
  if (dir_fd_ >= 0) ::close(dir_fd_);
}

void AtomicOutput::park() {
  if (dir_fd_ >= 0) ::close(dir_fd_);
  dir_fd_ = -1;
  short_.clear();
}

namespace {

// The output's folder for one call: its own descriptor, or for a parked
// output the folder opened again by name and closed after the call (a set
// of thousands committed in a row must not hold a descriptor each).
class Folder {
 public:
  Folder(int kept, const std::string& dir, const std::string& final_path)
      : fd_(kept >= 0 ? kept : ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)), own_(kept < 0) {
    if (fd_ < 0) throw Error(ErrorKind::Io, final_path + ": cannot open the output folder " + dir + ": " + errno_text());
  }
  ~Folder() {
    if (own_) ::close(fd_);
  }
  Folder(const Folder&) = delete;
  Folder& operator=(const Folder&) = delete;
  int fd() const { return fd_; }

 private:
  int fd_;
  bool own_;
};

}  // namespace

void AtomicOutput::flush() {
  if (committed_ || flushed_) return;
  const Folder dir(dir_fd_, dir_, final_);
  const int fd = ::openat(dir.fd(), temp_name_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(ErrorKind::Io, temp_ + ": the written file is gone: " + errno_text());
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0) throw Error(ErrorKind::Io, temp_ + ": cannot flush to disk: " + std::strerror(err));
  struct stat st;
  if (::fstatat(dir.fd(), name_.c_str(), &st, 0) == 0 && S_ISDIR(st.st_mode))
    throw Error(ErrorKind::Usage, final_ + ": is a directory; give a file name to write");
  flushed_ = true;
}

void AtomicOutput::commit() {
  if (committed_) return;
  flush();
  const Folder dir(dir_fd_, dir_, final_);
  if (::renameat(dir.fd(), temp_name_.c_str(), dir.fd(), name_.c_str()) != 0)
    throw Error(ErrorKind::Io, final_ + ": cannot move the finished file into place: " + errno_text());
  committed_ = true;
  release_slot(slot_);
  slot_ = -1;
  // The rename itself is durable only once the folder is flushed; the file
  // is complete either way, so a failure here is not worth an error.
  ::fsync(dir.fd());
}

void AtomicOutput::remove_uncommitted() noexcept {
  for (int i = 0; i < kSlots; ++i)
    if (g_state[i].load() == 2) ::unlink(g_path[i]);
}

}  // namespace dicer
