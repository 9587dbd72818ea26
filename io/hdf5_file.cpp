#include "hdf5_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <type_traits>

#include "dicer/error.hpp"

namespace dicer::h5 {
namespace {

template <class T>
hid_t mem_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_NATIVE_DOUBLE;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_NATIVE_INT64;
  else if constexpr (std::is_same_v<T, std::int32_t>) return H5T_NATIVE_INT32;
  else if constexpr (std::is_same_v<T, std::int8_t>) return H5T_NATIVE_INT8;
  else if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_NATIVE_UINT8;
  else if constexpr (std::is_same_v<T, char>) return H5T_NATIVE_CHAR;
  else static_assert(sizeof(T) == 0, "unsupported type");
}
template <class T>
hid_t file_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_IEEE_F64LE;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_STD_I64LE;
  else if constexpr (std::is_same_v<T, std::int32_t>) return H5T_STD_I32LE;
  else if constexpr (std::is_same_v<T, std::int8_t>) return H5T_STD_I8LE;
  else if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_STD_U8LE;
  else if constexpr (std::is_same_v<T, char>) return H5T_STD_I8LE;
}

constexpr hsize_t kPageBytes = 64 * 1024;  // one chunk; the page of issue 3's cache

struct StackScan {
  hid_t minor = -1;
  bool found = false;
  int err = 0;            // innermost errno in a description ("errno = N")
  std::string innermost;  // first description walked (the deepest)
};

herr_t scan(unsigned n, const H5E_error2_t* e, void* data) {
  auto* s = static_cast<StackScan*>(data);
  if (e->min_num == s->minor) s->found = true;
  const char* desc = e->desc ? e->desc : "";
  if (n == 0) s->innermost = desc;
  if (s->err == 0)
    if (const char* p = std::strstr(desc, "errno = ")) s->err = std::atoi(p + 8);
  return 0;
}

StackScan scan_stack(hid_t minor) {
  StackScan s;
  s.minor = minor;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, scan, &s);
  return s;
}

// The HDF5 superblock: its signature at 0, 512, 1024, 2048... (a user
// block may precede it); the version byte follows the signature. Returns
// the version, -1 without a signature, -2 when the file cannot be read.
int superblock_version(int fd, std::uint64_t size, std::uint8_t* flags) {
  static const unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  for (std::uint64_t at = 0; at + 12 <= size; at = at == 0 ? 512 : 2 * at) {
    unsigned char b[12];
    const ssize_t n = ::pread(fd, b, sizeof b, static_cast<off_t>(at));
    if (n < 0) return -2;
    if (n == static_cast<ssize_t>(sizeof b) && std::memcmp(b, kSignature, 8) == 0) {
      *flags = b[11];  // versions 2 and 3: file consistency flags
      return b[8];
    }
  }
  return -1;
}

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

}  // namespace

void quiet() {
  thread_local bool done = false;
  if (done) return;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  done = true;
}

std::string error_reason() {
  const StackScan s = scan_stack(-1);
  if (s.err > 0) return std::strerror(s.err);
  return s.innermost;
}

bool error_stack_has(hid_t minor) { return scan_stack(minor).found; }

File File::create(const std::string& path, const std::string& name) {
  quiet();
  File f;
  f.path_ = path;
  f.name_ = name;
  f.write_errno_ = std::make_unique<int>(0);
  hid_t id = create_file_id(path, f.write_errno_.get());
  if (id < 0) {
    const std::string reason = error_reason();
    throw Error(ErrorKind::Io, name + ": cannot create the file (as " + path + ")" + (reason.empty() ? "" : ": " + reason));
  }
  f.file_ = Handle(id, H5Fclose);
  return f;
}

std::string File::write_failure() const {
  if (write_errno_ && *write_errno_) return std::strerror(*write_errno_);
  return error_reason();
}

void File::close() {
  const bool ok = file_.reset();
  if (!ok || (write_errno_ && *write_errno_)) {
    const std::string reason = write_failure();
    throw Error(ErrorKind::Io, name_ + ": cannot write" + (reason.empty() ? "" : ": " + reason));
  }
}

