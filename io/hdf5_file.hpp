#pragma once
// Thin RAII over the HDF5 C API, private to the io layer (store/, export/). Every failure becomes a
// dicer::Error naming the file and the dataset.
#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

namespace dicer::h5 {

class Handle {
 public:
  Handle() = default;
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = -1; }
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = o.id_, close_ = o.close_;
      o.id_ = -1;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = -1;
  }
  hid_t get() const { return id_; }
  explicit operator bool() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

// Turns off HDF5's own error printing once per process (errors are ours to report).
void quiet();

class File {
 public:
  static File create(const std::string& path);
  static File open_read(const std::string& path);
  const std::string& path() const { return path_; }
  hid_t id() const { return file_.get(); }

  void group(const std::string& name);
  template <class T>
  void write(const std::string& name, const std::vector<T>& data, std::uint64_t cols = 1);
  template <class T>
  std::vector<T> read(const std::string& name, std::uint64_t cols = 1) const;
  bool exists(const std::string& name) const;
  void write_attr(const std::string& name, std::int64_t value);
  void write_attr(const std::string& name, const std::string& value);
  std::int64_t read_attr_int(const std::string& name) const;
  std::string read_attr_string(const std::string& name) const;

 private:
  std::string path_;
  Handle file_;
};

}  // namespace dicer::h5
