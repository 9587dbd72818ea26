#pragma once
// Thin RAII over the HDF5 C API, private to the io layer (store/, export/). Every failure becomes a
// dicer::Error naming the file and the dataset.
#include <hdf5.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hdf5_lock.hpp"

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
  // True when there was nothing to close or the close succeeded. Under the
  // HDF5 lock like every other call: a handle may close on any thread (the
  // last owner of a store's file may be a cache dropped by another thread).
  bool reset() {
    bool ok = true;
    if (id_ >= 0 && close_) {
      std::lock_guard lock(hdf5_lock());
      ok = close_(id_) >= 0;
    }
    id_ = -1;
    return ok;
  }
  hid_t get() const { return id_; }
  explicit operator bool() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

// Turns off HDF5's own error printing for the calling thread (errors are
// ours to report). Thread-safe HDF5 keeps that switch per thread, the
// others per process: call it on every thread before its first HDF5 call.
void quiet();

// This thread's HDF5 error stack, read after a failed call: the operating
// system's reason when HDF5 or dicer's driver recorded an errno ("No space
// left on device"), else the innermost description; "" when empty.
std::string error_reason();
// Whether the stack holds an error of this minor class (H5E_CANTLOCKFILE...).
bool error_stack_has(hid_t minor);

// Creates (truncates) `path` for writing and returns the file id (< 0 on
// failure, with the reason on the error stack and in *first_errno). Files
// are written in the HDF5 1.10 format (superblock 3: every piece of
// metadata carries a checksum, which the store reader relies on), through
// dicer's driver: POSIX I/O like HDF5's sec2, except that after the first
// failed write (disk full, EFBIG) later writes go to memory. The failure
// still reaches the caller, but HDF5 can then close the file: HDF5 1.10
// frees a file whose close fails yet keeps its id, and crashes at exit
// (CVE-2020-10812). *first_errno (optional; must outlive the file) gets
// the errno of the first failed write, also of one during the close.
// fcpl: the file creation property list (untimed_file_creation for an
// export).
hid_t create_file_id(const std::string& path, int* first_errno = nullptr, hid_t fcpl = H5P_DEFAULT);

// For a program whose HDF5 files are all closed by their owners before
// main returns (the dicer command): HDF5 then runs no cleanup at exit nor
// at MPI_Finalize. A write that fails inside netCDF (an Exodus export on a
// full disk) goes through HDF5's own POSIX driver, not create_file_id's,
// and leaves the freed file's id behind, on which that cleanup crashes.
// Call in main before MPI_Init and any other HDF5 call: HDF5 starts here, and
// parallel HDF5 hooks its cleanup to MPI_Finalize only when it starts
// inside MPI. Not for libraries: other users' files in the process would
// go unflushed at exit.
void no_cleanup_at_exit();

// A file creation property list whose root group records no object times
// (HDF5 stores creation and modification times by default, so the same
// data written a second later would differ in those bytes). Exports use it
// and create their groups and datasets with H5Pset_obj_track_times off:
// the same chunk exported twice is the same file, as an MSH or Exodus
// export is. Invalid (closes nothing) when HDF5 cannot make one.
Handle untimed_file_creation();

class File {
 public:
  // `name` is what messages call the file (the output, not its temporary).
  static File create(const std::string& path, const std::string& name);
  // Opens an existing file read-only. Refused before HDF5 parses anything:
  // a path that is missing, unreadable (permission) or not a regular file
  // (Error{Io}); no HDF5 signature (Error{BadInput}); HDF5 metadata without
  // checksums (superblock 0 or 1, not written by dicer: Error{BadInput}).
  // HDF5 then opens the very file checked (through /proc/self/fd). A file
  // locked by a writer, or marked open for writing, is Error{Io}.
  static File open_read(const std::string& path);
  const std::string& path() const { return path_; }
  const std::string& name() const { return name_; }
  hid_t id() const { return file_.get(); }
  std::uint64_t file_bytes() const { return file_bytes_; }

  // Closes a file being written; throws Error{Io} with the reason when
  // anything failed on the way (a failed write HDF5 swallowed included).
  void close();
  // The reason the last write failed ("" when none did), for messages.
  std::string write_failure() const;

  void group(const std::string& name);
  template <class T>
  void write(const std::string& name, const std::vector<T>& data, std::uint64_t cols = 1);
  template <class T>
  std::vector<T> read(const std::string& name, std::uint64_t cols = 1) const;
  bool exists(const std::string& name) const;
  void write_attr(const std::string& name, std::int64_t value);
  void write_attr(const std::string& name, const std::string& value);
  // Root attributes holding exactly one value of the right class (an
  // integer of at most 8 bytes; a fixed-length string of at most 4096
  // bytes), else Error{Corrupt} naming the attribute.
  std::int64_t read_attr_int(const std::string& name) const;
  std::string read_attr_string(const std::string& name) const;

 private:
  std::string path_, name_;
  std::uint64_t file_bytes_ = 0;
  std::unique_ptr<int> write_errno_;  // the driver's (stable address)
  Handle file_;
};

// Opens dataset `name` of `file` after checking that it is stored in the
// file itself: chunked, no external storage (a store is one file), the
// given rank; Error{Corrupt} naming the dataset otherwise. dims gets the
// extent (rank values).
Handle open_chunked_dataset(const File& file, const std::string& name, int rank, hsize_t* dims);

}  // namespace dicer::h5
