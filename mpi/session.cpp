// MPI session and error agreement (include/dicer/mpi.hpp).
#include <cstdlib>

#include "dicer/mpi.hpp"

namespace dicer::mpi {

bool launched_by_mpirun() {
  // Open MPI's mpirun, and PMIx/PMI launchers (srun, prterun).
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK"})
    if (std::getenv(v) != nullptr) return true;
  return false;
}

int launched_rank() {
  for (const char* v : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"})
    if (const char* r = std::getenv(v); r != nullptr && *r != '\0') return std::atoi(r);
  return 0;
}

Session::Session(int& argc, char**& argv) {
  if (!launched_by_mpirun()) return;
  int provided = 0;
  // Only the main thread calls MPI; the page cache's worker reads files.
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  // Errors come back as return codes (and become dicer::Error), never as
  // MPI's default abort.
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  active_ = true;
}

Session::~Session() {
  if (active_) MPI_Finalize();
}

namespace {
thread_local bool g_agreed = false;

int kind_of(std::exception_ptr e) {
  try {
    std::rethrow_exception(e);
  } catch (const Error& x) {
    return static_cast<int>(x.kind());
  } catch (const PeerFailed& x) {
    return static_cast<int>(x.kind());
  } catch (...) {
    return -1;  // not a dicer::Error: internal
  }
}
}  // namespace

namespace {
int (*g_signal_probe)() = nullptr;
}  // namespace

void checkpoint(MPI_Comm comm, std::exception_ptr local) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const int mine = local ? rank : size;
  int lowest = size;
  MPI_Allreduce(&mine, &lowest, 1, MPI_INT, MPI_MIN, comm);
  if (lowest == size) return;
  int sent[2] = {rank == lowest ? kind_of(local) : 0, rank == lowest && g_signal_probe ? g_signal_probe() : 0};
  MPI_Bcast(sent, 2, MPI_INT, lowest, comm);
  g_agreed = true;
  if (rank == lowest) std::rethrow_exception(local);
  throw PeerFailed(static_cast<ErrorKind>(sent[0]), lowest, sent[1]);
}

void set_signal_probe(int (*probe)()) { g_signal_probe = probe; }

bool error_was_agreed() { return g_agreed; }

}  // namespace dicer::mpi
