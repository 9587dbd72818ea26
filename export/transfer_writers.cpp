// The assembled prolongation, streamed to a file (transfer.hpp): CSR in
// HDF5 for h5py + scipy, and PETSc's binary matrix format for MatLoad.
// Both take the rows from one ProlongationCursor in id order and write
// them as they come: memory is one batch plus fixed-size buffers.
//
// PETSc's layout puts all row lengths before all column indices before all
// values; the non-zero count is known from the tables (Prolongation::
// nonzeros), so the three sections' offsets are fixed before the first row
// and each streams into its place through its own buffer (pwrite): one
// pass over the rows, not two.
#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/error.hpp"
#include "dicer/transfer.hpp"
#include "hdf5_file.hpp"
#include "hdf5_lock.hpp"

namespace dicer {
namespace {

constexpr size_t kSliceValues = 64 * 1024;  // values buffered per dataset or section before a write
constexpr hsize_t kChunkValues = 64 * 1024; // HDF5 chunk: 512 KiB of int64 or float64

std::string store_name(const FineMesh& m) {
  const std::string path = m.tables().origin.empty() ? "(in memory)" : m.tables().origin;
  return m.info().uuid.empty() ? path : path + " (uuid " + m.info().uuid + ")";
}

// The rows of P, batch by batch, with a check that they tile [0, rows)
// and hold exactly nonzeros() entries (the writers sized their files by it).
// columns: what the writers' columns are (transfer.hpp), checked here.
template <class Fn>
void stream_rows(const Prolongation& p, const std::string& path, const std::function<void(Id, Id)>& progress,
                 std::span<const Id> columns, Fn&& fn) {
  if (!columns.empty()) {
    if (static_cast<Id>(columns.size()) != p.cols())
      throw Error(ErrorKind::Usage, path + ": a column order of " + std::to_string(columns.size()) + " entries for " +
                                        std::to_string(p.cols()) + " columns");
    std::vector<char> seen(columns.size(), 0);
    for (const Id c : columns)
      if (c < 0 || c >= p.cols() || seen[static_cast<size_t>(c)]++)
        throw Error(ErrorKind::Usage, path + ": the column order is not a permutation of 0.." + std::to_string(p.cols() - 1));
  }
  ProlongationCursor cur(p);
  ProlongationBatch b;
  Id next_row = 0, entries = 0;
  std::vector<Id> cols;
  std::vector<double> weights;
  while (cur.next(b)) {
    if (b.row_begin != next_row || b.num_entries() > p.nonzeros() - entries)
      throw InternalError(path + ": prolongation rows out of order or beyond the counted non-zeros");
    // Files get each row's columns ascending, as CSR readers assume (PETSc's
    // AIJ kernels; scipy's has_sorted_indices); the generator gives them in
    // corner order. At most 8 per row: insertion sort.
    cols.assign(b.cols.begin(), b.cols.end());
    if (!columns.empty())
      for (Id& c : cols) c = columns[static_cast<size_t>(c)];
    weights.assign(b.weights.begin(), b.weights.end());
    for (Id r = 0; r < b.num_rows(); ++r)
      for (Id i = b.offsets[static_cast<size_t>(r)] + 1; i < b.offsets[static_cast<size_t>(r) + 1]; ++i)
        for (Id j = i; j > b.offsets[static_cast<size_t>(r)] && cols[static_cast<size_t>(j - 1)] > cols[static_cast<size_t>(j)]; --j)
          std::swap(cols[static_cast<size_t>(j - 1)], cols[static_cast<size_t>(j)]),
              std::swap(weights[static_cast<size_t>(j - 1)], weights[static_cast<size_t>(j)]);
    ProlongationBatch sorted = b;
    sorted.cols = cols, sorted.weights = weights;
    fn(sorted);
    next_row = b.row_end, entries += b.num_entries();
    if (progress) progress(next_row, p.rows());
  }
  if (next_row != p.rows() || entries != p.nonzeros())
    throw InternalError(path + ": prolongation rows " + std::to_string(next_row) + " of " + std::to_string(p.rows()) +
                        ", non-zeros " + std::to_string(entries) + " of " + std::to_string(p.nonzeros()));
}

// ---- HDF5

using Hid = h5::Handle;

struct H5Csr {
  std::string path;
  int write_errno = 0;
  Hid file;
  struct Column {
    const char* name;
    hid_t mem, disk;
    Hid id;
    hsize_t at = 0;
  };
  Column indptr{"indptr", H5T_NATIVE_INT64, H5T_STD_I64LE, {}}, indices{"indices", H5T_NATIVE_INT64, H5T_STD_I64LE, {}},
      data{"data", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, {}};

  [[noreturn]] void io(const std::string& what) const {
    const std::string reason = write_errno ? std::strerror(write_errno) : h5::error_reason();
    throw Error(ErrorKind::Io, path + ": " + what + (reason.empty() ? "" : ": " + reason));
  }

