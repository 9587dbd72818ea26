// The prolongation over ranks (mpi.hpp): each rank applies the rows of its
// chunk; ghost columns come from their owners, transpose shares go back to
// them. Every share names a column owned by a lower rank (a node's owner
// element comes first in store order), so the owners add the shares of
// higher ranks after their own, in rank order: the single process's sums.
#include <algorithm>

#include "all_to_all.hpp"
#include "dicer/mpi.hpp"

namespace dicer::mpi {
namespace {

struct Layout {
  int rank = 0, size = 1;
  std::vector<ChunkRange> plan;
  std::vector<Id> col_begin;  // per rank, and the total at the end
  Id first = 0, end = 0;
  // The rank owning coarse column c.
  int owner(Id c) const {
    return static_cast<int>(std::upper_bound(col_begin.begin(), col_begin.end() - 1, c) - col_begin.begin()) - 1;
  }
};

Layout layout(MPI_Comm comm, const Prolongation& p, size_t x_size, size_t y_size) {
  Layout l;
  MPI_Comm_rank(comm, &l.rank);
  MPI_Comm_size(comm, &l.size);
  collectively(comm, [&] {
    l.plan = plan_chunks(p.fine(), l.size);
    for (const ChunkRange& r : l.plan) l.col_begin.push_back(p.owned_cols(r.first_coarse, r.end_coarse)[0]);
    l.col_begin.push_back(p.cols());
    const ChunkRange& mine = l.plan[static_cast<size_t>(l.rank)];
    l.first = mine.first_coarse, l.end = mine.end_coarse;
    const auto rows = p.owned_rows(l.first, l.end);
    const Id cols = l.col_begin[l.rank + 1] - l.col_begin[l.rank];
    if (static_cast<Id>(x_size) != cols || static_cast<Id>(y_size) != rows[1] - rows[0])
      throw Error(ErrorKind::Usage, "rank " + std::to_string(l.rank) + ": " + std::to_string(x_size) + " coarse and " +
                                        std::to_string(y_size) + " fine values for " + std::to_string(cols) + " and " +
                                        std::to_string(rows[1] - rows[0]) + " owned nodes");
  });
  return l;
}

}  // namespace

void prolong(MPI_Comm comm, const Prolongation& p, std::span<const double> x_owned, std::span<double> y_owned) {
  const Layout l = layout(comm, p, x_owned.size(), y_owned.size());
  std::vector<Id> ghosts;
  std::vector<std::vector<std::int64_t>> ask(static_cast<size_t>(l.size));
  collectively(comm, [&] {
    ghosts = p.ghost_cols(l.first, l.end);
    for (Id g : ghosts) ask[static_cast<size_t>(l.owner(g))].push_back(g);  // sorted within each owner
  });
  const auto asked = detail::all_to_all(comm, ask);
  std::vector<std::vector<double>> answer(static_cast<size_t>(l.size));
  collectively(comm, [&] {
    const Id mine = l.col_begin[l.rank];
    for (int q = 0; q < l.size; ++q)
      for (std::int64_t c : asked[q]) {
        if (c < mine || c >= l.col_begin[l.rank + 1]) throw Error(ErrorKind::Io, "prolong: rank " + std::to_string(q) + " asked for a column this rank does not own");
        answer[q].push_back(x_owned[static_cast<size_t>(c - mine)]);
      }
  });
  const auto got = detail::all_to_all(comm, answer);
  collectively(comm, [&] {
    std::vector<double> x_local(x_owned.begin(), x_owned.end());
    for (const auto& v : got) x_local.insert(x_local.end(), v.begin(), v.end());  // owners in rank order: ghosts' order
    p.apply_range(l.first, l.end, ghosts, x_local, y_owned);
  });
}

void restrict_to(MPI_Comm comm, const Prolongation& p, std::span<const double> y_owned, std::span<double> x_owned) {
  const Layout l = layout(comm, p, x_owned.size(), y_owned.size());
  std::vector<std::vector<std::int64_t>> cols(static_cast<size_t>(l.size));
  std::vector<std::vector<double>> vals(static_cast<size_t>(l.size));
  collectively(comm, [&] {
    std::fill(x_owned.begin(), x_owned.end(), 0.0);
    std::vector<std::pair<Id, double>> lower;
    p.apply_transpose_range(l.first, l.end, y_owned, x_owned, lower);
    for (const auto& [c, v] : lower) {  // each owner's shares in their order
      const auto q = static_cast<size_t>(l.owner(c));
      cols[q].push_back(c), vals[q].push_back(v);
    }
  });
  const auto in_cols = detail::all_to_all(comm, cols);
  const auto in_vals = detail::all_to_all(comm, vals);
  collectively(comm, [&] {
    const Id mine = l.col_begin[l.rank];
    for (int q = 0; q < l.size; ++q) {  // higher ranks' shares, in rank order
      if (in_cols[q].size() != in_vals[q].size() || (q <= l.rank && !in_cols[q].empty()))
        throw Error(ErrorKind::Io, "restrict_to: unexpected shares from rank " + std::to_string(q));
      for (size_t i = 0; i < in_cols[q].size(); ++i) {
        const Id c = in_cols[q][i];
        if (c < mine || c >= l.col_begin[l.rank + 1]) throw Error(ErrorKind::Io, "restrict_to: rank " + std::to_string(q) + " sent a share for a column this rank does not own");
        x_owned[static_cast<size_t>(c - mine)] += in_vals[q][i];
      }
    }
  });
}

}  // namespace dicer::mpi
