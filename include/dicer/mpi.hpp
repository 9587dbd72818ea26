#pragma once
// The MPI layer: what dicer's commands and a solver need to run the same
// library on P ranks. Thin by design: rank r works on chunk r of
// plan_chunks(mesh, P) (partition.hpp), and MPI only exchanges what the
// ranks cannot compute alone (who uses a shared node run) and agrees on
// errors. The single process stays complete without any of this.
//
// Errors: every collective operation here is entered by every rank; a rank
// whose local work failed still enters it (checkpoint), so no rank ever
// waits for one that died in an exception. After checkpoint, all ranks
// throw: the failing rank (the lowest, when several) its own Error, the
// others PeerFailed with its exit kind, so all end with the same code and
// only one prints a message.
#include <mpi.h>

#include <cstdint>
#include <exception>
#include <functional>
#include <string>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/partition.hpp"
#include "dicer/transfer.hpp"
#include "dicer/verify.hpp"

namespace dicer::mpi {

// True when this process was started by mpirun (Open MPI or a PMIx launcher
// set the environment): the CLI then initialises MPI. Without it, dicer
// never touches MPI.
bool launched_by_mpirun();
// This process's rank as the launcher's environment gives it, before MPI
// starts (0 without a launcher): for output made before MPI_Init, such as
// `dicer --help`, which one rank prints, not every one.
int launched_rank();

// MPI_Init_thread (funneled: only the calling thread talks MPI) and
// MPI_Finalize, when launched by mpirun; otherwise a one-rank session that
// calls nothing.
class Session {
 public:
  Session(int& argc, char**& argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  bool active() const { return active_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  MPI_Comm comm() const { return MPI_COMM_WORLD; }

 private:
  bool active_ = false;
  int rank_ = 0, size_ = 1;
};

// Another rank failed; `failed_rank` reported the error.
class PeerFailed : public std::runtime_error {
 public:
  PeerFailed(ErrorKind kind, int failed_rank, int signal = 0)
      : std::runtime_error("rank " + std::to_string(failed_rank) + " failed"), kind_(kind), rank_(failed_rank),
        signal_(signal) {}
  ErrorKind kind() const { return kind_; }
  int failed_rank() const { return rank_; }
  // The signal the failed rank received (set_signal_probe), 0 if none: a
  // Cancelled rank's peers end with its exit code, 128 + that signal.
  int signal() const { return signal_; }

 private:
  ErrorKind kind_;
  int rank_;
  int signal_;
};

// Where checkpoint reads the signal a failing rank received, to send it
// with the error's kind (the command's signal handler records it). Unset:
// none is sent.
void set_signal_probe(int (*probe)());

// Collective: every rank passes what its local work threw (nullptr when it
// succeeded). If any rank failed, every rank throws as described above.
// Non-dicer exceptions count as internal errors (kind 0 is sent as -1).
void checkpoint(MPI_Comm comm, std::exception_ptr local);

// Whether the error this thread is handling came out of checkpoint (so
// every rank knows of it and none waits): the CLI may then simply return;
// otherwise it must end the job (MPI_Abort).
bool error_was_agreed();

// Runs fn on this rank, then checkpoints.
template <class Fn>
void collectively(MPI_Comm comm, Fn&& fn) {
  std::exception_ptr e;
  try {
    fn();
  } catch (...) {
    e = std::current_exception();
  }
  checkpoint(comm, e);
}

// Every rank's bytes, in rank order, on every rank (MPI_Allgatherv). Each
// rank's part must stay under 2 GiB (MPI's int counts): a larger one is
// Error{Overflow} on every rank, after the sizes are exchanged (no rank is
// left waiting). Collective; what ConformOptions::share needs.
std::vector<std::string> allgather_bytes(MPI_Comm comm, const std::string& mine);

// Every rank must hold the same `mine` (its command line, a fingerprint of
// what it read): the lowest rank whose value differs from rank 0's throws
// Error{kind} with message(that rank, rank 0's value), the others
// PeerFailed. Collective (allgather_bytes).
void require_same(MPI_Comm comm, const std::string& mine, ErrorKind kind,
                  const std::function<std::string(int rank, const std::string& rank0)>& message);

// Every rank must have read the same store (`uuid`, FineMesh::info().uuid):
// node-local copies under one name that differ gave wrong answers. The
// first rank whose uuid differs from rank 0's throws Error{BadInput} naming
// `path` and both uuids, the others PeerFailed (checkpoint). Collective:
// call it where every rank holds its store (after an agreed read).
void require_same_store(MPI_Comm comm, const std::string& path, const std::string& uuid);

// Every rank's bytes, in rank order, on rank 0 (empty elsewhere): parts of
// any size, sent point to point in pieces of at most `piece` bytes (MPI's
// counts are int; rank 0's total passes 2 GiB where verify's parts of a
// mesh near 10^7 coarse hexes meet). Rank 0 sizes its buffers before any
// piece travels, collectively: a failed allocation there is every rank's
// Error, not a sender blocked forever. Collective.
std::vector<std::string> gather_bytes(MPI_Comm comm, std::string mine, std::int64_t piece = std::int64_t{1} << 30);

// The sharing runs of this rank's chunk (partition.hpp), exchanged with the
// owners of its ghost runs: two all-to-all rounds, messages proportional to
// the chunk's boundary. Equals in_process_sharing(mesh, plan)[rank].
std::vector<NodeRun> exchange_sharing(MPI_Comm comm, const FineMesh& mesh, const std::vector<ChunkRange>& plan);

// The partition of this rank (chunk `rank` of `size`), maps exchanged.
// `plan`: plan_chunks(mesh, size) when empty; plan_like(mesh, other_plan)
// gives the coarse level of nested dicings the fine level's chunks.
Partition make_partition(const FineMesh& mesh, MPI_Comm comm, const MeshSets& sets = {},
                         std::vector<ChunkRange> plan = {});

// The prolongation over ranks (transfer.hpp). Rank r holds chunk r of
// plan_chunks(p.fine(), size) (make_partition's chunk of the fine level):
// the fine nodes its coarse elements own (y_owned, p.owned_rows of the
// chunk: the fine Partition's owned nodes) and the coarse-store nodes they
// own (x_owned, p.owned_cols: the owned nodes of the coarse level's
// partition with plan_like). Collective; the results equal the single
// process's bit for bit.
// y_owned = this rank's rows of P x: the ghost columns (p.ghost_cols) are
// fetched from their owners first (one all-to-all round trip).
void prolong(MPI_Comm comm, const Prolongation& p, std::span<const double> x_owned, std::span<double> y_owned);
// x_owned = this rank's part of P^T y: each rank's shares for columns lower
// ranks own go to them (one all-to-all) and are added there in rank order.
void restrict_to(MPI_Comm comm, const Prolongation& p, std::span<const double> y_owned, std::span<double> x_owned);

// verify on every rank's chunk (verify_part), merged and finished on rank 0
// (verify_finish): every fine element checked once, faces and edges matched
// across ranks (shared nodes bit-identical). The full report on rank 0; the
// other ranks get an empty one (use ok() of rank 0, e.g. broadcast).
VerifyReport verify_distributed(MPI_Comm comm, const FineMesh& mesh, const std::function<void(Id, Id)>& progress = {});

// One VTKHDF file with one partition per rank, written collectively through
// parallel HDF5 (MPI-IO): the same datasets and values as VtkHdfWriter
// writing the chunks one after another in one process. Rank 0 owns the
// temporary (AtomicOutput) and renames it when every rank has written.
// `deflate` as for VtkHdfWriter. A failure on one rank during the chunk's
// passes reaches every rank at its next slice (no rank is left waiting).
void write_vtkhdf_collective(MPI_Comm comm, const ChunkSource& chunk, const std::string& path, int deflate = 0);

}  // namespace dicer::mpi
