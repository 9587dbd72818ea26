// A distributed operator on a diced mesh, the way a solver uses dicer:
//
//   mpirun -n 4 build/examples/laplacian_mpi STORE
//
// Every rank gets its partition (include/dicer/partition.hpp, maps
// exchanged by include/dicer/mpi.hpp), applies a 7-point Laplacian
// assembled from its fine hexes (each of an element's 12 edges adds
// (x_i - x_j) / 4 to i and j: on a structured grid, 6 x_i minus the 6
// neighbours), then completes the nodes it shares by one ghost exchange
// over the communication maps (both sides list the shared nodes in the same
// order, so partial sums are added position by position). Rank 0 then
// compares the owned values of every rank with the same operator applied in
// one process over the whole mesh, and exits 1 beyond 1e-12 (relative).
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "dicer/mpi.hpp"
#include "dicer/orientation.hpp"
#include "dicer/store.hpp"

using namespace dicer;

namespace {

double input(Id global) { return std::sin(0.001 * static_cast<double>(global)) + 0.5 * std::cos(0.37 * static_cast<double>(global % 1009)); }

// y += the element edge Laplacian of x, for elements given by connectivity
// (8 node indices each) into arrays indexed the same way.
template <class Conn>
void apply_elements(const Conn& conn, std::size_t elements, const std::vector<double>& x, std::vector<double>& y) {
  for (std::size_t e = 0; e < elements; ++e)
    for (const auto& edge : kHexEdge) {
      const auto i = static_cast<std::size_t>(conn[8 * e + edge[0]]), j = static_cast<std::size_t>(conn[8 * e + edge[1]]);
      const double d = 0.25 * (x[i] - x[j]);
      y[i] += d, y[j] -= d;
    }
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  int status = 0;
  try {
    if (argc != 2) throw Error(ErrorKind::Usage, "usage: laplacian_mpi STORE");
    const FineMesh mesh = read_store(argv[1]);
    if (mesh.mode() != Mode::Volume) throw Error(ErrorKind::Usage, "laplacian_mpi: a volume (hex) store");
    const Partition p = mpi::make_partition(mesh, MPI_COMM_WORLD);

    // Local apply over this rank's elements (owned and ghost nodes).
    const auto nl = static_cast<std::size_t>(p.num_nodes());
    std::vector<double> x(nl), y(nl, 0.0);
    for (std::size_t l = 0; l < nl; ++l) x[l] = input(p.node_global()[l]);
    apply_elements(p.connectivity(), static_cast<std::size_t>(p.num_elements()), x, y);

    // Ghost exchange: every shared node's partial sums from every rank using it.
    const auto& nbr = p.neighbors();
    std::vector<std::vector<double>> send(nbr.size()), recv(nbr.size());
    std::vector<MPI_Request> req;
    for (std::size_t k = 0; k < nbr.size(); ++k) {
      const auto& shared = p.shared_nodes()[k];
      for (Id l : shared) send[k].push_back(y[static_cast<std::size_t>(l)]);
      recv[k].resize(shared.size());
      req.emplace_back(), MPI_Isend(send[k].data(), static_cast<int>(send[k].size()), MPI_DOUBLE, nbr[k], 7, MPI_COMM_WORLD, &req.back());
      req.emplace_back(), MPI_Irecv(recv[k].data(), static_cast<int>(recv[k].size()), MPI_DOUBLE, nbr[k], 7, MPI_COMM_WORLD, &req.back());
    }
    MPI_Waitall(static_cast<int>(req.size()), req.data(), MPI_STATUSES_IGNORE);
    for (std::size_t k = 0; k < nbr.size(); ++k)
      for (std::size_t q = 0; q < recv[k].size(); ++q) y[static_cast<std::size_t>(p.shared_nodes()[k][q])] += recv[k][q];

    // Owned values to rank 0, which checks them against one process.
    const int own = static_cast<int>(p.num_owned());
    std::vector<int> counts(static_cast<std::size_t>(size)), displs(static_cast<std::size_t>(size));
    MPI_Gather(&own, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<double> all;
    if (rank == 0) {
      int total = 0;
      for (int q = 0; q < size; ++q) displs[q] = total, total += counts[q];
      all.resize(static_cast<std::size_t>(total));
    }
    // Owned nodes are global ids [node_begin, node_end) in rank order: the
    // gathered array is y in global id order.
    MPI_Gatherv(y.data(), own, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (rank == 0) {
      const auto N = static_cast<std::size_t>(mesh.num_nodes());
      std::vector<double> gx(N), gy(N, 0.0);
      for (std::size_t i = 0; i < N; ++i) gx[i] = input(static_cast<Id>(i));
      FineBlock b;
      for (Id h = 0; h < mesh.num_coarse_elements(); ++h) {
        mesh.fill_block(h, b);
        apply_elements(b.conn, static_cast<std::size_t>(b.num_elements()), gx, gy);
      }
      double worst = 0, scale = 0;
      for (std::size_t i = 0; i < N; ++i) worst = std::max(worst, std::fabs(all[i] - gy[i])), scale = std::max(scale, std::fabs(gy[i]));
      const double rel = scale > 0 ? worst / scale : worst;
      std::printf("laplacian_mpi: %d ranks, %lld nodes, max |y - y_single| = %.3g (relative %.3g)\n", size,
                  static_cast<long long>(N), worst, rel);
      status = (all.size() == N && rel <= 1e-12) ? 0 : 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "laplacian_mpi (rank %d): %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 3);
  }
  MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Finalize();
  return status;
}
