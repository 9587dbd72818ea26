// VTKHDF UnstructuredGrid 1.0 writer: one partition per chunk (ChunkSource),
// appended to extendible, chunked datasets. A partition's rows are known
// up front, so each dataset is extended once per partition and filled by
// hyperslab writes of kSliceRows rows as the chunk's node and element
// passes produce them: memory is one slice per dataset plus HDF5's chunk
// caches, whatever the partition's size.
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
// Filters: none by default; with a deflate level, byte shuffle + deflate,
// both built into HDF5, so ParaView needs no plugin either way.
//
// Collective mode: every rank makes the same sequence of collective writes
// (slices it lacks are empty writes), and before each slice of a pass the
// ranks agree that none has failed (VtkHdfCollective::checkpoint): a rank
// whose pass throws (a corrupt page, a cancel) tells the others at their
// next slice, and all throw, instead of leaving them in a collective write.
// A failure inside one of HDF5's own collective calls cannot be agreed on
// that way: a rank whose write fails returns while the others wait in the
// call's barrier (a full disk hung a 3-rank export in H5Fflush). So before
// the first row, rank 0 reserves the file's blocks (fallocate, an upper
// bound of the file's size) and a full disk or quota is one agreed error;
// after the close the blocks past the end are given back. Every rank checks
// its file size limit (ulimit -f) against the same bound.
#include <fcntl.h>
#include <hdf5.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

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
constexpr hsize_t kChunkBytes = 512 * 1024;  // HDF5 chunk: below the default 1 MiB chunk cache (deflate)
constexpr hsize_t kSliceRows = 64 * 1024;    // rows converted and written per H5Dwrite

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
  int deflate = 0;
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
  bool agreed = false;  // collective: the ranks have agreed on a failure (every one throws it)
  bool created = false;  // the datasets (create_datasets)
  Hid point_data, cell_data;

  [[noreturn]] void io(const std::string& what) const {
    const std::string reason = write_errno ? std::strerror(write_errno) : h5::error_reason();
    throw Error(ErrorKind::Io, path + ": " + what + (reason.empty() ? "" : ": " + reason));
  }

  // No object times (h5::untimed_file_creation).
  Hid group(hid_t parent, const char* name) {
    Hid gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
    if (!gcpl || H5Pset_obj_track_times(gcpl.get(), false) < 0) io(std::string("cannot set up group ") + name);
    Hid g(H5Gcreate2(parent, name, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
    if (!g) io(std::string("cannot create group ") + name);
    return g;
  }

  template <class T>
  void create(Dataset& d, hid_t parent, const char* name, hsize_t width, hsize_t rows_hint) {
    d.name = name;
    d.width = width;
    const int rank = width > 1 ? 2 : 1;
    // kChunkBytes, or less for a small first partition (an uncompressed
    // chunk is stored whole: a tiny mesh would otherwise take MiBs).
    const hsize_t chunk_rows = std::clamp<hsize_t>(rows_hint, 1, std::max<hsize_t>(1, kChunkBytes / (width * sizeof(T))));
    hsize_t dims[2] = {0, width}, maxdims[2] = {H5S_UNLIMITED, width}, chunk[2] = {chunk_rows, width};
    Hid space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
    Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    // Every row is written, so HDF5 need not fill new chunks first.
    if (!space || !dcpl || H5Pset_chunk(dcpl.get(), rank, chunk) < 0 ||
        H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER) < 0 || H5Pset_obj_track_times(dcpl.get(), false) < 0)
      io(d.name + ": cannot set up dataset");
    if (deflate > 0 && (H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0 || H5Pset_shuffle(dcpl.get()) < 0 ||
                        H5Pset_deflate(dcpl.get(), static_cast<unsigned>(deflate)) < 0))
      io(d.name + ": cannot set up shuffle + deflate");
    // Uncompressed: no chunk cache. Rows go straight to the file, and a
    // failed write (a full disk) leaves no dirty chunk behind that HDF5
    // 1.10 could neither flush nor free (LeakSanitizer saw 512 KiB lost in
    // FileFaults.DiskFull*). Deflate needs the cache to compress whole chunks.
    Hid dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
    if (!dapl || (deflate == 0 && H5Pset_chunk_cache(dapl.get(), 0, 0, 1.0) < 0)) io(d.name + ": cannot set up dataset");
    d.id = Hid(H5Dcreate2(parent, name, file_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), dapl.get()), H5Dclose);
    if (!d.id) io(d.name + ": cannot create dataset");
  }

  // The rows a partition fills in one dataset: [at, at + rows); `slices`:
  // the number of slice writes to make (collectively, the most any rank
  // needs, so that every rank makes as many).
  struct Region {
    Dataset* d;
    hsize_t at, rows, slices;
  };

  // Extends d by this partition's rows; collectively by every rank's, this
  // rank's after those of the ranks before it.
  Region reserve(Dataset& d, hsize_t rows, hsize_t slice_rows) {
    hsize_t at = d.rows, total = d.rows + rows, slices = (rows + slice_rows - 1) / slice_rows;
    if (par) {
      const auto all = par->allgather(static_cast<std::int64_t>(rows));
      hsize_t before = 0, sum = 0, most = 0;
      for (int r = 0; r < par->size; ++r) {
        if (r < par->rank) before += static_cast<hsize_t>(all[r]);
        sum += static_cast<hsize_t>(all[r]);
        most = std::max<hsize_t>(most, (static_cast<hsize_t>(all[r]) + slice_rows - 1) / slice_rows);
      }
      at = d.rows + before, total = d.rows + sum, slices = most;
    }
    if (total > d.rows) {
      hsize_t new_dims[2] = {total, d.width};
      if (H5Dset_extent(d.id.get(), new_dims) < 0) io(d.name + ": cannot extend dataset");
    }
    d.rows = total;
    return {&d, at, rows, slices};
  }

  // Writes rows [first, first + n) of the region from buf (n * width
  // values); n = 0 is an empty write (collective mode: a rank with fewer
  // slices than the others).
  template <class T>
  void put(const Region& r, hsize_t first, hsize_t n, const T* buf) {
    const Dataset& d = *r.d;
    const int rank = d.width > 1 ? 2 : 1;
    Hid fspace(H5Dget_space(d.id.get()), H5Sclose);
    if (!fspace) io(d.name + ": cannot get dataspace");
    hsize_t start[2] = {r.at + first, 0}, count[2] = {n, d.width};
    Hid mspace(H5Screate_simple(rank, count, nullptr), H5Sclose);
    const bool selected = n > 0 ? H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) >= 0
                                : H5Sselect_none(fspace.get()) >= 0 && H5Sselect_none(mspace.get()) >= 0;
    const hid_t dxpl = par ? static_cast<hid_t>(par->transfer) : H5P_DEFAULT;
    const T dummy{};
    if (!mspace || !selected || H5Dwrite(d.id.get(), mem_type<T>(), mspace.get(), fspace.get(), dxpl, n ? buf : &dummy) < 0)
      io(d.name + ": writing rows " + std::to_string(r.at + first) + ".." + std::to_string(r.at + first + n) + " failed");
  }

  // Appends `rows` rows computed without a pass; fill(first, n, out)
  // writes rows [first, first + n) (n * width values) into out.
  template <class T, class Fill>
  void append(Dataset& d, hsize_t rows, Fill&& fill) {
    const Region r = reserve(d, rows, kSliceRows);
    std::vector<T> buf(static_cast<size_t>(std::max<hsize_t>(1, std::min(rows, kSliceRows)) * d.width));
    for (hsize_t s = 0; s < r.slices; ++s) {
      const hsize_t first = s * kSliceRows, n = first < rows ? std::min(kSliceRows, rows - first) : 0;
      if (n > 0) fill(static_cast<Id>(first), static_cast<Id>(n), buf.data());
      put(r, first, n, buf.data());
    }
  }

  // One pass of the chunk feeding slices: `pass(emit)` runs the pass
  // without the HDF5 lock, calling emit() whenever its buffers hold a
  // slice; `flush(first)` writes the buffered slice at row `first` (locked)
  // and returns its rows. Collectively, a checkpoint comes before every
  // slice and ranks with fewer slices write empty ones.
  template <class Pass, class Flush>
  hsize_t stream(std::unique_lock<std::recursive_mutex>& lock, hsize_t slices, Pass&& pass, Flush&& flush) {
    hsize_t done = 0, made = 0;
    auto emit = [&] {
      if (par) try {
          par->checkpoint(nullptr);
        } catch (...) {
          agreed = true;
          throw;
        }
      std::lock_guard call(hdf5_lock());
      done += flush(done);
      ++made;
    };
    try {
      lock.unlock();
      struct Relock {
        std::unique_lock<std::recursive_mutex>& l;
        ~Relock() { l.lock(); }
      } relock{lock};
      pass(emit);
    } catch (...) {
      if (par && !agreed) {
        agreed = true;
        par->checkpoint(std::current_exception());  // throws on every rank
      }
      throw;
    }
    while (par && made < slices) emit();
    return done;
  }

  void open() {
    h5::quiet();  // this thread's switch (hdf5_file.hpp)
    // One process: dicer's driver (a full disk fails the write, yet the
    // file still closes). Several ranks write one file through MPI-IO.
    const Hid fcpl = h5::untimed_file_creation();  // group()
    if (!fcpl) io("cannot set up " + tmp);
    file = par ? Hid(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl.get(), static_cast<hid_t>(par->file_access)), H5Fclose)
               : Hid(h5::create_file_id(tmp, &write_errno, fcpl.get()), H5Fclose);
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
    point_data = group(root.get(), "PointData"), cell_data = group(root.get(), "CellData");
  }

  // The datasets, at the first partition: chunks sized for it (collectively
  // for the largest rank's, the same on every rank).
  void create_datasets(const ChunkSource& c) {
    std::int64_t nodes = c.num_nodes(), cells = c.num_elements(), all_nodes = nodes, all_cells = cells;
    if (par) {
      all_nodes = all_cells = 0;
      for (std::int64_t v : par->allgather(nodes)) nodes = std::max(nodes, v), all_nodes += v;
      for (std::int64_t v : par->allgather(cells)) cells = std::max(cells, v), all_cells += v;
    }
    const auto nn = static_cast<hsize_t>(nodes), ne = static_cast<hsize_t>(cells);
    const auto corners = static_cast<hsize_t>(c.corners()), parts = static_cast<hsize_t>(partitions);
    create<std::int64_t>(number_of_points, root.get(), "NumberOfPoints", 1, parts);
    create<std::int64_t>(number_of_cells, root.get(), "NumberOfCells", 1, parts);
    create<std::int64_t>(number_of_connectivity_ids, root.get(), "NumberOfConnectivityIds", 1, parts);
    create<double>(points, root.get(), "Points", 3, nn);
    create<std::uint8_t>(types, root.get(), "Types", 1, ne);
    create<std::int64_t>(connectivity, root.get(), "Connectivity", 1, ne * corners);
    create<std::int64_t>(offsets, root.get(), "Offsets", 1, ne + 1);
    create<std::int64_t>(global_node_id, point_data.get(), "GlobalNodeId", 1, nn);
    create<std::int64_t>(global_element_id, cell_data.get(), "GlobalElementId", 1, ne);
    create<std::int64_t>(block_id, cell_data.get(), "BlockId", 1, ne);
    created = true;
    if (par) {
      std::exception_ptr e;
      try {
        const std::uint64_t bytes = file_bound(all_nodes, all_cells, c.corners());
        check_file_size_limit(bytes);  // every rank: each writes its own rows wherever they fall
        if (par->rank == 0) reserve_space(bytes);
      } catch (...) {
        e = std::current_exception();
      }
      try {
        par->checkpoint(e);
      } catch (...) {
        agreed = true;
        throw;
      }
    }
  }

  // The file's size, at most (see the top of this file): the datasets'
  // bytes (uncompressed; deflate only shrinks them, but for a few bytes a
  // block), a part-filled chunk per dataset (no larger than the dataset),
  // and for metadata 1% + 256 KiB + 2 KiB a partition (chunk indexes).
  std::uint64_t file_bound(std::int64_t nodes, std::int64_t cells, int corners) const {
    const auto n = static_cast<std::uint64_t>(nodes), e = static_cast<std::uint64_t>(cells);
    const auto parts = static_cast<std::uint64_t>(partitions);
    const std::uint64_t data = n * (3 * 8 + 8) + e * (1 + 8 * static_cast<std::uint64_t>(corners) + 8 + 8 + 8) +
                               (parts + 3 * parts) * 8;
    return data + data / 100 + std::min<std::uint64_t>(data, 10 * kChunkBytes) + (256 << 10) + parts * (2 << 10);
  }
  static std::string mib(std::uint64_t bytes) { return std::to_string((bytes + (1 << 20) - 1) >> 20) + " MiB"; }

  // A rank whose file size limit (ulimit -f) the file could pass would fail
  // a write inside a collective HDF5 call, where the others would wait.
  void check_file_size_limit(std::uint64_t bytes) const {
    struct rlimit rl {};
    if (::getrlimit(RLIMIT_FSIZE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < bytes)
      throw Error(ErrorKind::Io, path + ": the file may grow to " + mib(bytes) + " (its uncompressed size and a margin), "
                                 "past this process's file size limit of " + std::to_string(rl.rlim_cur) +
                                 " bytes (ulimit -f)");
  }

  // Rank 0 reserves the file's blocks. A file system without fallocate (NFS
  // v3) is written without a reserve.
  void reserve_space(std::uint64_t bytes) const {
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0) throw Error(ErrorKind::Io, path + ": cannot open " + tmp + ": " + std::strerror(errno));
    int rc;
    while ((rc = ::fallocate(fd, FALLOC_FL_KEEP_SIZE, 0, static_cast<off_t>(bytes))) != 0 && errno == EINTR) {
    }
    const int err = rc == 0 ? 0 : errno;
    ::close(fd);
    if (err != 0 && err != EOPNOTSUPP && err != ENOSYS)
      throw Error(ErrorKind::Io, path + ": cannot reserve " + mib(bytes) +
                                     " for the export (its uncompressed size and a margin): " + std::strerror(err));
  }

  // Gives back the reserved blocks past the end of the closed file.
  void release_reserve() const {
    struct stat st {};
    if (::stat(tmp.c_str(), &st) == 0 && ::truncate(tmp.c_str(), st.st_size) != 0)
      throw Error(ErrorKind::Io, path + ": cannot truncate " + tmp + ": " + std::strerror(errno));
  }

  void close_all() {
    for (Dataset* d : {&number_of_points, &number_of_cells, &number_of_connectivity_ids, &points, &types,
                       &connectivity, &offsets, &global_node_id, &global_element_id, &block_id})
      d->id.reset();
    point_data.reset(), cell_data.reset();
    root.reset();
  }

  void remove_tmp() {
    close_all();
    file.reset();
    out.reset();  // removes the uncommitted temporary
  }

  // What can be checked before any dataset grows.
  void validate(const ChunkSource& c) {
    const int corners = c.corners();
    const std::string part = "partition " + std::to_string(par ? par->rank : written);
    if ((c.mode() == Mode::Volume && corners != 8) || (c.mode() == Mode::Surface && corners != 4))
      throw Error(ErrorKind::Usage, path + ": " + part + ": " + std::to_string(corners) + " corners per element");
    Id total = 0;
    for (Id n : c.block_counts()) total += n;  // ExportChunk: checks its block indices
    if (total != c.num_elements())
      throw Error(ErrorKind::Usage, path + ": " + part + ": chunk is not prepared (element counts disagree)");
  }

  void write(const ChunkSource& c, std::unique_lock<std::recursive_mutex>& lock) {
    const Id nn = c.num_nodes(), ne = c.num_elements();
    const int corners = c.corners();
    const std::uint8_t cell_type = c.mode() == Mode::Volume ? kVtkHexahedron : kVtkQuad;
    const auto& blocks = c.mesh().info().blocks;
    const std::string part = "partition " + std::to_string(par ? par->rank : written);
    c.expect_passes(2);
    if (!created) create_datasets(c);
    auto one = [](std::int64_t v) { return [v](Id, Id, std::int64_t* out) { out[0] = v; }; };
    append<std::int64_t>(number_of_points, 1, one(nn));
    append<std::int64_t>(number_of_cells, 1, one(ne));
    append<std::int64_t>(number_of_connectivity_ids, 1, one(ne * corners));

    // Points and GlobalNodeId from the node pass.
    {
      const Region pts = reserve(points, static_cast<hsize_t>(nn), kSliceRows);
      const Region gid = reserve(global_node_id, static_cast<hsize_t>(nn), kSliceRows);
      std::vector<double> xyz(3 * kSliceRows);  // the first 3 * ids.size() are filled
      std::vector<std::int64_t> ids;
      ids.reserve(kSliceRows);
      const hsize_t done = stream(
          lock, pts.slices,
          [&](auto&& emit) {
            c.nodes({true, -1}, [&](const NodeSpan& span) {
              for (Id q = 0; q < span.count;) {  // whole slices at a time
                const Id n = std::min<Id>(span.count - q, static_cast<Id>(kSliceRows - ids.size()));
                const size_t at = 3 * ids.size();
                for (Id i = 0; i < n; ++i)
                  xyz[at + 3 * i] = span.x[q + i], xyz[at + 3 * i + 1] = span.y[q + i], xyz[at + 3 * i + 2] = span.z[q + i];
                ids.insert(ids.end(), span.global + q, span.global + q + n);
                q += n;
                if (ids.size() == kSliceRows) emit();
              }
            });
            if (!ids.empty()) emit();
          },
          [&](hsize_t first) {
            const hsize_t n = ids.size();
            if (first + n > pts.rows) throw Error(ErrorKind::Usage, path + ": " + part + ": more nodes than counted");
            put(pts, first, n, xyz.data()), put(gid, first, n, ids.data());
            ids.clear();
            return n;
          });
      if (done != static_cast<hsize_t>(nn)) throw Error(ErrorKind::Usage, path + ": " + part + ": fewer nodes than counted");
    }

    // Types, Connectivity, GlobalElementId and BlockId from the element pass.
    {
      const hsize_t slice = kSliceRows / 8;  // elements per slice
      const Region types_r = reserve(types, static_cast<hsize_t>(ne), slice);
      const Region conn_r = reserve(connectivity, static_cast<hsize_t>(ne * corners), slice * corners);
      const Region eid_r = reserve(global_element_id, static_cast<hsize_t>(ne), slice);
      const Region block_r = reserve(block_id, static_cast<hsize_t>(ne), slice);
      std::vector<std::uint8_t> type(slice, cell_type);
      std::vector<std::int64_t> conn, eid, bid;
      conn.reserve(slice * corners), eid.reserve(slice), bid.reserve(slice);
      const hsize_t done = stream(
          lock, types_r.slices,
          [&](auto&& emit) {
            c.elements({-1, false}, [&](const ElementSpan& span) {
              const std::int64_t block = blocks.at(static_cast<size_t>(span.block)).id;
              Id lo = nn, hi = -1;
              for (Id q = 0; q < span.count * corners; ++q)
                lo = std::min(lo, span.conn[q]), hi = std::max(hi, span.conn[q]);
              if (span.count > 0 && (lo < 0 || hi >= nn))
                throw Error(ErrorKind::Usage, path + ": " + part + ": local node id " + std::to_string(lo < 0 ? lo : hi) +
                                                  " out of range");
              for (Id e = 0; e < span.count;) {  // whole slices at a time
                const Id n = std::min<Id>(span.count - e, static_cast<Id>(slice - eid.size()));
                conn.insert(conn.end(), span.conn + e * corners, span.conn + (e + n) * corners);
                eid.insert(eid.end(), span.global + e, span.global + e + n);
                bid.insert(bid.end(), static_cast<size_t>(n), block);
                e += n;
                if (eid.size() == slice) emit();
              }
            });
            if (!eid.empty()) emit();
          },
          [&](hsize_t first) {
            const hsize_t n = eid.size();
            if (first + n > types_r.rows) throw Error(ErrorKind::Usage, path + ": " + part + ": more elements than counted");
            put(types_r, first, n, type.data()), put(conn_r, first * corners, n * corners, conn.data());
            put(eid_r, first, n, eid.data()), put(block_r, first, n, bid.data());
            conn.clear(), eid.clear(), bid.clear();
            return n;
          });
      if (done != static_cast<hsize_t>(ne))
        throw Error(ErrorKind::Usage, path + ": " + part + ": fewer elements than counted");
    }
    append<std::int64_t>(offsets, static_cast<hsize_t>(ne + 1), [&](Id first, Id n, std::int64_t* out) {
      for (Id i = 0; i < n; ++i) out[i] = (first + i) * corners;
    });
  }
};

