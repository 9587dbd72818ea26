// VTKHDF UnstructuredGrid 1.0 writer: one partition per ExportChunk,
// appended to extendible, chunked datasets so memory stays bounded by the
// chunk being written (plus one slice buffer and HDF5's chunk caches).
//
// Layout (what VTK 9.1's vtkHDFReader reads):
//   /VTKHDF                      attrs Version = [1, 0], Type = "UnstructuredGrid"
//   /VTKHDF/NumberOfPoints       [P] int64
//   /VTKHDF/NumberOfCells        [P] int64
//   /VTKHDF/NumberOfConnectivityIds [P] int64
//   /VTKHDF/Points               [sum N, 3] float64
//   /VTKHDF/Types                [sum C] uint8 (12 hexahedron, 9 quad)
//   /VTKHDF/Connectivity         [sum C * corners] int64, partition-local
//   /VTKHDF/Offsets              [sum (C + 1)] int64, each partition from 0
//   /VTKHDF/PointData/GlobalNodeId  [sum N] int64
//   /VTKHDF/CellData/GlobalElementId [sum C] int64
//   /VTKHDF/CellData/BlockId     [sum C] int64 (the block's file id)
// Only HDF5's built-in deflate filter is used, so ParaView needs no plugin.
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "hdf5_file.hpp"
#include "hdf5_lock.hpp"

namespace dicer {
namespace {

constexpr std::uint8_t kVtkQuad = 9, kVtkHexahedron = 12;
constexpr hsize_t kChunkBytes = 512 * 1024;  // HDF5 chunk: below the default 1 MiB chunk cache
constexpr hsize_t kSliceRows = 64 * 1024;    // rows converted and written per H5Dwrite
constexpr unsigned kDeflateLevel = 1;

using Hid = h5::Handle;  // an HDF5 identifier closed on scope exit

template <class T>
hid_t mem_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_NATIVE_DOUBLE;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_NATIVE_INT64;
  else if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_NATIVE_UINT8;
  else static_assert(sizeof(T) == 0, "unsupported type");
}
template <class T>
hid_t file_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_IEEE_F64LE;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_STD_I64LE;
  else if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_STD_U8LE;
  else static_assert(sizeof(T) == 0, "unsupported type");
}

}  // namespace

struct VtkHdfWriter::Impl {
  std::string path, tmp;
  std::unique_ptr<AtomicOutput> out;  // rank 0's (or the single process's)
  const VtkHdfCollective* par = nullptr;
  VtkHdfCollective par_copy;
  Id partitions = 0, written = 0;
  bool finished = false, broken = false;
  Hid file, root;

  // One extendible dataset: rows x width (width 1: rank 1).
  struct Dataset {
    std::string name;
    Hid id;
    hsize_t width = 1, rows = 0;
  };
  Dataset number_of_points, number_of_cells, number_of_connectivity_ids, points, types, connectivity, offsets,
      global_node_id, global_element_id, block_id;

  int write_errno = 0;  // the first failed write (h5::create_file_id)

  [[noreturn]] void io(const std::string& what) const {
    const std::string reason = write_errno ? std::strerror(write_errno) : h5::error_reason();
    throw Error(ErrorKind::Io, path + ": " + what + (reason.empty() ? "" : ": " + reason));
  }

