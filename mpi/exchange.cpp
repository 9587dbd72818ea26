// Who uses which node run, across ranks: two all-to-all rounds.
#include <algorithm>
#include <limits>
#include <map>
#include <optional>

#include "all_to_all.hpp"
#include "dicer/mpi.hpp"

namespace dicer::mpi {
using detail::all_to_all;

std::vector<NodeRun> exchange_sharing(MPI_Comm comm, const FineMesh& mesh, const std::vector<ChunkRange>& plan) {
  int rank = 0, P = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &P);
  if (static_cast<int>(plan.size()) != P)
    throw Error(ErrorKind::Usage, "exchange_sharing: a plan of " + std::to_string(plan.size()) + " chunks for " +
                                      std::to_string(P) + " ranks");
  std::vector<NodeRun> ghosts;
  collectively(comm, [&] { ghosts = ghost_runs(mesh, plan, rank); });

  // Round 1: tell each owner which of its runs this rank uses.
  std::vector<std::vector<std::int64_t>> to_owner(static_cast<size_t>(P));
  for (const NodeRun& r : ghosts) to_owner[r.owner].insert(to_owner[r.owner].end(), {r.first, r.count});
  const auto users_of_mine = all_to_all(comm, to_owner);
  std::map<Id, NodeRun> owned;  // my runs that others use, with all users
  for (int q = 0; q < P; ++q)
    for (size_t i = 0; i + 1 < users_of_mine[q].size(); i += 2) {
      auto [it, fresh] = owned.try_emplace(users_of_mine[q][i], NodeRun{users_of_mine[q][i], users_of_mine[q][i + 1], rank, {rank}});
      auto& u = it->second.users;
      u.insert(std::upper_bound(u.begin(), u.end(), q), q);
    }
  // Round 2: every user of a run learns all its users.
  std::vector<std::vector<std::int64_t>> back(static_cast<size_t>(P));
  for (const auto& [first, run] : owned)
    for (std::int32_t u : run.users) {
      if (u == rank) continue;
      auto& m = back[u];
      m.insert(m.end(), {run.first, run.count, static_cast<std::int64_t>(run.users.size())});
      m.insert(m.end(), run.users.begin(), run.users.end());
    }
  const auto told = all_to_all(comm, back);
  std::vector<NodeRun> out;
  for (const auto& [first, run] : owned) out.push_back(run);
  for (int q = 0; q < P; ++q) {
    const auto& m = told[q];
    for (size_t i = 0; i + 3 <= m.size();) {
      NodeRun r{m[i], m[i + 1], static_cast<std::int32_t>(q), {}};
      const auto n = static_cast<size_t>(m[i + 2]);
      if (i + 3 + n > m.size()) throw Error(ErrorKind::Io, "exchange_sharing: a truncated message from rank " + std::to_string(q));
      for (size_t k = 0; k < n; ++k) r.users.push_back(static_cast<std::int32_t>(m[i + 3 + k]));
      out.push_back(std::move(r));
      i += 3 + n;
    }
  }
  std::sort(out.begin(), out.end(), [](const NodeRun& a, const NodeRun& b) { return a.first < b.first; });
  return out;
}

Partition make_partition(const FineMesh& mesh, MPI_Comm comm, const MeshSets& sets, std::vector<ChunkRange> plan) {
  int rank = 0, P = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &P);
  collectively(comm, [&] {
    if (plan.empty()) plan = plan_chunks(mesh, P);
    if (static_cast<int>(plan.size()) != P)
      throw Error(ErrorKind::Usage, "make_partition: a plan of " + std::to_string(plan.size()) + " chunks for " +
                                        std::to_string(P) + " ranks");
  });
  std::vector<NodeRun> sharing = exchange_sharing(comm, mesh, plan);
  std::optional<Partition> p;
  collectively(comm, [&] { p.emplace(mesh, plan, rank, std::move(sharing), sets); });
  return std::move(*p);
}

}  // namespace dicer::mpi