File File::open_read(const std::string& path) {
  quiet();
  // Our own descriptor first: errno tells a missing file from an unreadable
  // one, O_NONBLOCK keeps a FIFO from blocking, and HDF5 then opens this
  // very inode (a file swapped in after the checks is not what HDF5 reads).
  const Fd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) {
    const int err = errno;
    if (err == ENOENT) throw Error(ErrorKind::Io, path + ": no such file");
    if (err == EACCES || err == EPERM) throw Error(ErrorKind::Io, path + ": permission denied (cannot read the file)");
    throw Error(ErrorKind::Io, path + ": cannot open: " + std::strerror(err));
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) throw Error(ErrorKind::Io, path + ": cannot stat: " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw Error(ErrorKind::Io, path + ": not a regular file");
  std::uint8_t flags = 0;
  const int version = superblock_version(fd.get(), static_cast<std::uint64_t>(st.st_size), &flags);
  if (version == -2) throw Error(ErrorKind::Io, path + ": cannot read: " + std::strerror(errno));
  if (version < 0) throw Error(ErrorKind::BadInput, path + ": not an HDF5 file (not a dicer store)");
  if (version < 2)
    throw Error(ErrorKind::BadInput, path + ": HDF5 superblock version " + std::to_string(version) +
                                         ": not a dicer store (dicer writes HDF5 1.10 metadata, which carries "
                                         "checksums; older layouts are not read)");
  File f;
  f.path_ = f.name_ = path;
  f.file_bytes_ = static_cast<std::uint64_t>(st.st_size);
  const std::string self = "/proc/self/fd/" + std::to_string(fd.get());
  hid_t id = H5Fopen(self.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) {
    if (error_stack_has(H5E_CANTLOCKFILE))
      throw Error(ErrorKind::Io, path + ": locked by another process that has it open for writing (HDF5 file "
                                        "locking; HDF5_USE_FILE_LOCKING=FALSE reads it anyway)");
    if (version >= 3 && (flags & 0x5) != 0)
      throw Error(ErrorKind::Io, path + ": marked as open for writing by a process that did not close it (HDF5 "
                                        "file consistency flags; `h5clear -s " + path + "` clears them)");
    const std::string reason = error_reason();
    throw Error(ErrorKind::Corrupt, path + ": HDF5 cannot open the file (truncated or damaged)" +
                                        (reason.empty() ? "" : ": " + reason));
  }
  f.file_ = Handle(id, H5Fclose);
  return f;
}

void File::group(const std::string& name) {
  hid_t g = H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) throw Error(ErrorKind::Io, name_ + ": cannot create group " + name);
  H5Gclose(g);
}

bool File::exists(const std::string& name) const { return H5Lexists(id(), name.c_str(), H5P_DEFAULT) > 0; }

