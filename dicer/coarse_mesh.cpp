// The invariants every coarse mesh must satisfy before
// topology is built (see include/dicer/coarse_mesh.hpp).
#include "dicer/coarse_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "dicer/coarse_conformity.hpp"
#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/topology.hpp"

namespace dicer {
namespace {

std::string element_name(const CoarseMesh& m, Id e) {
  const Id fid = e < static_cast<Id>(m.element_file_id.size()) ? m.element_file_id[e] : e + 1;
  return "element " + std::to_string(fid);
}

// Signs of the 8 corner Jacobians: +1 all positive, -1 all negative, 0 mixed
// or degenerate.
int hex_handedness(const CoarseMesh& m, const Id* c) {
  int pos = 0, neg = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3 o = m.vertex(c[k]);
    Vec3 e[3];
    for (int d = 0; d < 3; ++d) {
      const Vec3 p = m.vertex(c[kHexCornerNbr[k][d]]);
      e[d] = {p.x - o.x, p.y - o.y, p.z - o.z};
      // Each edge scaled by a power of two to a largest component near 1
      // (exact: the determinant's sign, zero included, stays as computed
      // unscaled): a cube of side 1e-110 has a determinant of 1e-330,
      // which underflows to 0 and read as degenerate.
      const double s = std::max({std::fabs(e[d].x), std::fabs(e[d].y), std::fabs(e[d].z)});
      if (s > 0 && std::isfinite(s)) {
        const int k = std::ilogb(s);
        e[d] = {std::ldexp(e[d].x, -k), std::ldexp(e[d].y, -k), std::ldexp(e[d].z, -k)};
      }
    }
    const double det = e[0].x * (e[1].y * e[2].z - e[1].z * e[2].y) -
                       e[0].y * (e[1].x * e[2].z - e[1].z * e[2].x) +
                       e[0].z * (e[1].x * e[2].y - e[1].y * e[2].x);
    if (det > 0) ++pos;
    else if (det < 0) ++neg;
  }
  return pos == 8 ? 1 : neg == 8 ? -1 : 0;
}

void reorient_left_handed(CoarseMesh& m) {
  const Id ne = m.num_elements();
  for (Id e = 0; e < ne; ++e) {
    Id* c = &m.conn[static_cast<size_t>(e) * 8];
    Id old[8];
    std::copy(c, c + 8, old);
    for (int k = 0; k < 8; ++k) c[k] = old[kHexMirror[k]];
  }
  // Side s of the old numbering has the corners old[kHexSideCorners[s]];
  // find the new side with the same corner set.
  int side_map[6];
  for (int s = 0; s < 6; ++s) {
    std::array<int, 4> want;
    for (int q = 0; q < 4; ++q) want[q] = kHexSideCorners[s][q];
    std::sort(want.begin(), want.end());
    for (int t = 0; t < 6; ++t) {
      std::array<int, 4> have;
      for (int q = 0; q < 4; ++q) have[q] = kHexMirror[kHexSideCorners[t][q]];
      std::sort(have.begin(), have.end());
      if (have == want) side_map[s] = t;
    }
  }
  for (auto& ss : m.side_sets)
    for (auto& s : ss.side)
      if (s >= 0 && s < 6) s = static_cast<std::int8_t>(side_map[s]);
  // Mid nodes follow their corners: the new slot of an edge (face) is the
  // old slot of the edge (face) between the mirrored corners.
  if (m.mid.empty()) return;
  int slot_map[kHexMidSlots];
  for (int e = 0; e < 12; ++e) slot_map[e] = hex_edge_between(kHexMirror[kHexEdge[e][0]], kHexMirror[kHexEdge[e][1]]);
  for (int f = 0; f < 6; ++f) {
    const int c[4] = {kHexMirror[kHexFace[f][0]], kHexMirror[kHexFace[f][1]], kHexMirror[kHexFace[f][2]],
                      kHexMirror[kHexFace[f][3]]};
    slot_map[12 + f] = 12 + hex_face_with(c);
  }
  slot_map[18] = 18;
  for (Id e = 0; e < ne; ++e) {
    Id* s = &m.mid[static_cast<size_t>(e) * kHexMidSlots];
    Id old[kHexMidSlots];
    std::copy(s, s + kHexMidSlots, old);
    for (int k = 0; k < kHexMidSlots; ++k) s[k] = old[slot_map[k]];
  }
}

// Keeps the vertices with keep[v] set, in order: coordinates, file ids,
// classification, connectivity and node sets (entries of dropped vertices
// leave them). Connectivity entries out of range are left for the checks.
// Returns the number dropped.
Id compact_vertices(CoarseMesh& m, const std::vector<char>& keep) {
  const Id nv = m.num_vertices();
  std::vector<Id> remap(static_cast<size_t>(nv), -1);
  Id used = 0;
  for (Id v = 0; v < nv; ++v)
    if (keep[v]) remap[v] = used++;
  if (used == nv) return 0;
  auto compact = [&](auto& arr) {
    if (arr.size() != static_cast<size_t>(nv)) return;
    for (Id v = 0; v < nv; ++v)
      if (remap[v] >= 0) arr[remap[v]] = arr[v];
    arr.resize(static_cast<size_t>(used));
  };
  compact(m.x), compact(m.y), compact(m.z), compact(m.vertex_file_id);
  compact(m.vertex_geo_dim), compact(m.vertex_geo_tag);
  for (Id& c : m.conn)
    if (c >= 0 && c < nv) c = remap[c];
  for (auto& ns : m.node_sets) {
    std::vector<Id> kept;
    for (Id v : ns.vertex)
      if (v >= 0 && v < nv && remap[v] >= 0) kept.push_back(remap[v]);
    ns.vertex = std::move(kept);
  }
  return nv - used;
}

}  // namespace

