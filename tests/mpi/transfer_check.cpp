// The prolongation over ranks against one process (run by ctest under
// mpirun -n P): on random boxes diced twice (the same seed on every rank)
// and on the store pairs named on the command line (COARSE FINE ...),
// every rank applies P and P^T to its owned values (mpi::prolong,
// mpi::restrict_to); rank 0 gathers them and compares with
// Prolongation::apply / apply_transpose in one process, bit for bit. The
// ranges are those of the partition API: the fine level's make_partition
// owns the rows, the coarse level's (plan_like) the columns, and its ghosts
// are ghost_cols. Exit 0 when everything agrees, 1 otherwise.
#include <mpi.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "dicer/mpi.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

double value(Id id, int salt) { return std::sin(0.37 * static_cast<double>(id) + salt) + 0.01 * static_cast<double>(id % 7); }

// Owned values of every rank, gathered on rank 0 in rank order (= id order).
std::vector<double> gather(const std::vector<double>& mine, int size) {
  const int n = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<size_t>(size)), displs(static_cast<size_t>(size));
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (int q = 0; q < size; ++q) displs[q] = total, total += counts[q];
  std::vector<double> all(static_cast<size_t>(total));
  MPI_Allgatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  return all;
}

int check(const FineMesh& coarse, const FineMesh& fine, const std::string& what, int rank, int size) {
  int bad = 0;
  auto fail = [&](const std::string& m) {
    std::fprintf(stderr, "%s rank %d: %s\n", what.c_str(), rank, m.c_str());
    bad = 1;
  };
  const Prolongation p(coarse, fine);
  const auto plan = plan_chunks(fine, size);
  const ChunkRange& mine = plan[static_cast<size_t>(rank)];
  const Partition fp = mpi::make_partition(fine, MPI_COMM_WORLD);
  const Partition cp = mpi::make_partition(coarse, MPI_COMM_WORLD, {}, plan_like(coarse, plan));
  const auto rows = p.owned_rows(mine.first_coarse, mine.end_coarse);
  const auto cols = p.owned_cols(mine.first_coarse, mine.end_coarse);
  if (fp.range().node_begin != rows[0] || fp.range().node_end != rows[1]) fail("the fine partition owns other rows");
  if (cp.range().node_begin != cols[0] || cp.range().node_end != cols[1]) fail("the coarse partition owns other columns");
  const auto ghosts = p.ghost_cols(mine.first_coarse, mine.end_coarse);
  const auto cg = cp.node_global().subspan(static_cast<size_t>(cp.num_owned()));
  if (!std::equal(ghosts.begin(), ghosts.end(), cg.begin(), cg.end())) fail("ghost_cols are not the coarse partition's ghosts");

  std::vector<double> x_owned, y_owned;
  for (Id c = cols[0]; c < cols[1]; ++c) x_owned.push_back(value(c, 1));
  for (Id r = rows[0]; r < rows[1]; ++r) y_owned.push_back(value(r, 2));
  std::vector<double> y(y_owned.size()), x(x_owned.size());
  mpi::prolong(MPI_COMM_WORLD, p, x_owned, y);
  mpi::restrict_to(MPI_COMM_WORLD, p, y_owned, x);
  const auto py = gather(y, size), ptx = gather(x, size);
  if (rank == 0) {
    std::vector<double> gx(static_cast<size_t>(p.cols())), gy(static_cast<size_t>(p.rows()));
    for (Id c = 0; c < p.cols(); ++c) gx[static_cast<size_t>(c)] = value(c, 1);
    for (Id r = 0; r < p.rows(); ++r) gy[static_cast<size_t>(r)] = value(r, 2);
    std::vector<double> want_y(gy.size()), want_x(gx.size());
    p.apply(gx, want_y);
    p.apply_transpose(gy, want_x);
    auto same = [](const std::vector<double>& a, const std::vector<double>& b) {
      if (a.size() != b.size()) return false;
      for (size_t i = 0; i < a.size(); ++i)
        if (std::bit_cast<std::uint64_t>(a[i]) != std::bit_cast<std::uint64_t>(b[i])) return false;
      return true;
    };
    if (!same(py, want_y)) fail("prolong differs from one process");
    if (!same(ptx, want_x)) fail("restrict_to differs from one process");
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
    std::mt19937_64 rng(91);  // the same stream on every rank: the same meshes
    for (int trial = 0; trial < 3; ++trial) {
      test::BoxSpec spec;
      spec.a = 3 + trial, spec.b = 2 + trial % 2, spec.c = 2;
      const CoarseMesh m = test::random_box(spec, rng);
      IntervalRequest rc, rf;
      rc.global = 1 + trial % 2, rf.global = rc.global.value() * (2 + trial % 2);
      bad |= check(FineMesh::dice(m, rc), FineMesh::dice(m, rf), "random box " + std::to_string(trial), rank, size);
      ++checked;
    }
    for (int a = 1; a + 1 < argc; a += 2)
      bad |= check(read_store(argv[a]), read_store(argv[a + 1]), std::string(argv[a]) + " -> " + argv[a + 1], rank, size),
          ++checked;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "transfer_check (rank %d): %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 3);
  }
  int any = 0;
  MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (rank == 0) std::printf("transfer_check: %d ranks, %d pairs, %s\n", size, checked, any ? "MISMATCH" : "agree");
  MPI_Finalize();
  return any;
}
