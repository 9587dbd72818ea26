#include "hdf5_file.hpp"

#include <filesystem>
#include <mutex>
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

}  // namespace

void quiet() {
  static std::once_flag once;
  std::call_once(once, [] { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); });
}

File File::create(const std::string& path) {
  quiet();
  File f;
  f.path_ = path;
  hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (id < 0) throw Error(ErrorKind::Io, path + ": cannot create HDF5 file");
  f.file_ = Handle(id, H5Fclose);
  return f;
}

File File::open_read(const std::string& path) {
  quiet();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(ErrorKind::Io, path + ": no such file");
  if (H5Fis_hdf5(path.c_str()) <= 0) throw Error(ErrorKind::BadInput, path + ": not an HDF5 file (not a dicer store)");
  File f;
  f.path_ = path;
  hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw Error(ErrorKind::Corrupt, path + ": HDF5 cannot open the file (truncated or damaged)");
  f.file_ = Handle(id, H5Fclose);
  return f;
}

void File::group(const std::string& name) {
  hid_t g = H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) throw Error(ErrorKind::Io, path_ + ": cannot create group " + name);
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
    throw Error(ErrorKind::Io, path_ + ": " + name + ": cannot set up dataset");
  Handle ds(H5Dcreate2(id(), name.c_str(), file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
            H5Dclose);
  if (!ds) throw Error(ErrorKind::Io, path_ + ": " + name + ": cannot create dataset");
  if (rows > 0 && H5Dwrite(ds.get(), mem_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0)
    throw Error(ErrorKind::Io, path_ + ": " + name + ": write failed");
}

template <class T>
std::vector<T> File::read(const std::string& name, std::uint64_t cols) const {
  if (!exists(name)) throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " is missing");
  Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds) throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " cannot be opened");
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  hsize_t dims[2] = {0, 1};
  if (rank != (cols > 1 ? 2 : 1) || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0 ||
      (cols > 1 && dims[1] != cols))
    throw Error(ErrorKind::Corrupt, path_ + ": dataset " + name + " has the wrong shape (expected " +
                                        std::to_string(cols) + " column(s))");
  const hsize_t n = dims[0] * cols;
  std::error_code ec;
  const auto fsize = std::filesystem::file_size(path_, ec);
  if (n > (static_cast<hsize_t>(fsize) + (1u << 20)) * 64 / sizeof(T))
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
    throw Error(ErrorKind::Io, path_ + ": cannot write attribute " + name);
}

void File::write_attr(const std::string& name, const std::string& value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type.get(), std::max<size_t>(1, value.size()));
  H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
  Handle a(H5Acreate2(id(), name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a || H5Awrite(a.get(), type.get(), value.data()) < 0)
    throw Error(ErrorKind::Io, path_ + ": cannot write attribute " + name);
}

std::int64_t File::read_attr_int(const std::string& name) const {
  if (H5Aexists(id(), name.c_str()) <= 0) throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " is missing");
  Handle a(H5Aopen(id(), name.c_str(), H5P_DEFAULT), H5Aclose);
  std::int64_t v = 0;
  if (!a || H5Aread(a.get(), H5T_NATIVE_INT64, &v) < 0)
    throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " cannot be read as an integer");
  return v;
}

std::string File::read_attr_string(const std::string& name) const {
  if (H5Aexists(id(), name.c_str()) <= 0) throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " is missing");
  Handle a(H5Aopen(id(), name.c_str(), H5P_DEFAULT), H5Aclose);
  Handle type(H5Aget_type(a.get()), H5Tclose);
  if (!a || !type || H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) > 0)
    throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " is not a fixed-length string");
  const size_t n = H5Tget_size(type.get());
  if (n > 4096) throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name + " is implausibly long");
  std::string s(n, '\0');
  if (H5Aread(a.get(), type.get(), s.data()) < 0) throw Error(ErrorKind::Corrupt, path_ + ": attribute " + name);
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

}  // namespace dicer::h5