void take_mid_nodes(CoarseMesh& m, std::vector<Id> mid) {
  const std::string& f = m.source;
  const int slots = mid_slots(m.mode), nc = m.corners_per_element();
  const Id ne = m.num_elements(), nv = m.num_vertices();
  if (mid.size() != static_cast<size_t>(ne) * slots)
    throw Error(ErrorKind::BadInput, f + ": the second-order node table has " + std::to_string(mid.size()) +
                                         " entries for " + std::to_string(ne) + " elements of " +
                                         std::to_string(slots) + " slots");
  std::vector<Id> corner_of(static_cast<size_t>(nv), -1);  // an element with v as corner
  for (Id e = 0; e < ne; ++e)
    for (int k = 0; k < nc; ++k)
      if (const Id v = m.conn[static_cast<size_t>(e) * nc + k]; v >= 0 && v < nv && corner_of[v] < 0) corner_of[v] = e;
  auto node_id = [&](Id v) { return v < static_cast<Id>(m.vertex_file_id.size()) ? m.vertex_file_id[v] : v + 1; };
  std::vector<Id> index(static_cast<size_t>(nv), -1);
  std::vector<char> keep(static_cast<size_t>(nv), 1);
  for (Id e = 0; e < ne; ++e)
    for (int k = 0; k < slots; ++k) {
      Id& v = mid[static_cast<size_t>(e) * slots + k];
      if (v == -1) continue;
      if (v < 0 || v >= nv)
        throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + ": mid-node slot " + std::to_string(k) +
                                             " references a node that does not exist");
      if (corner_of[v] >= 0)
        throw Error(ErrorKind::BadInput, f + ": node " + std::to_string(node_id(v)) + " is a corner of " +
                                             element_name(m, corner_of[v]) + " and a mid node of " +
                                             element_name(m, e) + " (inconsistent second-order connectivity)");
      if (index[v] < 0) {
        index[v] = static_cast<Id>(m.mid_x.size());
        m.mid_x.push_back(m.x[v]), m.mid_y.push_back(m.y[v]), m.mid_z.push_back(m.z[v]);
        m.mid_file_id.push_back(node_id(v));
        keep[v] = 0;
      }
      v = index[v];
    }
  m.mid = std::move(mid);
  compact_vertices(m, keep);
}

