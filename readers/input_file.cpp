#include "input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "dicer/error.hpp"

namespace dicer {
namespace {

// Why a file of this mode is not read, or nullptr for a regular file.
const char* not_regular(mode_t mode) {
  if (S_ISREG(mode)) return nullptr;
  if (S_ISDIR(mode)) return "is a directory";
  if (S_ISFIFO(mode)) return "is a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "is a character device";
  if (S_ISBLK(mode)) return "is a block device";
  if (S_ISSOCK(mode)) return "is a socket";
  return "is not a regular file";
}

[[noreturn]] void io_error(const std::string& path, const std::string& what, int err) {
  throw Error(ErrorKind::Io, path + ": " + what + ": " + std::strerror(err));
}

}  // namespace

InputFile::InputFile(const std::string& path) : path_(path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) io_error(path, "cannot open", errno);
  if (const char* why = not_regular(st.st_mode))
    throw Error(ErrorKind::Io, path + ": " + why + ", not a regular file; dicer reads only regular files");
  // O_NONBLOCK: should the path have become a FIFO since stat(), open()
  // returns at once and fstat() below refuses it.
  fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) io_error(path, "cannot open", errno);
  if (::fstat(fd_, &st) != 0) {
    const int err = errno;
    ::close(fd_);
    io_error(path, "cannot stat", err);
  }
  if (const char* why = not_regular(st.st_mode)) {
    ::close(fd_);
    throw Error(ErrorKind::Io, path + ": " + why + ", not a regular file; dicer reads only regular files");
  }
  size_ = static_cast<std::int64_t>(st.st_size);
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

std::string InputFile::read_at(std::int64_t offset, std::size_t n) const {
  if (offset < 0 || offset >= size_) return {};
  n = std::min<std::uint64_t>(n, static_cast<std::uint64_t>(size_ - offset));  // never more than the file holds
  std::string out(n, '\0');
  std::size_t got = 0;
  while (got < n) {
    const ssize_t r = ::pread(fd_, out.data() + got, n - got, static_cast<off_t>(offset + static_cast<std::int64_t>(got)));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) io_error(path_, "cannot read", errno);
    if (r == 0) break;
    got += static_cast<std::size_t>(r);
  }
  out.resize(got);
  return out;
}

std::string InputFile::read_all() const {
  std::string out;
  out.reserve(static_cast<std::size_t>(size_));  // what the file holds, not what it claims
  char buf[1 << 16];
  for (off_t at = 0;;) {
    const ssize_t r = ::pread(fd_, buf, sizeof buf, at);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) io_error(path_, "cannot read", errno);
    if (r == 0) break;
    out.append(buf, static_cast<std::size_t>(r));
    at += r;
  }
  return out;
}

}  // namespace dicer
