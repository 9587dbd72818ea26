#pragma once
// Opening the files the readers are given (coarse meshes, the intervals
// file). Private to readers/.
//
// Only regular files are read: a FIFO would block open() or read() forever
// (`dicer dice` hung on one), a directory reads as an empty file. The kind
// is checked with stat() before opening, and again on the open descriptor.
#include <cstdint>
#include <string>

namespace dicer {

class InputFile {
 public:
  // Throws Error{Io} naming the path: missing, unreadable, or not a regular
  // file ("is a directory", "is a FIFO (named pipe)", ...).
  explicit InputFile(const std::string& path);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  std::int64_t size() const { return size_; }
  // Up to n bytes from `offset` (fewer where the file ends).
  std::string read_at(std::int64_t offset, std::size_t n) const;
  std::string head(std::size_t n) const { return read_at(0, n); }
  // The whole file, read to its end.
  std::string read_all() const;

 private:
  std::string path_;
  int fd_ = -1;
  std::int64_t size_ = 0;
};

}  // namespace dicer
