// verify on P ranks: each checks its chunk (verify_part), rank 0 merges the
// parts and does the global checks (verify_finish), as one process would.
#include <cstring>

#include "dicer/mpi.hpp"
#include "dicer/verify.hpp"

namespace dicer::mpi {
namespace {

// A part as bytes: counters, then the three entity lists, then the notes.
std::string pack(const VerifyPart& p) {
  std::string out;
  auto put = [&](const void* d, size_t n) {
    if (n == 0) return;
    const size_t at = out.size();
    out.resize(at + n);
    std::memcpy(out.data() + at, d, n);
  };
  auto put64 = [&](std::int64_t v) { put(&v, 8); };
  const VerifyReport& r = p.report;
  for (Id v : {r.fine_faces_checked, r.id_errors, r.bit_identity_errors, r.coincident_nodes, r.conformity_errors, r.inverted,
                 r.index_errors})
    put64(v);
  put(&r.min_scaled_jacobian, 8);
  put64(static_cast<std::int64_t>(p.face_sides.size()));
  put(p.face_sides.data(), p.face_sides.size() * sizeof(p.face_sides[0]));
  put64(static_cast<std::int64_t>(p.edge_hashes.size()));
  put(p.edge_hashes.data(), p.edge_hashes.size() * sizeof(p.edge_hashes[0]));
  put64(static_cast<std::int64_t>(p.edge_uses.size()));
  put(p.edge_uses.data(), p.edge_uses.size() * sizeof(p.edge_uses[0]));
  for (const auto* list : {&r.problems, &r.warnings}) {
    put64(static_cast<std::int64_t>(list->size()));
    for (const auto& s : *list) put64(static_cast<std::int64_t>(s.size())), put(s.data(), s.size());
  }
  return out;
}

VerifyPart unpack(const char* d, size_t n) {
  size_t at = 0;
  auto get = [&](void* to, size_t k) {
    if (k > n - at) throw Error(ErrorKind::Io, "verify: a truncated part from another rank");
    if (k == 0) return;  // an empty vector's data() may be null
    std::memcpy(to, d + at, k);
    at += k;
  };
  auto get64 = [&] {
    std::int64_t v;
    get(&v, 8);
    return v;
  };
  // A count is checked against the bytes left before anything is sized by it.
  auto count = [&](size_t item) {
    const std::int64_t k = get64();
    if (k < 0 || static_cast<std::uint64_t>(k) > (n - at) / item)
      throw Error(ErrorKind::Io, "verify: a part from another rank declares more than it holds");
    return static_cast<size_t>(k);
  };
  VerifyPart p;
  VerifyReport& r = p.report;
  for (Id* v : {&r.fine_faces_checked, &r.id_errors, &r.bit_identity_errors, &r.coincident_nodes, &r.conformity_errors,
                &r.inverted, &r.index_errors})
    *v = get64();
  get(&r.min_scaled_jacobian, 8);
  p.face_sides.resize(count(sizeof(p.face_sides[0])));
  get(p.face_sides.data(), p.face_sides.size() * sizeof(p.face_sides[0]));
  p.edge_hashes.resize(count(sizeof(p.edge_hashes[0])));
  get(p.edge_hashes.data(), p.edge_hashes.size() * sizeof(p.edge_hashes[0]));
  p.edge_uses.resize(count(sizeof(p.edge_uses[0])));
  get(p.edge_uses.data(), p.edge_uses.size() * sizeof(p.edge_uses[0]));
  for (auto* list : {&r.problems, &r.warnings}) {
    const size_t k = count(8);
    for (size_t i = 0; i < k; ++i) {
      std::string s(count(1), '\0');
      get(s.data(), s.size());
      list->push_back(std::move(s));
    }
  }
  return p;
}

}  // namespace

VerifyReport verify_distributed(MPI_Comm comm, const FineMesh& mesh, const std::function<void(Id, Id)>& progress) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  std::string mine;
  collectively(comm, [&] {
    const ChunkRange c = plan_chunks(mesh, size)[static_cast<size_t>(rank)];
    mine = pack(verify_part(mesh, c.first_coarse, c.end_coarse, progress));
  });
  // Rank 0's parts total some 220 bytes a coarse hex: past MPI's 2 GiB of
  // one collective near 10^7 of them, so they come in pieces.
  const std::vector<std::string> all = gather_bytes(comm, std::move(mine));
  VerifyReport report;
  collectively(comm, [&] {
    if (rank != 0) return;
    std::vector<VerifyPart> parts;
    for (const std::string& part : all) parts.push_back(unpack(part.data(), part.size()));
    report = verify_finish(mesh, parts);
  });
  return report;
}

}  // namespace dicer::mpi