VtkHdfWriter::VtkHdfWriter(const std::string& path, Id partitions, int deflate) : impl_(new Impl) {
  namespace fs = std::filesystem;
  std::lock_guard lock(hdf5_lock());
  impl_->path = path;
  impl_->partitions = partitions;
  impl_->deflate = deflate;
  try {
    if (deflate < 0 || deflate > 9)
      throw Error(ErrorKind::Usage, path + ": deflate level " + std::to_string(deflate) + " is not 0..9");
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

VtkHdfWriter::VtkHdfWriter(const std::string& path, const VtkHdfCollective& c, int deflate) : impl_(new Impl) {
  std::lock_guard lock(hdf5_lock());
  Impl& m = *impl_;
  m.path = path;
  m.partitions = c.size;
  m.deflate = std::clamp(deflate, 0, 9);
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

void VtkHdfWriter::write_partition(const ChunkSource& chunk) {
  // Held except while a pass generates the chunk (Impl::stream).
  std::unique_lock lock(hdf5_lock());
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
      m.write(chunk, lock);
    } catch (...) {
      m.broken = true;
      if (m.agreed) throw;  // every rank threw from the same checkpoint
      e = std::current_exception();
    }
    m.par->checkpoint(e);
    m.written = m.partitions;
    return;
  }
  m.validate(chunk);  // a Usage error here leaves the file intact
  try {
    m.write(chunk, lock);
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
    if (m.par && m.out) m.release_reserve();
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
