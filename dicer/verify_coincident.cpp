// Coincident fine nodes across coarse elements, counted exactly in bounded
// memory. Two fine nodes with different ids can only share a position on
// the coarse mesh's boundary facets (faces of one hex, edges of one quad):
// elsewhere a node is strictly inside its coarse element or shared by id.
// So: the boundary facets' bounding boxes are swept along x to find the
// pairs that touch, and only those pairs' fine nodes are compared, a few
// facets' points in memory at a time.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <list>
#include <unordered_map>
#include <unordered_set>

#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "evaluate.hpp"
#include "verify_coincident.hpp"

namespace dicer::detail {
namespace {

struct Box {
  double lo[3], hi[3];
};

// Points of one facet, sorted by x for range searches.
struct FacetPoints {
  std::vector<Id> id;
  std::vector<Vec3> xyz;
};

// The corner positions of the coarse entity that owns a node, sorted: two
// nodes on coincident coarse entities (an interface made by duplicated
// vertices) have equal lists.
std::vector<std::array<double, 3>> entity_corners(const FineMesh& mesh, Id node, MeshCursor& cur) {
  const RowReader R(mesh.tables(), cur);
  const NodeRef r = mesh.locate_node(node, cur);
  std::vector<Id> vs;
  switch (r.kind) {
    case EntityKind::Vertex: vs = {r.entity}; break;
    case EntityKind::Edge: {
      const EdgeRow e = R.edge(r.entity);
      vs = {e.lo, e.hi};
      break;
    }
    case EntityKind::Face: {
      const FaceRow f = R.face(r.entity);
      vs.assign(f.v.begin(), f.v.end());
      break;
    }
    case EntityKind::Cell: {
      const ElementRow h = R.element(r.entity);
      vs.assign(h.corner.begin(), h.corner.begin() + R.corners());
      break;
    }
  }
  std::vector<std::array<double, 3>> out;
  for (Id v : vs) {
    const Vec3 p = R.xyz(v);
    out.push_back({p.x, p.y, p.z});
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

void find_coincident_nodes(const FineMesh& mesh, const std::vector<Facet>& facets, double tol, VerifyReport& r,
                           const std::function<void(const std::string&)>& note) {
  MeshCursor cur;
  const Evaluator E(mesh.tables(), cur);
  FineBlock::Scratch scratch;
  std::vector<Id> ids;
  std::vector<Vec3> xyz;
  auto points_of = [&](const Facet& f, FacetPoints& out) {
    facet_points(E, E.R.element(f.element), f.element, f.slot, scratch, ids, xyz);
    std::vector<size_t> order(ids.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return xyz[a].x < xyz[b].x; });
    out.id.resize(order.size()), out.xyz.resize(order.size());
    for (size_t i = 0; i < order.size(); ++i) out.id[i] = ids[order[i]], out.xyz[i] = xyz[order[i]];
  };

  // Bounding boxes (of the fine points: moved nodes may bulge past corners).
  std::vector<Box> box(facets.size());
  {
    FacetPoints p;
    for (size_t i = 0; i < facets.size(); ++i) {
      points_of(facets[i], p);
      Box& b = box[i];
      for (int d = 0; d < 3; ++d) b.lo[d] = INFINITY, b.hi[d] = -INFINITY;
      for (const Vec3& q : p.xyz) {
        const double c[3] = {q.x, q.y, q.z};
        for (int d = 0; d < 3; ++d) b.lo[d] = std::min(b.lo[d], c[d] - tol), b.hi[d] = std::max(b.hi[d], c[d] + tol);
      }
    }
  }
  std::vector<size_t> order(facets.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return box[a].lo[0] < box[b].lo[0]; });

  // A small LRU of facets' points (the sweep meets each facet in a window).
  constexpr size_t kCachedPoints = size_t{1} << 21;
  std::list<size_t> lru;
  std::unordered_map<size_t, std::pair<FacetPoints, std::list<size_t>::iterator>> cache;
  size_t cached = 0;
  auto get = [&](size_t i) -> const FacetPoints& {
    auto it = cache.find(i);
    if (it != cache.end()) {
      lru.splice(lru.begin(), lru, it->second.second);
      return it->second.first;
    }
    while (cached > kCachedPoints && lru.size() > 1) {  // never the one just used
      auto old = cache.find(lru.back());
      cached -= old->second.first.id.size();
      cache.erase(old);
      lru.pop_back();
    }
    lru.push_front(i);
    auto& e = cache[i];
    e.second = lru.begin();
    points_of(facets[i], e.first);
    cached += e.first.id.size();
    return e.first;
  };

  std::unordered_set<Id> coincident, interface, near;
  Id examples = 0;
  auto compare = [&](size_t ia, size_t ib) {
    const FacetPoints& a = get(ia);
    const FacetPoints& b = get(ib);  // may evict nothing a needs: both were just touched
    for (size_t p = 0; p < a.id.size(); ++p) {
      const Vec3& x = a.xyz[p];
      auto lo = std::lower_bound(b.xyz.begin(), b.xyz.end(), x.x - tol, [](const Vec3& v, double s) { return v.x < s; });
      for (auto q = lo; q != b.xyz.end() && q->x <= x.x + tol; ++q) {
        const Id other = b.id[static_cast<size_t>(q - b.xyz.begin())];
        if (other == a.id[p]) continue;
        const bool same = std::bit_cast<std::uint64_t>(q->x) == std::bit_cast<std::uint64_t>(x.x) &&
                          std::bit_cast<std::uint64_t>(q->y) == std::bit_cast<std::uint64_t>(x.y) &&
                          std::bit_cast<std::uint64_t>(q->z) == std::bit_cast<std::uint64_t>(x.z);
        if (same) {
          const bool fresh_a = coincident.insert(a.id[p]).second;  // both inserted
          const bool fresh_b = coincident.insert(other).second;
          if (!fresh_a && !fresh_b) continue;
          const bool iface = entity_corners(mesh, a.id[p], cur) == entity_corners(mesh, other, cur);
          if (iface) interface.insert(a.id[p]), interface.insert(other);
          if (examples < 5) {
            ++examples;
            // %.17g, as coarse_conformity: to_string's six decimals print a
            // millimetre part in metres as (0.000000, ...).
            char at[96];
            std::snprintf(at, sizeof at, "(%.17g, %.17g, %.17g)", x.x, x.y, x.z);
            note("fine nodes " + std::to_string(a.id[p]) + " and " + std::to_string(other) + " coincide at " + at +
                 (iface ? ": on coincident coarse entities (an interface)" : ": the coarse mesh does not conform there"));
          }
        } else {
          const double dx = q->x - x.x, dy = q->y - x.y, dz = q->z - x.z;
          if (std::sqrt(dx * dx + dy * dy + dz * dz) <= tol) near.insert(a.id[p]), near.insert(other);
        }
      }
    }
  };

  // Sweep and prune along x.
  std::vector<size_t> active;
  for (size_t oi : order) {
    const Box& bi = box[oi];
    active.erase(std::remove_if(active.begin(), active.end(), [&](size_t j) { return box[j].hi[0] < bi.lo[0]; }),
                 active.end());
    for (size_t j : active) {
      const Box& bj = box[j];
      if (bj.hi[1] < bi.lo[1] || bj.lo[1] > bi.hi[1] || bj.hi[2] < bi.lo[2] || bj.lo[2] > bi.hi[2]) continue;
      compare(oi, j);
    }
    active.push_back(oi);
  }
  r.coincident_nodes += static_cast<Id>(coincident.size());
  r.coincident_interface += static_cast<Id>(interface.size());
  r.near_coincident += static_cast<Id>(near.size());
}

}  // namespace dicer::detail
