// One VTKHDF file from every rank, through parallel HDF5 (MPI-IO): the
// export layer's writer in its collective mode, fed MPI here.
#include <hdf5.h>

#include "dicer/mpi.hpp"
#include "hdf5_lock.hpp"

namespace dicer::mpi {

void write_vtkhdf_collective(MPI_Comm comm, const ChunkSource& chunk, const std::string& path, int deflate) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  hid_t fapl = -1, dxpl = -1;
  {
    std::lock_guard lock(hdf5_lock());
    fapl = H5Pcreate(H5P_FILE_ACCESS);
    dxpl = H5Pcreate(H5P_DATASET_XFER);
    // Collective I/O: parallel HDF5 writes deflated chunks only collectively.
    if (fapl < 0 || dxpl < 0 || H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL) < 0 ||
        H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE) < 0) {
      if (fapl >= 0) H5Pclose(fapl);
      if (dxpl >= 0) H5Pclose(dxpl);
      throw Error(ErrorKind::Io, path + ": cannot set up MPI-IO for HDF5");
    }
  }
  struct Close {
    hid_t a, b;
    ~Close() {
      std::lock_guard lock(hdf5_lock());
      H5Pclose(a), H5Pclose(b);
    }
  } close{fapl, dxpl};
  VtkHdfCollective c;
  c.rank = rank, c.size = size, c.file_access = fapl, c.transfer = dxpl;
  c.allgather = [comm, size](std::int64_t v) {
    std::vector<std::int64_t> out(static_cast<size_t>(size));
    if (MPI_Allgather(&v, 1, MPI_INT64_T, out.data(), 1, MPI_INT64_T, comm) != MPI_SUCCESS)
      throw Error(ErrorKind::Io, "MPI_Allgather failed");
    return out;
  };
  c.broadcast = [comm](const std::string& s) {
    int n = static_cast<int>(s.size());
    MPI_Bcast(&n, 1, MPI_INT, 0, comm);
    std::string r = s;
    r.resize(static_cast<size_t>(n));
    MPI_Bcast(r.data(), n, MPI_CHAR, 0, comm);
    return r;
  };
  c.checkpoint = [comm](std::exception_ptr e) { checkpoint(comm, e); };
  VtkHdfWriter w(path, c, deflate);
  w.write_partition(chunk);
  w.finish();
}

}  // namespace dicer::mpi