  void create(Column& c, hsize_t size, bool shuffle) {
    hsize_t dims = size, maxdims = H5S_UNLIMITED, chunk = kChunkValues;
    Hid space(H5Screate_simple(1, &dims, &maxdims), H5Sclose);
    Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    if (!space || !dcpl || H5Pset_chunk(dcpl.get(), 1, &chunk) < 0 || (shuffle && H5Pset_shuffle(dcpl.get()) < 0) ||
        H5Pset_deflate(dcpl.get(), 1) < 0 || H5Pset_obj_track_times(dcpl.get(), false) < 0)  // untimed_file_creation
      io(std::string(c.name) + ": cannot set up the dataset");
    c.id = Hid(H5Dcreate2(file.get(), c.name, c.disk, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose);
    if (!c.id) io(std::string("cannot create dataset ") + c.name);
  }

  template <class T>
  void put(Column& c, std::vector<T>& buf) {
    if (buf.empty()) return;
    std::lock_guard lock(hdf5_lock());
    hsize_t start = c.at, count = buf.size();
    Hid fspace(H5Dget_space(c.id.get()), H5Sclose);
    Hid mspace(H5Screate_simple(1, &count, nullptr), H5Sclose);
    if (!fspace || !mspace || H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, &start, nullptr, &count, nullptr) < 0 ||
        H5Dwrite(c.id.get(), c.mem, mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
      io(std::string(c.name) + ": writing values " + std::to_string(start) + ".." + std::to_string(start + count) +
         " failed");
    c.at += count;
    buf.clear();
  }

  void attr(const char* name, const std::vector<std::int64_t>& v) {
    const hsize_t n = v.size();
    Hid space(n == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr), H5Sclose);
    Hid a(H5Acreate2(file.get(), name, H5T_STD_I64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!space || !a || H5Awrite(a.get(), H5T_NATIVE_INT64, v.data()) < 0) io(std::string("cannot write attribute ") + name);
  }
  void attr(const char* name, const std::string& v) {
    Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
    Hid space(H5Screate(H5S_SCALAR), H5Sclose);
    if (!type || !space || H5Tset_size(type.get(), std::max<size_t>(1, v.size())) < 0 ||
        H5Tset_strpad(type.get(), H5T_STR_NULLPAD) < 0 || H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0)
      io(std::string("cannot set up attribute ") + name);
    Hid a(H5Acreate2(file.get(), name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    const std::string padded = v.empty() ? std::string(1, '\0') : v;
    if (!a || H5Awrite(a.get(), type.get(), padded.data()) < 0) io(std::string("cannot write attribute ") + name);
  }

  void close() {
    std::lock_guard lock(hdf5_lock());
    if (H5Fflush(file.get(), H5F_SCOPE_GLOBAL) < 0) io("flush failed");
    indptr.id.reset(), indices.id.reset(), data.id.reset();
    if (!file.reset() || write_errno) io("closing the file failed");
  }
  ~H5Csr() {
    std::lock_guard lock(hdf5_lock());
    indptr.id.reset(), indices.id.reset(), data.id.reset(), file.reset();
  }
};

// ---- PETSc binary

// One section of the file, written from `offset` on through a buffer.
class Section {
 public:
  Section(int fd, const std::string& path, off_t offset) : fd_(fd), path_(path), at_(offset) { buf_.reserve(1 << 20); }
  template <class T>
  void big_endian(T v) {
    static_assert(sizeof(T) == 4 || sizeof(T) == 8);
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    std::reverse(b, b + sizeof(T));  // x86-64 is little-endian
    buf_.insert(buf_.end(), b, b + sizeof(T));
    if (buf_.size() >= (1 << 20)) flush();
  }
  void index(Id v, int bytes) {
    if (bytes == 4) big_endian(static_cast<std::int32_t>(v));
    else big_endian(static_cast<std::int64_t>(v));
  }
  void flush() {
    size_t done = 0;
    while (done < buf_.size()) {
      const ssize_t w = ::pwrite(fd_, buf_.data() + done, buf_.size() - done, at_ + static_cast<off_t>(done));
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) throw Error(ErrorKind::Io, path_ + ": write failed: " + std::string(w < 0 ? std::strerror(errno) : "no bytes written"));
      done += static_cast<size_t>(w);
    }
    at_ += static_cast<off_t>(done);
    buf_.clear();
  }

 private:
  int fd_;
  const std::string& path_;
  off_t at_;
  std::vector<unsigned char> buf_;
};

}  // namespace

void write_prolongation_hdf5(const Prolongation& p, const std::string& path, const std::function<void(Id, Id)>& progress,
                             std::span<const Id> columns, const std::string& columns_are) {
  if (!std::filesystem::path(path).has_filename()) throw Error(ErrorKind::Usage, path + ": not a file name");
  AtomicOutput out(path);  // destroyed last: the file is closed before an unfinished temporary goes
  H5Csr w;
  w.path = path;
  {
    std::lock_guard lock(hdf5_lock());
    h5::quiet();
    const Hid fcpl = h5::untimed_file_creation();
    w.file = fcpl ? Hid(h5::create_file_id(out.temp_path(), &w.write_errno, fcpl.get()), H5Fclose) : Hid();
    if (!w.file) w.io("cannot create " + out.temp_path());
    w.create(w.indptr, static_cast<hsize_t>(p.rows()) + 1, true);
    w.create(w.indices, static_cast<hsize_t>(p.nonzeros()), true);
    w.create(w.data, static_cast<hsize_t>(p.nonzeros()), false);
    w.attr("shape", std::vector<std::int64_t>{p.rows(), p.cols()});
    w.attr("nnz", std::vector<std::int64_t>{p.nonzeros()});
    w.attr("format", std::string("csr"));
    w.attr("coarse", store_name(p.coarse()));
    w.attr("fine", store_name(p.fine()));
    w.attr("columns", columns_are.empty() ? std::string("coarse store node ids") : columns_are);
  }
  std::vector<std::int64_t> ip, ix;
  std::vector<double> dv;
  ip.reserve(kSliceValues), ix.reserve(kSliceValues), dv.reserve(kSliceValues);
  Id base = 0;
  stream_rows(p, path, progress, columns, [&](const ProlongationBatch& b) {
    for (Id r = 0; r < b.num_rows(); ++r) {
      ip.push_back(base + b.offsets[static_cast<size_t>(r)]);
      if (ip.size() >= kSliceValues) w.put(w.indptr, ip);
    }
    for (size_t e = 0; e < b.cols.size(); ++e) {
      ix.push_back(b.cols[e]), dv.push_back(b.weights[e]);
      if (ix.size() >= kSliceValues) w.put(w.indices, ix), w.put(w.data, dv);
    }
    base += b.num_entries();
  });
  ip.push_back(base);
  w.put(w.indptr, ip), w.put(w.indices, ix), w.put(w.data, dv);
  w.close();
  out.commit();
}

void write_prolongation_petsc(const Prolongation& p, const std::string& path, int index_bytes,
                              const std::function<void(Id, Id)>& progress, std::span<const Id> columns) {
  if (index_bytes != 4 && index_bytes != 8)
    throw Error(ErrorKind::Usage, path + ": PETSc indices are 4 or 8 bytes, not " + std::to_string(index_bytes));
  if (index_bytes == 4)
    for (const auto& [what, n] : {std::pair{"rows", p.rows()}, std::pair{"columns", p.cols()}, std::pair{"non-zeros", p.nonzeros()}})
      if (n > INT32_MAX)
        throw Error(ErrorKind::Usage, path + ": " + std::to_string(n) + " " + what +
                                          " do not fit PETSc's 32-bit indices; write 64-bit indices (for a PETSc "
                                          "built --with-64-bit-indices) or CSR in HDF5");
  if (!std::filesystem::path(path).has_filename()) throw Error(ErrorKind::Usage, path + ": not a file name");
  AtomicOutput out(path);
  const int fd = ::open(out.temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(ErrorKind::Io, path + ": cannot create " + out.temp_path() + ": " + std::strerror(errno));
  struct Fd {
    int fd;
    ~Fd() {
      if (fd >= 0) ::close(fd);
    }
  } guard{fd};
  const off_t ib = index_bytes, rows = p.rows(), nnz = p.nonzeros();
  Section header(fd, path, 0), lengths(fd, path, 4 * ib), cols(fd, path, 4 * ib + rows * ib),
      values(fd, path, 4 * ib + rows * ib + nnz * ib);
  header.index(1211216, index_bytes);  // MAT_FILE_CLASSID
  header.index(p.rows(), index_bytes), header.index(p.cols(), index_bytes), header.index(p.nonzeros(), index_bytes);
  stream_rows(p, path, progress, columns, [&](const ProlongationBatch& b) {
    for (Id r = 0; r < b.num_rows(); ++r)
      lengths.index(b.offsets[static_cast<size_t>(r + 1)] - b.offsets[static_cast<size_t>(r)], index_bytes);
    for (size_t e = 0; e < b.cols.size(); ++e) cols.index(b.cols[e], index_bytes), values.big_endian(b.weights[e]);
  });
  header.flush(), lengths.flush(), cols.flush(), values.flush();
  guard.fd = -1;
  if (::close(fd) != 0) throw Error(ErrorKind::Io, path + ": close failed: " + std::string(std::strerror(errno)));
  out.commit();
}

}  // namespace dicer
