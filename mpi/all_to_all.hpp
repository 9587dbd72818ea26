#pragma once
// Private to mpi/: one personalised all-to-all exchange (counts, then the
// values), for the sharing maps and the transfer operators.
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/mpi.hpp"

namespace dicer::mpi::detail {

template <class T>
MPI_Datatype mpi_type() {
  if constexpr (std::is_same_v<T, std::int64_t>) return MPI_INT64_T;
  else if constexpr (std::is_same_v<T, double>) return MPI_DOUBLE;
  else static_assert(sizeof(T) == 0, "unsupported type");
}

// send[q] goes to rank q; returns what each rank sent here, in rank order.
template <class T>
std::vector<std::vector<T>> all_to_all(MPI_Comm comm, const std::vector<std::vector<T>>& send) {
  const int P = static_cast<int>(send.size());
  std::vector<int> scount(static_cast<size_t>(P)), rcount(static_cast<size_t>(P)), sdisp(static_cast<size_t>(P)),
      rdisp(static_cast<size_t>(P));
  // MPI's counts and displacements are int: past 2^31 - 1 values sent or
  // received on any rank, every rank ends with Overflow before the values
  // travel (a rank alone throwing would leave the others in MPI_Alltoallv).
  constexpr std::uint64_t kMax = std::numeric_limits<int>::max();
  std::uint64_t sent = 0, received = 0;
  for (int q = 0; q < P; ++q) {
    sent += send[q].size();
    scount[q] = static_cast<int>(std::min<std::uint64_t>(send[q].size(), kMax));
  }
  if (MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm) != MPI_SUCCESS)
    throw Error(ErrorKind::Io, "MPI_Alltoall failed");
  for (int q = 0; q < P; ++q) received += static_cast<std::uint64_t>(rcount[q]);
  collectively(comm, [&] {
    if (sent > kMax || received > kMax)
      throw Error(ErrorKind::Overflow, "an exchange between ranks of " + std::to_string(std::max(sent, received)) +
                                           " values on one rank: over MPI's limit of 2^31 - 1 (run on more ranks)");
  });
  std::vector<T> sbuf, rbuf;
  for (int q = 0, s = 0, r = 0; q < P; ++q) {
    sdisp[q] = s, rdisp[q] = r;
    s += scount[q], r += rcount[q];
    sbuf.insert(sbuf.end(), send[q].begin(), send[q].end());
  }
  rbuf.resize(static_cast<size_t>(rdisp.back() + rcount.back()));
  if (MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), mpi_type<T>(), rbuf.data(), rcount.data(), rdisp.data(),
                    mpi_type<T>(), comm) != MPI_SUCCESS)
    throw Error(ErrorKind::Io, "MPI_Alltoallv failed");
  std::vector<std::vector<T>> out(static_cast<size_t>(P));
  for (int q = 0; q < P; ++q) out[q].assign(rbuf.begin() + rdisp[q], rbuf.begin() + rdisp[q] + rcount[q]);
  return out;
}

}  // namespace dicer::mpi::detail
