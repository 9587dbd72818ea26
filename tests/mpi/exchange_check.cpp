// The MPI exchange against the single process (run by ctest under
// mpirun -n P): on random perturbed boxes (the same seed on every rank) and
// on the stores named on the command line, every rank's
// exchange_sharing() equals in_process_sharing()[rank], and the shared
// node lists of make_partition() name the same global ids, in the same
// order, on both sides of every neighbour pair (checked by sending them);
// gather_bytes brings every rank's bytes to rank 0 whatever the piece size.
// Exit 0 when every rank agrees, 1 otherwise.
#include <mpi.h>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "dicer/mpi.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

int check(const FineMesh& mesh, const std::string& what, int rank, int size) {
  int bad = 0;
  const auto plan = plan_chunks(mesh, size);
  const auto exchanged = mpi::exchange_sharing(MPI_COMM_WORLD, mesh, plan);
  const auto expected = in_process_sharing(mesh, plan)[static_cast<std::size_t>(rank)];
  if (exchanged != expected) {
    std::fprintf(stderr, "%s rank %d: exchange_sharing gives %zu runs, in_process_sharing %zu\n", what.c_str(), rank,
                 exchanged.size(), expected.size());
    bad = 1;
  }
  const Partition p = mpi::make_partition(mesh, MPI_COMM_WORLD);
  const auto& nbr = p.neighbors();
  std::vector<std::vector<long long>> send(nbr.size()), recv(nbr.size());
  std::vector<int> recv_count(nbr.size());
  std::vector<MPI_Request> req;
  for (std::size_t k = 0; k < nbr.size(); ++k) {
    for (Id l : p.shared_nodes()[k]) send[k].push_back(p.node_global()[static_cast<std::size_t>(l)]);
    const int n = static_cast<int>(send[k].size());
    req.emplace_back(), MPI_Isend(&n, 1, MPI_INT, nbr[k], 1, MPI_COMM_WORLD, &req.back());
    req.emplace_back(), MPI_Irecv(&recv_count[k], 1, MPI_INT, nbr[k], 1, MPI_COMM_WORLD, &req.back());
    MPI_Waitall(2, &req[req.size() - 2], MPI_STATUSES_IGNORE);
    req.resize(req.size() - 2);
  }
  for (std::size_t k = 0; k < nbr.size(); ++k) {
    recv[k].resize(static_cast<std::size_t>(recv_count[k]));
    req.emplace_back(), MPI_Isend(send[k].data(), static_cast<int>(send[k].size()), MPI_LONG_LONG, nbr[k], 2, MPI_COMM_WORLD, &req.back());
    req.emplace_back(), MPI_Irecv(recv[k].data(), recv_count[k], MPI_LONG_LONG, nbr[k], 2, MPI_COMM_WORLD, &req.back());
  }
  MPI_Waitall(static_cast<int>(req.size()), req.data(), MPI_STATUSES_IGNORE);
  for (std::size_t k = 0; k < nbr.size(); ++k)
    if (send[k] != recv[k] || send[k].empty()) {
      std::fprintf(stderr, "%s rank %d: shared nodes with rank %d differ (%zu here, %zu there)\n", what.c_str(), rank,
                   nbr[k], send[k].size(), recv[k].size());
      bad = 1;
    }
  if (size > 1 && nbr.empty()) {
    std::fprintf(stderr, "%s rank %d: no neighbours in a connected mesh\n", what.c_str(), rank);
    bad = 1;
  }
  return bad;
}

// gather_bytes in pieces of 1 byte, 7 bytes and 1 GiB: rank q's part is
// 37q + 11 bytes of a pattern derived from q alone (rank 1's is empty in
// the first round), so rank 0 knows what each part must be.
int check_gather(int rank, int size) {
  int bad = 0;
  auto part = [](int q, int which) {
    std::string s(static_cast<size_t>(which == 0 && q == 1 ? 0 : 37 * q + 11), '\0');
    for (size_t i = 0; i < s.size(); ++i) s[i] = static_cast<char>((q * 131 + static_cast<int>(i) * 7) & 0xff);
    return s;
  };
  int which = 0;
  for (std::int64_t piece : {std::int64_t{1}, std::int64_t{7}, std::int64_t{1} << 30}) {
    const auto all = mpi::gather_bytes(MPI_COMM_WORLD, part(rank, which), piece);
    if (rank == 0) {
      for (int q = 0; q < size; ++q)
        if (static_cast<int>(all.size()) != size || all[static_cast<size_t>(q)] != part(q, which)) {
          std::fprintf(stderr, "gather_bytes (pieces of %lld): rank %d's part differs\n", static_cast<long long>(piece), q);
          bad = 1;
        }
    } else if (!all.empty()) {
      std::fprintf(stderr, "gather_bytes: rank %d got %zu parts, not none\n", rank, all.size());
      bad = 1;
    }
    ++which;
  }
  return bad;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1, bad = 0, checked = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  try {
    bad |= check_gather(rank, size);
    std::mt19937_64 rng(77);  // the same stream on every rank: the same meshes
    for (int trial = 0; trial < 4; ++trial) {
      test::BoxSpec spec;
      spec.a = 3 + trial, spec.b = 2 + trial % 2, spec.c = 2;
      IntervalRequest req;
      req.global = 2 + trial % 2;
      bad |= check(FineMesh::dice(test::random_box(spec, rng), req), "random box " + std::to_string(trial), rank, size);
      ++checked;
    }
    for (int a = 1; a < argc; ++a) bad |= check(read_store(argv[a]), argv[a], rank, size), ++checked;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exchange_check (rank %d): %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 3);
  }
  int any = 0;
  MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (rank == 0) std::printf("exchange_check: %d ranks, %d meshes, %s\n", size, checked, any ? "MISMATCH" : "agree");
  MPI_Finalize();
  return any;
}