  Hid group(hid_t parent, const char* name) {
    Hid g(H5Gcreate2(parent, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!g) io(std::string("cannot create group ") + name);
    return g;
  }

  template <class T>
  void create(Dataset& d, hid_t parent, const char* name, hsize_t width) {
    d.name = name;
    d.width = width;
    const int rank = width > 1 ? 2 : 1;
    const hsize_t chunk_rows = std::max<hsize_t>(1, kChunkBytes / (width * sizeof(T)));
    hsize_t dims[2] = {0, width}, maxdims[2] = {H5S_UNLIMITED, width}, chunk[2] = {chunk_rows, width};
    Hid space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
    Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    if (!space || !dcpl || H5Pset_chunk(dcpl.get(), rank, chunk) < 0) io(d.name + ": cannot set up dataset");
    if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0 && H5Pset_deflate(dcpl.get(), kDeflateLevel) < 0)
      io(d.name + ": cannot set up deflate");
    d.id = Hid(H5Dcreate2(parent, name, file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose);
    if (!d.id) io(d.name + ": cannot create dataset");
  }

  // Appends `rows` rows; fill(first, n, out) writes rows [first, first + n)
  // (n * width values) into out. Converts and writes kSliceRows at a time.
  // Collectively, every rank appends its rows after those of the ranks
  // before it, in the same number of (possibly empty) collective writes.
  template <class T, class Fill>
  void append(Dataset& d, hsize_t rows, Fill&& fill) {
    hsize_t at = d.rows, total = d.rows + rows, slices = (rows + kSliceRows - 1) / kSliceRows;
    hid_t dxpl = H5P_DEFAULT;
    if (par) {
      const auto all = par->allgather(static_cast<std::int64_t>(rows));
      hsize_t before = 0, sum = 0, most = 0;
      for (int r = 0; r < par->size; ++r) {
        if (r < par->rank) before += static_cast<hsize_t>(all[r]);
        sum += static_cast<hsize_t>(all[r]);
        most = std::max<hsize_t>(most, (static_cast<hsize_t>(all[r]) + kSliceRows - 1) / kSliceRows);
      }
      at = d.rows + before, total = d.rows + sum, slices = most;
      dxpl = static_cast<hid_t>(par->transfer);
    }
    if (total == d.rows) return;
    const int rank = d.width > 1 ? 2 : 1;
    hsize_t new_dims[2] = {total, d.width};
    if (H5Dset_extent(d.id.get(), new_dims) < 0) io(d.name + ": cannot extend dataset");
    d.rows = total;
    Hid fspace(H5Dget_space(d.id.get()), H5Sclose);
    if (!fspace) io(d.name + ": cannot get dataspace");
    std::vector<T> buf(static_cast<size_t>(std::max<hsize_t>(1, std::min(rows, kSliceRows)) * d.width));
    for (hsize_t s = 0; s < slices; ++s) {
      const hsize_t first = s * kSliceRows, n = first < rows ? std::min(kSliceRows, rows - first) : 0;
      if (n > 0) fill(static_cast<Id>(first), static_cast<Id>(n), buf.data());
      hsize_t start[2] = {at + first, 0}, count[2] = {n, d.width};
      Hid mspace(H5Screate_simple(rank, count, nullptr), H5Sclose);
      const bool selected = n > 0 ? H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) >= 0
                                  : H5Sselect_none(fspace.get()) >= 0 && H5Sselect_none(mspace.get()) >= 0;
      if (!mspace || !selected || H5Dwrite(d.id.get(), mem_type<T>(), mspace.get(), fspace.get(), dxpl, buf.data()) < 0)
        io(d.name + ": writing rows " + std::to_string(at + first) + ".." + std::to_string(at + first + n) + " failed");
    }
  }

