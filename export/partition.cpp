// Partitions and their communication maps (include/dicer/partition.hpp).
#include "dicer/partition.hpp"

#include <algorithm>
#include <map>

#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"

namespace dicer {
namespace {

// The chunk owning node id `id`: the last whose own range starts at or below it.
std::int32_t owner_chunk(const std::vector<ChunkRange>& plan, Id id) {
  auto it = std::upper_bound(plan.begin(), plan.end(), id, [](Id v, const ChunkRange& c) { return v < c.node_begin; });
  // Chunks owning no node share their successor's start: upper_bound skips them.
  return static_cast<std::int32_t>((it == plan.begin() ? plan.begin() : it - 1) - plan.begin());
}

void add_user(std::vector<std::int32_t>& users, std::int32_t c) {
  auto it = std::lower_bound(users.begin(), users.end(), c);
  if (it == users.end() || *it != c) users.insert(it, c);
}

}  // namespace

std::vector<NodeRun> ghost_runs(const FineMesh& mesh, const std::vector<ChunkRange>& plan, Id c) {
  const ChunkRange& range = plan.at(static_cast<size_t>(c));
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  const bool vol = mesh.mode() == Mode::Volume;
  std::vector<NodeRun> out;
  auto add = [&](Id first, Id count) {
    if (count > 0 && first < range.node_begin) out.push_back({first, count, owner_chunk(plan, first), {}});
  };
  for (Id h = range.first_coarse; h < range.end_coarse; ++h) {
    const ElementRow e = R.element(h);
    for (int k = 0; k < R.corners(); ++k) add(e.corner_node[k], 1);
    for (int k = 0; k < R.edges(); ++k) add(e.edge_node[k], ids::edge_nodes(e.n[vol ? k / 4 : k / 2]));
    for (int k = 0; k < R.faces(); ++k) {
      const auto [nu, nv] = face_intervals(e, k, mesh.mode());
      add(e.face_node[k], ids::face_nodes(nu, nv));
    }
  }
  std::sort(out.begin(), out.end(), [](const NodeRun& a, const NodeRun& b) { return a.first < b.first; });
  out.erase(std::unique(out.begin(), out.end(), [](const NodeRun& a, const NodeRun& b) { return a.first == b.first; }),
            out.end());
  for (NodeRun& r : out) {
    if (r.owner == c) R.corrupt(RowTable::Elements, range.first_coarse, "a run below the chunk's own nodes is its own");
    r.users = {std::min<std::int32_t>(r.owner, static_cast<std::int32_t>(c)),
               std::max<std::int32_t>(r.owner, static_cast<std::int32_t>(c))};
  }
  return out;
}

namespace {

// Every shared run with all its users, from every chunk's ghost runs.
std::map<Id, NodeRun> all_shared_runs(const std::vector<std::vector<NodeRun>>& ghosts) {
  std::map<Id, NodeRun> runs;
  for (const auto& g : ghosts)
    for (const NodeRun& r : g) {
      auto [it, fresh] = runs.try_emplace(r.first, r);
      if (!fresh) {
        if (it->second.count != r.count || it->second.owner != r.owner)
          throw Error(ErrorKind::Corrupt, "node run " + std::to_string(r.first) + " is seen with two sizes or owners");
        for (std::int32_t u : r.users) add_user(it->second.users, u);
      }
    }
  return runs;
}

}  // namespace

std::vector<NodeRun> sharing_for(Id r, const std::vector<ChunkRange>& plan,
                                 const std::vector<std::vector<NodeRun>>& ghosts_of_every_chunk) {
  (void)plan;
  std::vector<NodeRun> out;
  for (const auto& [first, run] : all_shared_runs(ghosts_of_every_chunk))
    if (std::binary_search(run.users.begin(), run.users.end(), static_cast<std::int32_t>(r))) out.push_back(run);
  return out;
}

std::vector<std::vector<NodeRun>> in_process_sharing(const FineMesh& mesh, const std::vector<ChunkRange>& plan) {
  std::vector<std::vector<NodeRun>> ghosts;
  for (Id c = 0; c < static_cast<Id>(plan.size()); ++c) ghosts.push_back(ghost_runs(mesh, plan, c));
  std::vector<std::vector<NodeRun>> out(plan.size());
  for (const auto& [first, run] : all_shared_runs(ghosts))
    for (std::int32_t u : run.users) out[static_cast<size_t>(u)].push_back(run);
  return out;  // map order: sorted by first id in every entry
}

PartitionStats partition_stats(Id r, const std::vector<ChunkRange>& plan, const std::vector<NodeRun>& sharing) {
  const ChunkRange& c = plan.at(static_cast<size_t>(r));
  PartitionStats s;
  s.rank = r;
  s.elements = c.fine_elements;
  s.owned_nodes = c.node_end - c.node_begin;
  std::vector<std::int32_t> nbr;
  for (const NodeRun& run : sharing) {
    if (run.owner != r) s.ghost_nodes += run.count;
    s.shared_nodes += run.count;
    s.comm_entries += run.count * static_cast<Id>(run.users.size() - 1);
    for (std::int32_t u : run.users)
      if (u != r) add_user(nbr, u);
  }
  s.neighbors = static_cast<Id>(nbr.size());
  return s;
}

Partition::Partition(const FineMesh& mesh, const std::vector<ChunkRange>& plan, Id rank, std::vector<NodeRun> sharing,
                     const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                     const std::function<bool()>& cancel)
    : range_(plan.at(static_cast<size_t>(rank))), chunk_(mesh, range_), sharing_(std::move(sharing)) {
  chunk_.set_plan(plan);
  chunk_.prepare(sets, progress, cancel);
  const Id nown = num_owned(), nn = chunk_.num_nodes(), ng = nn - nown;
  const auto g = chunk_.node_global();
  // The chunk lists ghosts (lower ids) then the own range; here the own
  // range comes first.
  auto local_of = [&](Id l) { return l >= ng ? l - ng : nown + l; };
  node_global_.resize(static_cast<size_t>(nn)), node_owner_.resize(static_cast<size_t>(nn));
  x_.resize(static_cast<size_t>(nn)), y_.resize(static_cast<size_t>(nn)), z_.resize(static_cast<size_t>(nn));
  for (Id l = 0; l < nn; ++l) {
    const Id L = local_of(l);
    node_global_[L] = g[l], node_owner_[L] = chunk_.node_owner()[l];
    x_[L] = chunk_.x()[l], y_[L] = chunk_.y()[l], z_[L] = chunk_.z()[l];
  }
  conn_.resize(chunk_.connectivity().size());
  for (size_t q = 0; q < conn_.size(); ++q) conn_[q] = local_of(chunk_.connectivity()[q]);

  // Communication maps: for every other user of a shared run, the run's
  // nodes in global id order (runs are sorted and disjoint).
  std::map<std::int32_t, std::vector<Id>> by_rank;
  const Id own0 = range_.node_begin;
  auto ghost_local = [&](Id id) {
    auto it = std::lower_bound(g.begin(), g.begin() + ng, id);
    if (it == g.begin() + ng || *it != id)
      throw Error(ErrorKind::Corrupt, "partition " + std::to_string(rank) + ": shared node " + std::to_string(id) +
                                          " is not among its nodes");
    return nown + (it - g.begin());
  };
  for (const NodeRun& run : sharing_) {
    for (std::int32_t q : run.users) {
      if (q == rank) continue;
      auto& list = by_rank[q];
      for (Id id = run.first; id < run.first + run.count; ++id)
        list.push_back(id >= own0 && id - own0 < nown ? id - own0 : ghost_local(id));
    }
  }
  for (auto& [q, list] : by_rank) neighbors_.push_back(q), shared_.push_back(std::move(list));
}

NemesisInfo nemesis_info(const ChunkSource& chunk, Id processors, Id rank, const std::vector<NodeRun>& sharing,
                         const SetCounts& counts) {
  NemesisInfo n;
  n.processors = processors;
  n.processor = rank;
  n.global_nodes = chunk.mesh().num_nodes();
  n.global_elements = chunk.mesh().num_elements();
  n.side_set_counts = counts.side;
  n.node_set_counts = counts.node;
  // For every other user of a shared run, the run's nodes in global id
  // order (runs are sorted and disjoint), in the chunk's local numbering.
  std::map<std::int32_t, std::vector<Id>> by_rank;
  for (const NodeRun& run : sharing)
    for (std::int32_t q : run.users) {
      if (q == rank) continue;
      auto& list = by_rank[q];
      for (Id id = run.first; id < run.first + run.count; ++id) {
        const Id l = chunk.local_of(id);
        if (l < 0)
          throw Error(ErrorKind::Corrupt, "partition " + std::to_string(rank) + ": shared node " + std::to_string(id) +
                                              " is not among its nodes");
        list.push_back(l);
      }
    }
  for (auto& [q, list] : by_rank) n.neighbors.push_back(q), n.shared.push_back(std::move(list));
  return n;
}

NemesisInfo nemesis_info(const Partition& p, const SetCounts& counts) {
  return nemesis_info(p.chunk(), p.size(), p.rank(), p.sharing(), counts);
}

}  // namespace dicer