void validate_coarse_mesh(CoarseMesh& m) {
  const std::string& f = m.source;
  const int nc = m.corners_per_element();
  const Id nv = m.num_vertices();
  if (m.y.size() != m.x.size() || m.z.size() != m.x.size())
    throw Error(ErrorKind::BadInput, f + ": coordinate arrays differ in length");
  if (m.conn.size() % static_cast<size_t>(nc) != 0)
    throw Error(ErrorKind::BadInput, f + ": connectivity length is not a multiple of " + std::to_string(nc));
  const Id ne = m.num_elements();
  if (ne == 0) throw Error(ErrorKind::BadInput, f + ": mesh has no " +
                                                    (m.mode == Mode::Volume ? "hexahedra" : "quadrilaterals"));
  if (m.vertex_file_id.empty()) {
    m.vertex_file_id.resize(static_cast<size_t>(nv));
    std::iota(m.vertex_file_id.begin(), m.vertex_file_id.end(), Id{1});
  }
  if (m.element_file_id.empty()) {
    m.element_file_id.resize(static_cast<size_t>(ne));
    std::iota(m.element_file_id.begin(), m.element_file_id.end(), Id{1});
  }
  if (m.blocks.empty()) m.blocks.push_back(Block{1, ""});
  if (m.element_block.empty()) m.element_block.assign(static_cast<size_t>(ne), 0);
  if (static_cast<Id>(m.element_block.size()) != ne || static_cast<Id>(m.element_file_id.size()) != ne ||
      static_cast<Id>(m.vertex_file_id.size()) != nv)
    throw Error(ErrorKind::BadInput, f + ": per-element or per-vertex arrays have inconsistent lengths");

  for (Id v = 0; v < nv; ++v)
    if (!std::isfinite(m.x[v]) || !std::isfinite(m.y[v]) || !std::isfinite(m.z[v]))
      throw Error(ErrorKind::BadInput, f + ": node " + std::to_string(m.vertex_file_id[v]) +
                                           ": coordinate is not finite (NaN or Inf)");
  for (Id e = 0; e < ne; ++e) {
    const Id* c = &m.conn[static_cast<size_t>(e) * nc];
    for (int k = 0; k < nc; ++k)
      if (c[k] < 0 || c[k] >= nv)
        throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + ": corner " + std::to_string(k) +
                                             " references a node that does not exist");
    for (int a = 0; a < nc; ++a)
      for (int b = a + 1; b < nc; ++b)
        if (c[a] == c[b])
          throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + ": node " +
                                               std::to_string(m.vertex_file_id[c[a]]) +
                                               " appears twice (degenerate element)");
    if (m.element_block[e] < 0 || m.element_block[e] >= static_cast<std::int32_t>(m.blocks.size()))
      throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + ": block index out of range");
  }

  // Second-order nodes: the table's shape, every slot in range, finite.
  if (!m.mid.empty()) {
    const int slots = mid_slots(m.mode);
    const Id nm = static_cast<Id>(m.mid_x.size());
    if (m.mid.size() != static_cast<size_t>(ne) * slots || m.mid_y.size() != m.mid_x.size() ||
        m.mid_z.size() != m.mid_x.size() || m.mid_file_id.size() != m.mid_x.size())
      throw Error(ErrorKind::BadInput, f + ": the second-order node tables have inconsistent lengths");
    for (Id e = 0; e < ne; ++e)
      for (int k = 0; k < slots; ++k) {
        const Id q = m.mid[static_cast<size_t>(e) * slots + k];
        if (q < -1 || q >= nm)
          throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + " (block " +
                                               std::to_string(m.blocks[m.element_block[e]].id) + "): mid-node slot " +
                                               std::to_string(k) + " references a node that does not exist");
        if (q >= 0 && !(std::isfinite(m.mid_x[q]) && std::isfinite(m.mid_y[q]) && std::isfinite(m.mid_z[q])))
          throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) + " (block " +
                                               std::to_string(m.blocks[m.element_block[e]].id) + "): mid node " +
                                               std::to_string(m.mid_file_id[q]) +
                                               ": coordinate is not finite (NaN or Inf)");
      }
  }

  // Duplicated elements: same corner set.
  {
    std::vector<std::pair<std::array<Id, 8>, Id>> keys(static_cast<size_t>(ne));
    for (Id e = 0; e < ne; ++e) {
      std::array<Id, 8> k;
      k.fill(-1);
      std::copy_n(&m.conn[static_cast<size_t>(e) * nc], nc, k.begin());
      std::sort(k.begin(), k.begin() + nc);
      keys[e] = {k, e};
    }
    std::sort(keys.begin(), keys.end());
    for (size_t i = 1; i < keys.size(); ++i)
      if (keys[i].first == keys[i - 1].first)
        throw Error(ErrorKind::BadInput, f + ": " + element_name(m, keys[i].second) + " duplicates " +
                                             element_name(m, keys[i - 1].second) + " (same nodes)");
  }

  // Handedness (volume mode).
  if (m.mode == Mode::Volume) {
    Id right = 0, left = 0, first_right = -1, first_left = -1;
    for (Id e = 0; e < ne; ++e) {
      const int h = hex_handedness(m, &m.conn[static_cast<size_t>(e) * 8]);
      if (h == 0)
        throw Error(ErrorKind::BadInput, f + ": " + element_name(m, e) +
                                             " is inverted or degenerate (its corner Jacobians are not all of "
                                             "one sign)");
      if (h > 0) {
        if (right++ == 0) first_right = e;
      } else if (left++ == 0) {
        first_left = e;
      }
    }
    if (right > 0 && left > 0) {
      const Id bad = left < right ? first_left : first_right;
      throw Error(ErrorKind::BadInput, f + ": mixed handedness: " + std::to_string(right) + " right-handed and " +
                                           std::to_string(left) + " left-handed hexes; " + element_name(m, bad) +
                                           " is " + (left < right ? "left" : "right") + "-handed");
    }
    if (left > 0) {
      reorient_left_handed(m);
      m.warnings.push_back("all " + std::to_string(left) +
                           " hexes are numbered left-handed; reoriented them (mirrored local i and j)");
    }
  }

  // Drop vertices used by no element (boundary-only or orphan nodes).
  {
    std::vector<char> keep(static_cast<size_t>(nv), 0);
    for (Id c : m.conn) keep[c] = 1;
    if (const Id dropped = compact_vertices(m, keep); dropped > 0)
      m.warnings.push_back("dropped " + std::to_string(dropped) + " node(s) used by no " +
                           (m.mode == Mode::Volume ? "hexahedron" : "quadrilateral"));
  }
  // A set's id names it in every output (Exodus set id, MSH physical tag):
  // two sets of one id would merge in MSH and make the Exodus library fail.
  auto once = [&](const char* what, std::vector<Id> ids) {
    std::sort(ids.begin(), ids.end());
    if (const auto d = std::adjacent_find(ids.begin(), ids.end()); d != ids.end())
      throw Error(ErrorKind::BadInput, f + ": two " + what + "s have id " + std::to_string(*d));
  };
  std::vector<Id> ids;
  for (const auto& ss : m.side_sets) ids.push_back(ss.id);
  once("side set", ids);
  ids.clear();
  for (const auto& ns : m.node_sets) ids.push_back(ns.id);
  once("node set", std::move(ids));
  for (auto& ss : m.side_sets) {
    if (ss.element.size() != ss.side.size())
      throw Error(ErrorKind::BadInput, f + ": side set " + std::to_string(ss.id) + ": element and side lists differ");
    for (size_t i = 0; i < ss.element.size(); ++i)
      if (ss.element[i] < 0 || ss.element[i] >= ne || ss.side[i] < 0 || ss.side[i] >= 6)
        throw Error(ErrorKind::BadInput, f + ": side set " + std::to_string(ss.id) + ": entry " + std::to_string(i) +
                                             " is out of range");
  }
  // Coincident and hanging vertices are accepted (an interface may be
  // meant) but said up front, with ids, before hours of dicing.
  // The topology is kept for dicing (topology_of), which would build it again.
  auto topo = std::make_shared<const Topology>(build_topology(m));
  for (auto& w : conformity_warnings(m, check_coarse_conformity(m, *topo))) m.warnings.push_back(std::move(w));
  // Quads that do not all run one way round (a Moebius strip, flipped
  // quads) are diced as they are, but verify fails them (misoriented
  // edges): said up front, as verify counts them.
  if (m.mode == Mode::Surface) {
    const Id edges = topo->num_edges();
    std::vector<std::int8_t> uses(static_cast<size_t>(edges), 0), way(static_cast<size_t>(edges), 0);
    for (Id h = 0; h < ne; ++h)
      for (int k = 0; k < 4; ++k) {
        const Id e = topo->elem_edge[static_cast<size_t>(h) * 4 + k];
        const Id a = m.conn[static_cast<size_t>(h) * 4 + kQuadEdge[k][0]], b = m.conn[static_cast<size_t>(h) * 4 + kQuadEdge[k][1]];
        if (uses[e] < 3) ++uses[e];
        way[e] = static_cast<std::int8_t>(way[e] + (a < b ? 1 : -1) * kQuadEdgeCyclic[k]);
      }
    Id bad = 0, first = -1;
    for (Id e = 0; e < edges; ++e)
      if (uses[e] == 2 && way[e] != 0 && bad++ == 0) first = e;
    if (bad > 0)
      m.warnings.push_back(
          "the quadrilaterals do not all run one way round: " + std::to_string(bad) +
          " coarse edge(s) are traversed the same way by both their quads (the first between nodes " +
          std::to_string(m.vertex_file_id[topo->edge_v[2 * first]]) + " and " +
          std::to_string(m.vertex_file_id[topo->edge_v[2 * first + 1]]) +
          "): flipped quads, or a surface with no orientation (a Moebius strip). It is diced as it is; verify "
          "reports these edges as misoriented and fails");
  }
  keep_topology(m, std::move(topo));
}

}  // namespace dicer
