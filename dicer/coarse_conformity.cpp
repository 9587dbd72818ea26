#include "dicer/coarse_conformity.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <unordered_map>

namespace dicer {

namespace {

struct V3 {
  double x, y, z;
};
V3 sub(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 add(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 mul(V3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double dist2(V3 a, V3 b) { return dot(sub(a, b), sub(a, b)); }

V3 closest_on_segment(V3 p, V3 a, V3 b) {
  const V3 ab = sub(b, a);
  const double l = dot(ab, ab);
  const double t = l > 0 ? std::clamp(dot(sub(p, a), ab) / l, 0.0, 1.0) : 0.0;
  return add(a, mul(ab, t));
}

// Closest point of triangle abc to p (Ericson, Real-Time Collision
// Detection, 5.1.5): by Voronoi regions, no division by a zero area.
V3 closest_on_triangle(V3 p, V3 a, V3 b, V3 c) {
  const V3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const V3 bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return add(a, mul(ab, d1 / (d1 - d3)));
  const V3 cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return add(a, mul(ac, d2 / (d2 - d6)));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return add(b, mul(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
  const double denom = va + vb + vc;
  if (!(denom > 0)) return closest_on_segment(p, a, b);  // degenerate triangle
  return add(a, add(mul(ab, vb / denom), mul(ac, vc / denom)));
}

struct Facet {
  Id element;
  int slot;
  int n;              // corners: 4 (quad face) or 2 (edge)
  std::array<Id, 4> v;
  double size;        // longest diagonal or length
};

}  // namespace

CoarseConformity check_coarse_conformity(const CoarseMesh& mesh, const Topology& t, int examples) {
  CoarseConformity out;
  const Id nv = mesh.num_vertices();
  auto P = [&](Id v) { return V3{mesh.x[v], mesh.y[v], mesh.z[v]}; };

  // Coincident: sort by coordinates; equal neighbours coincide (+0.0 and
  // -0.0 too: the same point, whatever the bits).
  {
    std::vector<Id> order(static_cast<size_t>(nv));
    for (Id v = 0; v < nv; ++v) order[v] = v;
    auto key = [&](Id v) { return std::array<double, 3>{mesh.x[v], mesh.y[v], mesh.z[v]}; };
    std::sort(order.begin(), order.end(), [&](Id a, Id b) { return key(a) != key(b) ? key(a) < key(b) : a < b; });
    size_t first = 0;  // start of the current group of equal keys
    for (size_t i = 1; i < order.size(); ++i) {
      if (key(order[i - 1]) != key(order[i])) first = i;
      if (first == i) continue;
      // Every vertex of a group pairs with the group's first.
      ++out.coincident_pairs;
      if (static_cast<int>(out.coincident.size()) < examples)
        out.coincident.push_back({std::min(order[first], order[i]), std::max(order[first], order[i])});
    }
  }

  // Boundary facets: faces with one hex (volume), edges with one quad (surface).
  std::vector<Facet> facets;
  const Id nh = t.num_elements();
  const int nc = mesh.corners_per_element();
  if (t.mode == Mode::Volume) {
    for (Id h = 0; h < nh; ++h)
      for (int k = 0; k < 6; ++k) {
        const Id f = t.elem_face[6 * h + k];
        if (t.face_elem[2 * f + 1] >= 0) continue;
        Facet fa{h, k, 4, {}, 0};
        for (int m = 0; m < 4; ++m) fa.v[m] = mesh.conn[nc * h + kHexFace[k][m]];
        fa.size = std::sqrt(std::max(dist2(P(fa.v[0]), P(fa.v[2])), dist2(P(fa.v[1]), P(fa.v[3]))));
        facets.push_back(fa);
      }
  } else {
    std::vector<std::int32_t> uses(static_cast<size_t>(t.num_edges()), 0);
    for (Id e : t.elem_edge) ++uses[e];
    for (Id h = 0; h < nh; ++h)
      for (int k = 0; k < 4; ++k) {
        if (uses[t.elem_edge[4 * h + k]] != 1) continue;
        Facet fa{h, k, 2, {}, 0};
        fa.v[0] = mesh.conn[nc * h + kQuadEdge[k][0]], fa.v[1] = mesh.conn[nc * h + kQuadEdge[k][1]];
        fa.size = std::sqrt(dist2(P(fa.v[0]), P(fa.v[1])));
        facets.push_back(fa);
      }
  }
  if (facets.empty()) return out;

  // A uniform grid of cells of the median facet size; a facet goes into the
  // cells its (tolerance-grown) box overlaps, at most kMaxCells of them, the
  // rest (few, huge facets) into a list every vertex is checked against.
  std::vector<double> sizes;
  for (const Facet& f : facets) sizes.push_back(f.size);
  std::nth_element(sizes.begin(), sizes.begin() + static_cast<std::ptrdiff_t>(sizes.size() / 2), sizes.end());
  const double cell = std::max(sizes[sizes.size() / 2], 1e-300);
  constexpr double kRel = 1e-6;
  constexpr long long kMaxCells = 64;
  // Clamped to +-2^60: a coordinate far beyond the cell size (a tiny median
  // facet, a huge coordinate) is no long long (a fuzzed mesh found the
  // overflowing cast). A clamped facet still meets the vertices near it
  // there, which clamp the same way.
  auto cell_of = [&](double c) {
    constexpr double kLimit = 0x1p60;
    const double q = std::floor(c / cell);
    return static_cast<long long>(q > kLimit ? kLimit : q < -kLimit ? -kLimit : q == q ? q : 0.0);
  };
  auto hash = [](long long i, long long j, long long k) {
    return static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4Full ^
           static_cast<std::uint64_t>(k) * 0x165667B19E3779F9ull;
  };
  std::unordered_multimap<std::uint64_t, std::uint32_t> grid;
  std::vector<std::uint32_t> huge;
  std::vector<std::uint8_t> on_boundary(static_cast<size_t>(nv), 0);
  for (std::uint32_t i = 0; i < facets.size(); ++i) {
    const Facet& f = facets[i];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int m = 0; m < f.n; ++m) {
      on_boundary[f.v[m]] = 1;
      const V3 p = P(f.v[m]);
      const double c[3] = {p.x, p.y, p.z};
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], c[d] - kRel * f.size), hi[d] = std::max(hi[d], c[d] + kRel * f.size);
    }
    long long a[3], b[3], count = 1;
    bool finite = true;  // an overflowing size or box: no grid cells, the huge list
    for (int d = 0; d < 3; ++d) finite &= std::isfinite(lo[d] / cell) && std::isfinite(hi[d] / cell);
    for (int d = 0; d < 3; ++d) a[d] = cell_of(lo[d]), b[d] = cell_of(hi[d]), count *= std::min(b[d] - a[d] + 1, kMaxCells + 1);
    if (!finite || count > kMaxCells) {
      huge.push_back(i);
      continue;
    }
    for (long long x = a[0]; x <= b[0]; ++x)
      for (long long y = a[1]; y <= b[1]; ++y)
        for (long long z = a[2]; z <= b[2]; ++z) grid.emplace(hash(x, y, z), i);
  }

  auto hangs_in = [&](Id v, const Facet& f) {
    for (int m = 0; m < f.n; ++m)
      if (f.v[m] == v) return false;
    const V3 p = P(v);
    const double tol2 = (kRel * f.size) * (kRel * f.size);
    for (int m = 0; m < f.n; ++m)
      if (dist2(p, P(f.v[m])) <= tol2) return false;  // at a corner: coincident, not hanging
    if (f.n == 2) return dist2(p, closest_on_segment(p, P(f.v[0]), P(f.v[1]))) <= tol2;
    // A (possibly warped) quad as two triangles either way: on the surface
    // within the tolerance if on one of them.
    const V3 a = P(f.v[0]), b = P(f.v[1]), c = P(f.v[2]), d = P(f.v[3]);
    return dist2(p, closest_on_triangle(p, a, b, c)) <= tol2 || dist2(p, closest_on_triangle(p, a, c, d)) <= tol2 ||
           dist2(p, closest_on_triangle(p, a, b, d)) <= tol2 || dist2(p, closest_on_triangle(p, b, c, d)) <= tol2;
  };
  for (Id v = 0; v < nv; ++v) {
    if (!on_boundary[v]) continue;
    const V3 p = P(v);
    const std::uint32_t* found = nullptr;
    auto range = grid.equal_range(hash(cell_of(p.x), cell_of(p.y), cell_of(p.z)));
    for (auto it = range.first; it != range.second && !found; ++it)
      if (hangs_in(v, facets[it->second])) found = &it->second;
    for (size_t k = 0; k < huge.size() && !found; ++k)
      if (hangs_in(v, facets[huge[k]])) found = &huge[k];
    if (!found) continue;
    ++out.hanging_vertices;
    if (static_cast<int>(out.hanging.size()) < examples) out.hanging.push_back({v, facets[*found].element, facets[*found].slot});
  }
  return out;
}

std::vector<std::string> conformity_warnings(const CoarseMesh& mesh, const CoarseConformity& c) {
  std::vector<std::string> w;
  auto vid = [&](Id v) { return std::to_string(mesh.vertex_file_id.empty() ? v + 1 : mesh.vertex_file_id[v]); };
  auto eid = [&](Id e) { return std::to_string(mesh.element_file_id.empty() ? e + 1 : mesh.element_file_id[e]); };
  auto at = [&](Id v) {
    char b[96];
    std::snprintf(b, sizeof b, "(%.17g, %.17g, %.17g)", mesh.x[v], mesh.y[v], mesh.z[v]);
    return std::string(b);
  };
  if (c.coincident_pairs > 0) {
    std::string s = std::to_string(c.coincident_pairs) + " pair(s) of coarse vertices share coordinates (";
    for (size_t i = 0; i < c.coincident.size(); ++i)
      s += (i ? "; " : "") + std::string("nodes ") + vid(c.coincident[i].a) + " and " + vid(c.coincident[i].b) + " at " +
           at(c.coincident[i].a);
    s += c.coincident_pairs > static_cast<Id>(c.coincident.size()) ? "; ...)" : ")";
    s += ": a contact interface or a split mesh; the fine nodes of the coincident edges and faces coincide too "
         "(dicer verify counts them)";
    w.push_back(s);
  }
  if (c.hanging_vertices > 0) {
    const bool vol = mesh.mode == Mode::Volume;
    std::string s = std::to_string(c.hanging_vertices) + " hanging coarse vertice(s) (";
    for (size_t i = 0; i < c.hanging.size(); ++i) {
      const auto& h = c.hanging[i];
      std::string corners;
      for (int m = 0; m < (vol ? 4 : 2); ++m) {
        const int local = vol ? kHexFace[h.slot][m] : kQuadEdge[h.slot][m];
        corners += (m ? " " : "") + vid(mesh.conn[static_cast<size_t>(mesh.corners_per_element() * h.element + local)]);
      }
      s += (i ? "; " : "") + std::string("node ") + vid(h.vertex) + " at " + at(h.vertex) + " inside the boundary " +
           (vol ? "face [" : "edge [") + corners + "] of element " + eid(h.element);
    }
    s += c.hanging_vertices > static_cast<Id>(c.hanging.size()) ? "; ...)" : ")";
    // verify finds a T-junction, not elements that overlap (no face is shared): no promise here.
    s += ": the coarse mesh is non-conforming there (a T-junction, or elements that overlap), and so will be the "
         "fine mesh";
    w.push_back(s);
  }
  return w;
}

}  // namespace dicer