  void open() {
    h5::quiet();  // this thread's switch (hdf5_file.hpp)
    // One process: dicer's driver (a full disk fails the write, yet the
    // file still closes). Several ranks write one file through MPI-IO.
    file = par ? Hid(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, static_cast<hid_t>(par->file_access)), H5Fclose)
               : Hid(h5::create_file_id(tmp, &write_errno), H5Fclose);
    if (!file) io("cannot create " + tmp);
    root = group(file.get(), "VTKHDF");
    {  // Version = [1, 0]
      const hsize_t two = 2;
      const int version[2] = {1, 0};
      Hid space(H5Screate_simple(1, &two, nullptr), H5Sclose);
      Hid attr(H5Acreate2(root.get(), "Version", H5T_STD_I32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
      if (!space || !attr || H5Awrite(attr.get(), H5T_NATIVE_INT, version) < 0) io("cannot write attribute Version");
    }
    {  // Type = "UnstructuredGrid", fixed-length ASCII, null-padded, no terminator
      static constexpr char kType[] = "UnstructuredGrid";
      Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
      Hid space(H5Screate(H5S_SCALAR), H5Sclose);
      if (!type || !space || H5Tset_size(type.get(), sizeof(kType) - 1) < 0 ||
          H5Tset_strpad(type.get(), H5T_STR_NULLPAD) < 0 || H5Tset_cset(type.get(), H5T_CSET_ASCII) < 0)
        io("cannot set up attribute Type");
      Hid attr(H5Acreate2(root.get(), "Type", type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
      if (!attr || H5Awrite(attr.get(), type.get(), kType) < 0) io("cannot write attribute Type");
    }
    Hid point_data = group(root.get(), "PointData"), cell_data = group(root.get(), "CellData");
    create<std::int64_t>(number_of_points, root.get(), "NumberOfPoints", 1);
    create<std::int64_t>(number_of_cells, root.get(), "NumberOfCells", 1);
    create<std::int64_t>(number_of_connectivity_ids, root.get(), "NumberOfConnectivityIds", 1);
    create<double>(points, root.get(), "Points", 3);
    create<std::uint8_t>(types, root.get(), "Types", 1);
    create<std::int64_t>(connectivity, root.get(), "Connectivity", 1);
    create<std::int64_t>(offsets, root.get(), "Offsets", 1);
    create<std::int64_t>(global_node_id, point_data.get(), "GlobalNodeId", 1);
    create<std::int64_t>(global_element_id, cell_data.get(), "GlobalElementId", 1);
    create<std::int64_t>(block_id, cell_data.get(), "BlockId", 1);
  }

  void close_all() {
    for (Dataset* d : {&number_of_points, &number_of_cells, &number_of_connectivity_ids, &points, &types,
                       &connectivity, &offsets, &global_node_id, &global_element_id, &block_id})
      d->id.reset();
    root.reset();
  }

  void remove_tmp() {
    close_all();
    file.reset();
    out.reset();  // removes the uncommitted temporary
  }

  // The chunk's arrays agree with each other (before any dataset grows).
  void validate(const ExportChunk& c) {
    const Id nn = c.num_nodes(), ne = c.num_elements();
    const int corners = c.corners();
    const std::string part = "partition " + std::to_string(par ? par->rank : written);
    if ((c.mode() == Mode::Volume && corners != 8) || (c.mode() == Mode::Surface && corners != 4))
      throw Error(ErrorKind::Usage, path + ": " + part + ": " + std::to_string(corners) + " corners per element");
    if (static_cast<Id>(c.x().size()) != nn || static_cast<Id>(c.y().size()) != nn ||
        static_cast<Id>(c.z().size()) != nn || static_cast<Id>(c.element_block().size()) != ne ||
        static_cast<Id>(c.connectivity().size()) != ne * corners)
      throw Error(ErrorKind::Usage, path + ": " + part + ": chunk is not prepared (array sizes disagree)");
    for (Id v : c.connectivity())
      if (v < 0 || v >= nn)
        throw Error(ErrorKind::Usage, path + ": " + part + ": local node id " + std::to_string(v) + " out of range");
    const auto& blocks = c.mesh().info().blocks;
    for (std::int32_t b : c.element_block())
      if (b < 0 || static_cast<size_t>(b) >= blocks.size())
        throw Error(ErrorKind::Usage, path + ": " + part + ": block index " + std::to_string(b) + " out of range");
  }

  void write(const ExportChunk& c) {
    const Id nn = c.num_nodes(), ne = c.num_elements();
    const int corners = c.corners();
    const std::uint8_t cell_type = c.mode() == Mode::Volume ? kVtkHexahedron : kVtkQuad;
    const auto& blocks = c.mesh().info().blocks;
    auto one = [](std::int64_t v) { return [v](Id, Id, std::int64_t* out) { out[0] = v; }; };
    append<std::int64_t>(number_of_points, 1, one(nn));
    append<std::int64_t>(number_of_cells, 1, one(ne));
    append<std::int64_t>(number_of_connectivity_ids, 1, one(ne * corners));
    const auto x = c.x(), y = c.y(), z = c.z();
    append<double>(points, static_cast<hsize_t>(nn), [&](Id first, Id n, double* out) {
      for (Id i = 0; i < n; ++i) out[3 * i] = x[first + i], out[3 * i + 1] = y[first + i], out[3 * i + 2] = z[first + i];
    });
    append<std::uint8_t>(types, static_cast<hsize_t>(ne),
                         [&](Id, Id n, std::uint8_t* out) { std::fill(out, out + n, cell_type); });
    const auto conn = c.connectivity();
    append<std::int64_t>(connectivity, static_cast<hsize_t>(ne * corners),
                         [&](Id first, Id n, std::int64_t* out) { std::copy_n(conn.data() + first, n, out); });
    append<std::int64_t>(offsets, static_cast<hsize_t>(ne + 1), [&](Id first, Id n, std::int64_t* out) {
      for (Id i = 0; i < n; ++i) out[i] = (first + i) * corners;
    });
    const auto ng = c.node_global();
    append<std::int64_t>(global_node_id, static_cast<hsize_t>(nn),
                         [&](Id first, Id n, std::int64_t* out) { std::copy_n(ng.data() + first, n, out); });
    const auto eg = c.element_global();
    append<std::int64_t>(global_element_id, static_cast<hsize_t>(ne),
                         [&](Id first, Id n, std::int64_t* out) { std::copy_n(eg.data() + first, n, out); });
    const auto eb = c.element_block();
    append<std::int64_t>(block_id, static_cast<hsize_t>(ne), [&](Id first, Id n, std::int64_t* out) {
      for (Id i = 0; i < n; ++i) out[i] = blocks[static_cast<size_t>(eb[first + i])].id;
    });
  }
};

VtkHdfWriter::VtkHdfWriter(const std::string& path, Id partitions) : impl_(new Impl) {
  namespace fs = std::filesystem;
  std::lock_guard lock(hdf5_lock());
  impl_->path = path;
  impl_->partitions = partitions;
  try {
    if (partitions < 1)
      throw Error(ErrorKind::Usage, path + ": VTKHDF needs at least one partition, got " + std::to_string(partitions));
    const fs::path final_path(path);
    if (!final_path.has_filename()) throw Error(ErrorKind::Usage, path + ": not a file name");
    impl_->out = std::make_unique<AtomicOutput>(path);
    impl_->tmp = impl_->out->temp_path();
    impl_->open();
  } catch (...) {
    impl_->remove_tmp();
    delete impl_;
    throw;
  }
}

VtkHdfWriter::VtkHdfWriter(const std::string& path, const VtkHdfCollective& c) : impl_(new Impl) {
  std::lock_guard lock(hdf5_lock());
  Impl& m = *impl_;
  m.path = path;
  m.partitions = c.size;
  m.par_copy = c;
  m.par = &m.par_copy;
  try {
    // Rank 0 owns the temporary; every rank opens the same one.
    std::exception_ptr e;
    std::string tmp;
    if (c.rank == 0) try {
        if (!std::filesystem::path(path).has_filename()) throw Error(ErrorKind::Usage, path + ": not a file name");
        m.out = std::make_unique<AtomicOutput>(path);
        tmp = m.out->temp_path();
      } catch (...) {
        e = std::current_exception();
      }
    c.checkpoint(e);
    m.tmp = c.broadcast(tmp);
    e = nullptr;
    try {
      m.open();
    } catch (...) {
      e = std::current_exception();
    }
    c.checkpoint(e);
  } catch (...) {
    m.remove_tmp();
    delete impl_;
    throw;
  }
}

VtkHdfWriter::~VtkHdfWriter() {
  std::lock_guard lock(hdf5_lock());
  if (!impl_->finished) impl_->remove_tmp();
  delete impl_;
}

void VtkHdfWriter::write_partition(const ExportChunk& chunk) {
  std::lock_guard lock(hdf5_lock());
  Impl& m = *impl_;
  if (m.finished) throw Error(ErrorKind::Usage, m.path + ": write_partition after finish");
  if (m.broken) throw Error(ErrorKind::Usage, m.path + ": write_partition after a failed write");
  if (m.written >= m.partitions)
    throw Error(ErrorKind::Usage,
                m.path + ": partition " + std::to_string(m.written + 1) + " of " + std::to_string(m.partitions) +
                    " declared");
  if (m.par) {  // every rank its one partition, collectively
    std::exception_ptr e;
    try {
      m.validate(chunk);
    } catch (...) {
      e = std::current_exception();
    }
    m.par->checkpoint(e);
    e = nullptr;
    try {
      m.write(chunk);
    } catch (...) {
      m.broken = true;
      e = std::current_exception();
    }
    m.par->checkpoint(e);
    m.written = m.partitions;
    return;
  }
  m.validate(chunk);  // a Usage error here leaves the file intact
  try {
    m.write(chunk);
  } catch (...) {
    m.broken = true;
    throw;
  }
  ++m.written;
}

void VtkHdfWriter::finish() {
  std::lock_guard lock(hdf5_lock());
  Impl& m = *impl_;
  if (m.finished) throw Error(ErrorKind::Usage, m.path + ": finish called twice");
  if (m.broken) throw Error(ErrorKind::Io, m.path + ": an earlier write failed; the file is incomplete");
  if (m.written != m.partitions)
    throw Error(ErrorKind::Usage, m.path + ": " + std::to_string(m.written) + " of " + std::to_string(m.partitions) +
                                      " partitions written");
  std::exception_ptr e;
  try {
    if (H5Fflush(m.file.get(), H5F_SCOPE_GLOBAL) < 0) m.io("flush failed");
    m.close_all();
    if (!m.file.reset() || m.write_errno) m.io("closing " + m.tmp + " failed");
  } catch (...) {
    m.broken = true;
    e = std::current_exception();
  }
  if (m.par) m.par->checkpoint(e);
  else if (e) std::rethrow_exception(e);
  try {
    if (m.out) m.out->commit();  // rank 0's (or the single process's) temporary
  } catch (...) {
    m.broken = true;
    e = std::current_exception();
  }
  if (m.par) m.par->checkpoint(e);
  else if (e) std::rethrow_exception(e);
  m.finished = true;
}

}  // namespace dicer
