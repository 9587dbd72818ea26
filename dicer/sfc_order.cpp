// Locality: coarse elements along a Morton (Z-order) curve of their
// centroids, vertices in order of first use. Pages of every table then hold
// neighbours, so a sweep or a box query touches few pages.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "dicer/coarse_mesh.hpp"

namespace dicer {
namespace {

// Spreads the low 21 bits of v so that two zero bits separate each.
std::uint64_t spread3(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffull;
  v = (v | v << 16) & 0x1f0000ff0000ffull;
  v = (v | v << 8) & 0x100f00f00f00f00full;
  v = (v | v << 4) & 0x10c30c30c30c30c3ull;
  v = (v | v << 2) & 0x1249249249249249ull;
  return v;
}

}  // namespace

CoarseMesh sfc_order(const CoarseMesh& in, std::vector<Id>* old_vertex_of_new, std::vector<Id>* old_element_of_new,
                     bool morton) {
  const int nc = in.corners_per_element();
  const Id ne = in.num_elements(), nv = in.num_vertices();
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  const std::vector<double>* X[3] = {&in.x, &in.y, &in.z};
  for (int d = 0; d < 3; ++d)
    for (double v : *X[d]) lo[d] = std::min(lo[d], v), hi[d] = std::max(hi[d], v);
  std::vector<std::pair<std::uint64_t, Id>> key(static_cast<size_t>(ne));
  for (Id e = 0; e < ne; ++e) {
    std::uint64_t code = 0;
    for (int d = 0; d < 3; ++d) {
      double c = 0;
      for (int q = 0; q < nc; ++q) c += (*X[d])[in.conn[static_cast<size_t>(e) * nc + q]];
      c /= nc;
      const double span = hi[d] - lo[d];
      const double t = span > 0 ? (c - lo[d]) / span : 0.0;
      code |= spread3(static_cast<std::uint64_t>(std::clamp(t, 0.0, 1.0) * 2097151.0)) << d;
    }
    key[e] = {morton ? code : 0, e};
  }
  std::sort(key.begin(), key.end());  // ties keep file order (second key)

  CoarseMesh out;
  out.source = in.source;
  out.mode = in.mode;
  out.blocks = in.blocks;
  out.warnings = in.warnings;
  std::vector<Id> new_of_old_vertex(static_cast<size_t>(nv), -1), new_of_old_element(static_cast<size_t>(ne));
  std::vector<Id> old_of_new_vertex;
  old_of_new_vertex.reserve(static_cast<size_t>(nv));
  out.conn.reserve(in.conn.size());
  for (Id k = 0; k < ne; ++k) {
    const Id e = key[k].second;
    new_of_old_element[e] = k;
    for (int q = 0; q < nc; ++q) {
      const Id v = in.conn[static_cast<size_t>(e) * nc + q];
      if (new_of_old_vertex[v] < 0) {
        new_of_old_vertex[v] = static_cast<Id>(old_of_new_vertex.size());
        old_of_new_vertex.push_back(v);
      }
      out.conn.push_back(new_of_old_vertex[v]);
    }
    out.element_file_id.push_back(in.element_file_id[e]);
    out.element_block.push_back(in.element_block[e]);
    if (!in.mid.empty()) {
      const size_t slots = static_cast<size_t>(mid_slots(in.mode));
      out.mid.insert(out.mid.end(), in.mid.begin() + static_cast<std::ptrdiff_t>(e * slots),
                     in.mid.begin() + static_cast<std::ptrdiff_t>((e + 1) * slots));
    }
  }
  // Mid nodes keep their numbering: elements index them, vertices do not.
  out.mid_x = in.mid_x, out.mid_y = in.mid_y, out.mid_z = in.mid_z, out.mid_file_id = in.mid_file_id;
  // Validated meshes use every vertex; keep any stragglers at the end.
  for (Id v = 0; v < nv; ++v)
    if (new_of_old_vertex[v] < 0) new_of_old_vertex[v] = static_cast<Id>(old_of_new_vertex.size()), old_of_new_vertex.push_back(v);
  for (Id v : old_of_new_vertex) {
    out.x.push_back(in.x[v]), out.y.push_back(in.y[v]), out.z.push_back(in.z[v]);
    out.vertex_file_id.push_back(in.vertex_file_id[v]);
    if (!in.vertex_geo_dim.empty()) out.vertex_geo_dim.push_back(in.vertex_geo_dim[v]);
    if (!in.vertex_geo_tag.empty()) out.vertex_geo_tag.push_back(in.vertex_geo_tag[v]);
  }
  out.geo_entities = in.geo_entities;
  for (const auto& ss : in.side_sets) {
    SideSet s = ss;
    for (Id& e : s.element) e = new_of_old_element[e];
    out.side_sets.push_back(std::move(s));
  }
  for (const auto& ns : in.node_sets) {
    NodeSet s = ns;
    for (Id& v : s.vertex) v = new_of_old_vertex[v];
    out.node_sets.push_back(std::move(s));
  }
  if (old_vertex_of_new) *old_vertex_of_new = std::move(old_of_new_vertex);
  if (old_element_of_new) {
    old_element_of_new->resize(static_cast<size_t>(ne));
    for (Id k = 0; k < ne; ++k) (*old_element_of_new)[k] = key[k].second;
  }
  return out;
}

}  // namespace dicer