namespace dicer::mpi {

std::vector<std::string> allgather_bytes(MPI_Comm comm, const std::string& mine) {
  int P = 1;
  MPI_Comm_size(comm, &P);
  const std::int64_t size = static_cast<std::int64_t>(mine.size());
  std::vector<std::int64_t> sizes(static_cast<size_t>(P));
  if (MPI_Allgather(&size, 1, MPI_INT64_T, sizes.data(), 1, MPI_INT64_T, comm) != MPI_SUCCESS)
    throw Error(ErrorKind::Io, "MPI_Allgather failed");
  std::vector<int> counts(static_cast<size_t>(P)), displs(static_cast<size_t>(P));
  std::int64_t total = 0;
  for (int q = 0; q < P; ++q) {
    if (sizes[q] > std::numeric_limits<int>::max() || total > std::numeric_limits<int>::max() - sizes[q])
      throw Error(ErrorKind::Overflow, "rank " + std::to_string(q) + " has " + std::to_string(sizes[q]) +
                                           " bytes to share with every rank: over MPI's 2 GiB limit for one exchange");
    counts[q] = static_cast<int>(sizes[q]), displs[q] = static_cast<int>(total), total += sizes[q];
  }
  std::string all(static_cast<size_t>(total), '\0');
  if (MPI_Allgatherv(mine.data(), static_cast<int>(size), MPI_BYTE, all.data(), counts.data(),
                     displs.data(), MPI_BYTE, comm) != MPI_SUCCESS)
    throw Error(ErrorKind::Io, "MPI_Allgatherv failed");
  std::vector<std::string> out(static_cast<size_t>(P));
  for (int q = 0; q < P; ++q) out[q] = all.substr(static_cast<size_t>(displs[q]), static_cast<size_t>(counts[q]));
  return out;
}

void require_same(MPI_Comm comm, const std::string& mine, ErrorKind kind,
                  const std::function<std::string(int rank, const std::string& rank0)>& message) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const std::vector<std::string> all = allgather_bytes(comm, mine);
  int q = -1;
  for (size_t r = 1; r < all.size() && q < 0; ++r)
    if (all[r] != all.front()) q = static_cast<int>(r);
  collectively(comm, [&] {
    if (rank == q) throw Error(kind, message(q, all.front()));
  });
}

void require_same_store(MPI_Comm comm, const std::string& path, const std::string& uuid) {
  require_same(comm, uuid, ErrorKind::BadInput, [&](int q, const std::string& first) {
    return path + ": rank " + std::to_string(q) + " read another store than rank 0 (uuid " + uuid + ", rank 0's " +
           first + "): every rank must read the same file (copies local to each node that differ?)";
  });
}

std::vector<std::string> gather_bytes(MPI_Comm comm, std::string mine, std::int64_t piece) {
  int rank = 0, P = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &P);
  if (piece < 1 || piece > std::numeric_limits<int>::max())
    throw Error(ErrorKind::Usage, "gather_bytes: a piece of " + std::to_string(piece) + " bytes");
  const std::int64_t size = static_cast<std::int64_t>(mine.size());
  std::vector<std::int64_t> sizes(static_cast<size_t>(P));
  if (MPI_Gather(&size, 1, MPI_INT64_T, sizes.data(), 1, MPI_INT64_T, 0, comm) != MPI_SUCCESS)
    throw Error(ErrorKind::Io, "MPI_Gather failed");
  std::vector<std::string> out;
  collectively(comm, [&] {
    if (rank != 0) return;
    out.resize(static_cast<size_t>(P));
    for (int q = 1; q < P; ++q) out[q].resize(static_cast<size_t>(sizes[q]));
    out[0] = std::move(mine);
  });
  constexpr int kTag = 7101;  // this exchange's messages, apart from any other point-to-point traffic
  auto pieces = [&](std::int64_t total, auto&& move) {
    for (std::int64_t at = 0; at < total; at += piece)
      if (move(at, static_cast<int>(std::min(piece, total - at))) != MPI_SUCCESS)
        throw Error(ErrorKind::Io, "gather_bytes: a point-to-point transfer failed");
  };
  if (rank == 0) {
    for (int q = 1; q < P; ++q)
      pieces(sizes[q], [&](std::int64_t at, int n) {
        return MPI_Recv(out[q].data() + at, n, MPI_BYTE, q, kTag, comm, MPI_STATUS_IGNORE);
      });
  } else {
    pieces(size, [&](std::int64_t at, int n) { return MPI_Send(mine.data() + at, n, MPI_BYTE, 0, kTag, comm); });
  }
  return out;
}

}  // namespace dicer::mpi
