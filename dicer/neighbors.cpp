// Fine element adjacency (neighbors.hpp).
#include "dicer/neighbors.hpp"

#include <algorithm>
#include <string>

#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"

namespace dicer {

namespace {

// Local (p, q) of canonical (u, v) under a face map: its matrix is a signed
// permutation, so the inverse is the transpose.
std::array<Id, 2> unmap(const FaceMap& m, Id u, Id v) {
  const Id du = u - m.u0, dv = v - m.v0;
  return {m.up * du + m.vp * dv, m.uq * du + m.vq * dv};
}

Id across_face(const RowReader& R, Id h, const ElementRow& r, int lf, const std::array<Id, 3>& c) {
  const Id f = r.face[lf];
  const FaceRow fr = R.face(f);
  const Id h2 = fr.owner_element == h ? fr.other_element : fr.owner_element;
  if (h2 < 0) return -1;
  // The fine face's cell in canonical (u, v): the lower corner of its image.
  const auto [nu, nv] = face_intervals(r, lf, Mode::Volume);
  const FaceMap fm = face_map(r.code(lf), nu, nv);
  const Id p = c[kHexFaceAxes[lf][0]], q = c[kHexFaceAxes[lf][1]];
  const Id cu = std::min(fm.u(p, q), fm.u(p + 1, q + 1)), cv = std::min(fm.v(p, q), fm.v(p + 1, q + 1));
  const ElementRow r2 = R.element(h2);
  int lf2 = 0;
  while (lf2 < 6 && r2.face[lf2] != f) ++lf2;
  if (lf2 == 6)
    throw Error(ErrorKind::Corrupt, "coarse element " + std::to_string(h2) + " does not use face " + std::to_string(f) +
                                        " that names it as a neighbour");
  const auto [nu2, nv2] = face_intervals(r2, lf2, Mode::Volume);
  const FaceMap g = face_map(r2.code(lf2), nu2, nv2);
  const auto a = unmap(g, cu, cv), b = unmap(g, cu + 1, cv + 1);
  std::array<Id, 3> c2;
  const int axis = lf2 / 2;
  c2[axis] = lf2 % 2 ? r2.n[axis] - 1 : 0;
  c2[kHexFaceAxes[lf2][0]] = std::min(a[0], b[0]);
  c2[kHexFaceAxes[lf2][1]] = std::min(a[1], b[1]);
  return ids::element(r2.element_first, r2.n, c2[0], c2[1], c2[2]);
}

Id across_edge(const RowReader& R, Id h, const ElementRow& r, int axis, bool high, const std::array<Id, 3>& c) {
  const int along = 1 - axis;
  const int le = quad_edge_at(along, high ? 1 : 0);
  const Id e = r.edge[le];
  const EdgeRow er = R.edge(e);
  const Id h2 = er.owner_element == h ? er.other_element : er.owner_element;
  if (h2 < 0) return -1;
  const Id n = r.n[along];
  const Id tc = r.rev(le) ? n - 1 - c[along] : c[along];  // the fine segment, canonical direction
  const ElementRow r2 = R.element(h2);
  int le2 = 0;
  while (le2 < 4 && r2.edge[le2] != e) ++le2;
  if (le2 == 4)
    throw Error(ErrorKind::Corrupt, "coarse element " + std::to_string(h2) + " does not use edge " + std::to_string(e) +
                                        " that names it as a neighbour");
  const int along2 = le2 < 2 ? 0 : 1, other2 = 1 - along2;  // kQuadEdge: 0, 1 along i; 2, 3 along j
  std::array<Id, 3> c2{0, 0, 0};
  c2[along2] = r2.rev(le2) ? r2.n[along2] - 1 - tc : tc;
  c2[other2] = le2 % 2 ? r2.n[other2] - 1 : 0;
  return ids::element(r2.element_first, r2.n, c2[0], c2[1], 0);
}

// Grid point of node `ref` in its owner element: (h, i, j, k).
Id owner_grid_point(const RowReader& R, const NodeRef& ref, Mode mode, std::array<Id, 3>& g) {
  const bool vol = mode == Mode::Volume;
  Id h = -1;
  g = {0, 0, 0};
  switch (ref.kind) {
    case EntityKind::Cell:
      h = ref.entity;
      g = ref.local;
      break;
    case EntityKind::Vertex: {
      const VertexRow vr = R.vertex(ref.entity);
      h = vr.owner_element;
      const ElementRow r = R.element(h);
      for (int d = 0; d < (vol ? 3 : 2); ++d) g[d] = kHexCorner[vr.corner][d] * r.n[d];
      break;
    }
    case EntityKind::Edge: {
      const EdgeRow er = R.edge(ref.entity);
      h = er.owner_element;
      const ElementRow r = R.element(h);
      const int ne = vol ? 12 : 4;
      int le = 0;
      while (le < ne && r.edge[le] != ref.entity) ++le;
      if (le == ne) throw Error(ErrorKind::Corrupt, "coarse element " + std::to_string(h) + " does not use its edge");
      const int a = vol ? le / 4 : (le < 2 ? 0 : 1);
      const int c0 = vol ? kHexEdge[le][0] : kQuadEdge[le][0];
      for (int d = 0; d < (vol ? 3 : 2); ++d) g[d] = kHexCorner[c0][d] * r.n[d];
      g[a] = r.rev(le) ? r.n[a] - ref.local[0] : ref.local[0];
      break;
    }
    case EntityKind::Face: {
      const FaceRow fr = R.face(ref.entity);
      h = fr.owner_element;
      const ElementRow r = R.element(h);
      int lf = 0;
      if (vol) {
        while (lf < 6 && r.face[lf] != ref.entity) ++lf;
        if (lf == 6) throw Error(ErrorKind::Corrupt, "coarse element " + std::to_string(h) + " does not use its face");
      }
      const auto [nu, nv] = face_intervals(r, lf, mode);
      const auto pq = unmap(face_map(r.code(lf), nu, nv), ref.local[0], ref.local[1]);
      if (vol) {
        g[lf / 2] = lf % 2 ? r.n[lf / 2] : 0;
        g[kHexFaceAxes[lf][0]] = pq[0], g[kHexFaceAxes[lf][1]] = pq[1];
      } else {
        g = {pq[0], pq[1], 0};
      }
      break;
    }
  }
  return h;
}

}  // namespace

std::vector<Id> node_elements(const FineMesh& mesh, Id id) {
  if (id < 0 || id >= mesh.num_nodes())
    throw Error(ErrorKind::Usage, "node id " + std::to_string(id) + " out of range (the mesh has " +
                                      std::to_string(mesh.num_nodes()) + " nodes)");
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  std::array<Id, 3> g;
  const Id h = owner_grid_point(R, mesh.locate_node(id, cur), mesh.mode(), g);
  const ElementRow r = R.element(h);
  const Id start = ids::element(r.element_first, r.n, std::min(g[0], r.n[0] - 1), std::min(g[1], r.n[1] - 1),
                                mesh.mode() == Mode::Volume ? std::min(g[2], r.n[2] - 1) : 0);
  const int nc = mesh.corners();
  auto uses = [&](Id e) {
    const FineElement el = mesh.element(e, cur);
    return std::find(el.nodes.begin(), el.nodes.begin() + nc, id) != el.nodes.begin() + nc;
  };
  if (!uses(start))
    throw Error(ErrorKind::Corrupt, "node " + std::to_string(id) + " is not a node of element " + std::to_string(start) +
                                        " where its owner row places it");
  std::vector<Id> found{start}, todo{start};
  while (!todo.empty()) {
    const Id e = todo.back();
    todo.pop_back();
    for (Id n : element_neighbors(mesh, e))
      if (n >= 0 && std::find(found.begin(), found.end(), n) == found.end() && uses(n)) found.push_back(n), todo.push_back(n);
  }
  std::sort(found.begin(), found.end());
  return found;
}

std::vector<Id> element_neighbors(const FineMesh& mesh, Id id) {
  if (id < 0 || id >= mesh.num_elements())
    throw Error(ErrorKind::Usage, "element id " + std::to_string(id) + " out of range (the mesh has " +
                                      std::to_string(mesh.num_elements()) + " elements)");
  MeshCursor cur;
  std::array<Id, 3> c;
  const Id h = mesh.locate_element(id, c, cur);
  const RowReader R(mesh.tables(), cur);
  const ElementRow r = R.element(h);
  const bool vol = mesh.mode() == Mode::Volume;
  std::vector<Id> out(vol ? 6 : 4, -1);
  for (int s = 0; s < static_cast<int>(out.size()); ++s) {
    const SidePlane sp = exodus_side_plane(mesh.mode(), vol ? s : s + 2);
    const int a = sp.axis;
    if (sp.high ? c[a] + 1 < r.n[a] : c[a] > 0) {
      std::array<Id, 3> c2 = c;
      c2[a] += sp.high ? 1 : -1;
      out[s] = ids::element(r.element_first, r.n, c2[0], c2[1], c2[2]);
    } else {
      out[s] = vol ? across_face(R, h, r, 2 * a + (sp.high ? 1 : 0), c) : across_edge(R, h, r, a, sp.high, c);
    }
  }
  return out;
}

}  // namespace dicer