template <class T>
void File::write(const std::string& name, const std::vector<T>& data, std::uint64_t cols) {
  const hsize_t rows = data.size() / cols;
  const int rank = cols > 1 ? 2 : 1;
  hsize_t dims[2] = {rows, cols}, maxdims[2] = {H5S_UNLIMITED, cols};
  hsize_t chunk[2] = {std::max<hsize_t>(1, std::min<hsize_t>(std::max<hsize_t>(rows, 1), kPageBytes / sizeof(T) / cols)),
                      cols};
  Handle space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (!space || !dcpl || H5Pset_chunk(dcpl.get(), rank, chunk) < 0)
    throw Error(ErrorKind::Io, name_ + ": " + name + ": cannot set up dataset");
  Handle ds(H5Dcreate2(id(), name.c_str(), file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
            H5Dclose);
  if (!ds) throw Error(ErrorKind::Io, name_ + ": " + name + ": cannot create dataset");
  // Flushed here so that a full disk fails this call, not the close.
  if ((rows > 0 && H5Dwrite(ds.get(), mem_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0) ||
      H5Dflush(ds.get()) < 0)
    throw Error(ErrorKind::Io, name_ + ": " + name + ": write failed: " + write_failure());
}

Handle open_chunked_dataset(const File& file, const std::string& name, int rank, hsize_t* dims) {
  const std::string what = file.path() + ": dataset " + name;
  if (!file.exists(name)) throw Error(ErrorKind::Corrupt, what + " is missing");
  Handle ds(H5Dopen2(file.id(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds) throw Error(ErrorKind::Corrupt, what + " cannot be opened (not a dataset, or damaged)");
  Handle dcpl(H5Dget_create_plist(ds.get()), H5Pclose);
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  if (!dcpl || !space) throw Error(ErrorKind::Corrupt, what + " cannot be opened (damaged)");
  if (H5Pget_layout(dcpl.get()) != H5D_CHUNKED || H5Pget_external_count(dcpl.get()) != 0)
    throw Error(ErrorKind::Corrupt, what + " is not stored as chunks in this file (virtual, external or contiguous "
                                           "storage; a store is one file)");
  if (H5Sget_simple_extent_type(space.get()) != H5S_SIMPLE || H5Sget_simple_extent_ndims(space.get()) != rank ||
      H5Sget_simple_extent_dims(space.get(), dims, nullptr) != rank)
    throw Error(ErrorKind::Corrupt, what + " does not have rank " + std::to_string(rank));
  return ds;
}

template <class T>
std::vector<T> File::read(const std::string& name, std::uint64_t cols) const {
  const int rank = cols > 1 ? 2 : 1;
  hsize_t dims[2] = {0, 1};
  Handle ds = open_chunked_dataset(*this, name, rank, dims);
  if (cols > 1 && dims[1] != cols)
    throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " has the wrong shape (expected " +
                                        std::to_string(cols) + " column(s))");
  Handle type(H5Dget_type(ds.get()), H5Tclose);
  if (!type || H5Tequal(type.get(), file_type<T>()) <= 0)
    throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " has an unexpected element type");
  const hsize_t n = dims[0] * cols;
  // Data the file holds: compressed at most ~255:1 (LZ4's limit), so more
  // values than that is a lie about the shape, not a big dataset.
  if (dims[0] > (file_bytes_ + (1u << 20)) * 256 / sizeof(T) / cols)
    throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " claims " + std::to_string(n) +
                                        " values, more than the file can hold");
  std::vector<T> out(n);
  if (n > 0 && H5Dread(ds.get(), mem_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + ": read failed (damaged page?)");
  return out;
}

void File::write_attr(const std::string& name, std::int64_t value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle a(H5Acreate2(id(), name.c_str(), H5T_STD_I64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a || H5Awrite(a.get(), H5T_NATIVE_INT64, &value) < 0)
    throw Error(ErrorKind::Io, name_ + ": cannot write attribute " + name);
}

void File::write_attr(const std::string& name, const std::string& value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type.get(), std::max<size_t>(1, value.size()));
  H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
  Handle a(H5Acreate2(id(), name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a || H5Awrite(a.get(), type.get(), value.data()) < 0)
    throw Error(ErrorKind::Io, name_ + ": cannot write attribute " + name);
}

namespace {

// A root attribute holding exactly one value of class `cls` whose size is
// in [1, max_size]; what read_attr_* may read into a buffer of that size.
std::pair<Handle, Handle> single_value_attr(const File& f, const std::string& name, H5T_class_t cls, size_t max_size,
                                            const char* kind) {
  const std::string what = f.path() + ": attribute " + name;
  if (H5Aexists(f.id(), name.c_str()) <= 0) throw Error(ErrorKind::Corrupt, what + " is missing");
  Handle a(H5Aopen(f.id(), name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!a) throw Error(ErrorKind::Corrupt, what + " cannot be opened");
  Handle space(H5Aget_space(a.get()), H5Sclose);
  Handle type(H5Aget_type(a.get()), H5Tclose);
  if (!space || !type) throw Error(ErrorKind::Corrupt, what + " cannot be opened");
  const H5S_class_t sc = H5Sget_simple_extent_type(space.get());
  if ((sc != H5S_SCALAR && sc != H5S_SIMPLE) || H5Sget_simple_extent_npoints(space.get()) != 1)
    throw Error(ErrorKind::Corrupt, what + " does not hold exactly one value");
  const size_t size = H5Tget_size(type.get());
  if (H5Tget_class(type.get()) != cls || size == 0 || size > max_size ||
      (cls == H5T_STRING && H5Tis_variable_str(type.get()) != 0))
    throw Error(ErrorKind::Corrupt, what + " is not " + kind);
  return {std::move(a), std::move(type)};
}

}  // namespace

std::int64_t File::read_attr_int(const std::string& name) const {
  const auto [a, type] = single_value_attr(*this, name, H5T_INTEGER, 8, "an integer of at most 8 bytes");
  std::int64_t v = 0;
  if (H5Aread(a.get(), H5T_NATIVE_INT64, &v) < 0)
    throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " cannot be read as an integer");
  return v;
}

std::string File::read_attr_string(const std::string& name) const {
  const auto [a, type] = single_value_attr(*this, name, H5T_STRING, 4096, "a fixed-length string of at most 4096 bytes");
  std::string s(H5Tget_size(type.get()), '\0');
  if (H5Aread(a.get(), type.get(), s.data()) < 0) throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " cannot be read");
  s.resize(s.find('\0') == std::string::npos ? s.size() : s.find('\0'));
  return s;
}

#define DICER_H5_INSTANTIATE(T)                                                           \
  template void File::write<T>(const std::string&, const std::vector<T>&, std::uint64_t); \
  template std::vector<T> File::read<T>(const std::string&, std::uint64_t) const;
DICER_H5_INSTANTIATE(double)
DICER_H5_INSTANTIATE(std::int64_t)
DICER_H5_INSTANTIATE(std::int32_t)
DICER_H5_INSTANTIATE(std::int8_t)
DICER_H5_INSTANTIATE(std::uint8_t)
DICER_H5_INSTANTIATE(char)

void no_cleanup_at_exit() {
  H5dont_atexit();
  H5open();
}

}  // namespace dicer::h5
