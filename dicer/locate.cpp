// Point location (locate.hpp): index -> bounds -> corner map -> fine cell.
#include "dicer/locate.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"

namespace dicer {

using Corners = std::array<std::array<double, 3>, 8>;
using P3 = std::array<double, 3>;

P3 trilinear(const Corners& x, const P3& xi) {
  P3 out{0, 0, 0};
  for (int q = 0; q < 8; ++q) {
    double w = 1;
    for (int d = 0; d < 3; ++d) w *= kHexCorner[q][d] ? xi[d] : 1 - xi[d];
    for (int d = 0; d < 3; ++d) out[d] += w * x[q][d];
  }
  return out;
}

namespace {

double size_of(const Corners& x) {
  double s = 0;
  for (int d = 0; d < 3; ++d) s = std::max(s, std::abs(x[6][d] - x[0][d]));
  for (int q = 1; q < 8; ++q)
    for (int d = 0; d < 3; ++d) s = std::max(s, std::abs(x[q][d] - x[0][d]));
  return s;
}

// Newton on the trilinear map: xi with map(xi) = p, false when it does not
// converge (degenerate or far outside). Plain 3x3 solve by Cramer's rule.
bool invert(const Corners& x, const P3& p, P3& xi) {
  xi = {0.5, 0.5, 0.5};
  const double h = size_of(x);
  if (!(h > 0)) return false;
  for (int it = 0; it < 40; ++it) {
    P3 r = trilinear(x, xi);
    for (int d = 0; d < 3; ++d) r[d] -= p[d];
    double J[3][3] = {};  // J[d][a] = dx_d / dxi_a
    for (int q = 0; q < 8; ++q)
      for (int a = 0; a < 3; ++a) {
        double w = kHexCorner[q][a] ? 1.0 : -1.0;
        for (int b = 0; b < 3; ++b)
          if (b != a) w *= kHexCorner[q][b] ? xi[b] : 1 - xi[b];
        for (int d = 0; d < 3; ++d) J[d][a] += w * x[q][d];
      }
    const double det = J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) -
                       J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) +
                       J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
    if (!(std::abs(det) > 1e-300)) return false;
    P3 dx;
    for (int a = 0; a < 3; ++a) {
      double M[3][3];
      for (int d = 0; d < 3; ++d)
        for (int b = 0; b < 3; ++b) M[d][b] = b == a ? r[d] : J[d][b];
      dx[a] = (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) - M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
               M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0])) /
              det;
    }
    double step = 0;
    for (int a = 0; a < 3; ++a) xi[a] -= dx[a], step = std::max(step, std::abs(dx[a]));
    if (!std::isfinite(step) || step > 1e6) return false;
    if (step < 1e-15) break;
  }
  P3 r = trilinear(x, xi);
  double err = 0;
  for (int d = 0; d < 3; ++d) err = std::max(err, std::abs(r[d] - p[d]));
  return err <= kLocateTolerance * h;
}

bool inside(const P3& xi) {
  for (double v : xi)
    if (!(v >= -kLocateTolerance && v <= 1 + kLocateTolerance)) return false;
  return true;
}

// Groups per super-group: a second level built in memory per call (the
// union of kSuper group boxes), so a point tests O(G / kSuper + kSuper)
// boxes, not all G.
constexpr Id kSuper = 64;

std::vector<double> super_bounds(const std::vector<double>& groups) {
  const size_t G = groups.size() / 6, S = (G + kSuper - 1) / kSuper;
  std::vector<double> out(S * 6);
  for (size_t s = 0; s < S; ++s) {
    double* o = &out[s * 6];
    for (int d = 0; d < 3; ++d) o[d] = INFINITY, o[3 + d] = -INFINITY;
    for (size_t g = s * kSuper; g < std::min(G, (s + 1) * kSuper); ++g)
      for (int d = 0; d < 3; ++d) o[d] = std::min(o[d], groups[g * 6 + d]), o[3 + d] = std::max(o[3 + d], groups[g * 6 + 3 + d]);
  }
  return out;
}

struct Searcher {
  const FineMesh& mesh;
  const std::vector<double>& super;
  MeshCursor cur;

  Corners cell_nodes(Id id) {
    const FineElement el = mesh.element(id, cur);
    Corners x;
    for (int q = 0; q < 8; ++q) {
      const Vec3 v = mesh.node(el.nodes[q], cur);
      x[q] = {v.x, v.y, v.z};
    }
    return x;
  }

  // The cell (i, j, k) of coarse element row r contains p: xi of it.
  bool in_cell(const ElementRow& r, const std::array<Id, 3>& c, const P3& p, P3& xi) {
    return invert(cell_nodes(ids::element(r.element_first, r.n, c[0], c[1], c[2])), p, xi) && inside(xi);
  }

  // Lowest-id cell of coarse element h containing p.
  bool in_element(Id h, const P3& p, Located& out) {
    const RowReader R(mesh.tables(), cur);
    const ElementRow r = R.element(h);
    Vec3 v[8];
    R.corner_xyz(h, v);
    Corners x;
    for (int q = 0; q < 8; ++q) x[q] = {v[q].x, v[q].y, v[q].z};
    P3 g{0.5, 0.5, 0.5};
    const bool guessed = invert(x, p, g);
    if (!r.curved()) {
      // A straight element is its corners' trilinear map (TFI reproduces
      // it) and its cell (i, j, k) that map on [i/n, (i+1)/n] x ...: the
      // cell and xi follow from g without reading a fine node. Inside a
      // valid straight hex Newton converges; where it does not, the point
      // is outside. The lowest id: the lowest cell that holds the point.
      if (!guessed) return false;
      Id best = -1;
      for (int mask = 0; mask < 8; ++mask) {
        std::array<Id, 3> c;
        P3 xi;
        bool ok = true;
        for (int d = 0; d < 3 && ok; ++d) {
          const double t = g[d] * static_cast<double>(r.n[d]);
          c[d] = std::clamp<Id>(static_cast<Id>(std::floor(t)), 0, r.n[d] - 1) - (mask >> d & 1);
          xi[d] = t - static_cast<double>(c[d]);
          ok = c[d] >= 0 && xi[d] >= -kLocateTolerance && xi[d] <= 1 + kLocateTolerance;
        }
        if (!ok) continue;
        const Id id = ids::element(r.element_first, r.n, c[0], c[1], c[2]);
        if (best < 0 || id < best) best = id, out.xi = xi;
      }
      out.element = best;
      return best >= 0;
    }
    std::array<Id, 3> c;
    for (int d = 0; d < 3; ++d)
      c[d] = std::clamp<Id>(static_cast<Id>(std::floor((guessed ? g[d] : 0.5) * static_cast<double>(r.n[d]))), 0, r.n[d] - 1);
    P3 xi;
    bool found = false;
    // Walk: a step towards the point along every direction it lies beyond.
    // Blocked: the point lies beyond a boundary cell's outer face (the
    // element's boundary, locally nearly flat at a fine cell's scale): it is
    // outside. The walk ends undecided only when a cell's map cannot be
    // inverted or the steps run out (a cycle).
    const Id steps = r.n[0] + r.n[1] + r.n[2] + 3;
    bool blocked = false;
    for (Id step = 0; step < steps; ++step) {
      if (!invert(cell_nodes(ids::element(r.element_first, r.n, c[0], c[1], c[2])), p, xi)) break;
      if (inside(xi)) {
        found = true;
        break;
      }
      bool moved = false;
      for (int d = 0; d < 3; ++d) {
        if (xi[d] < -kLocateTolerance && c[d] > 0) --c[d], moved = true;
        else if (xi[d] > 1 + kLocateTolerance && c[d] < r.n[d] - 1) ++c[d], moved = true;
      }
      if (!moved) {
        blocked = true;
        break;
      }
    }
    if (!found && !blocked) {
      // Undecided: every cell, in id order.
      auto scan = [&] {
        for (Id k = 0; k < r.n[2]; ++k)
          for (Id j = 0; j < r.n[1]; ++j)
            for (Id i = 0; i < r.n[0]; ++i)
              if (c = {i, j, k}; in_cell(r, c, p, xi)) return true;
        return false;
      };
      found = scan();
    }
    if (!found) return false;
    // On a face, edge or node shared with lower cells of this element: the
    // lowest id among them (lower i, j or k is a lower id).
    Id best = ids::element(r.element_first, r.n, c[0], c[1], c[2]);
    P3 best_xi = xi;
    for (int mask = 1; mask < 8; ++mask) {
      std::array<Id, 3> c2 = c;
      bool ok = true;
      for (int d = 0; d < 3 && ok; ++d)
        if (mask >> d & 1) {
          if (c[d] == 0 || xi[d] > kLocateTolerance) ok = false;
          else --c2[d];
        }
      if (!ok) continue;
      P3 xi2;
      const Id id = ids::element(r.element_first, r.n, c2[0], c2[1], c2[2]);
      if (id < best && in_cell(r, c2, p, xi2)) best = id, best_xi = xi2;
    }
    out.element = best;
    out.xi = best_xi;
    return true;
  }

  Located locate(const P3& p) {
    const MeshTables& t = mesh.tables();
    const RowReader R(t, cur);
    const Id H = mesh.num_coarse_elements();
    Located out;
    auto hit = [&](const double* q) {
      for (int d = 0; d < 3; ++d) {
        const double pad = kLocateTolerance * (q[3 + d] - q[d] + std::abs(q[d]) + std::abs(q[3 + d]));
        if (p[d] < q[d] - pad || p[d] > q[3 + d] + pad) return false;
      }
      return true;
    };
    const Id G = (H + kBoundsGroup - 1) / kBoundsGroup;
    for (Id sg = 0; sg * kSuper < G; ++sg) {
      if (!hit(&super[static_cast<size_t>(sg) * 6])) continue;
      for (Id g = sg * kSuper; g < std::min(G, (sg + 1) * kSuper); ++g) {
        if (!hit(&t.group_bounds[static_cast<size_t>(g) * 6])) continue;
        // Coarse elements in order: element ids grow with them, so the
        // first one that contains the point holds the lowest id.
        for (Id h = g * kBoundsGroup; h < std::min(H, (g + 1) * kBoundsGroup); ++h) {
          const ElementBounds b = R.bounds(h);
          double ext = 0;
          for (int d = 0; d < 3; ++d) ext = std::max({ext, b.hi[d] - b.lo[d], std::abs(b.lo[d]), std::abs(b.hi[d])});
          if (!b.contains({p[0], p[1], p[2]}, kLocateTolerance * ext)) continue;
          if (in_element(h, p, out)) return out;
        }
      }
    }
    return out;
  }
};

void require_volume(const FineMesh& mesh) {
  if (mesh.mode() != Mode::Volume)
    throw Error(ErrorKind::Usage, "point location reads volume (hex) stores; this one is a surface (quad) store");
  const size_t groups = static_cast<size_t>((mesh.num_coarse_elements() + kBoundsGroup - 1) / kBoundsGroup);
  if (mesh.tables().group_bounds.size() != groups * 6)
    throw Error(ErrorKind::Corrupt, "the spatial index does not have one box per group of coarse elements");
}

}  // namespace

Located locate_point(const FineMesh& mesh, const std::array<double, 3>& p) {
  require_volume(mesh);
  const std::vector<double> super = super_bounds(mesh.tables().group_bounds);
  Searcher s{mesh, super, {}};
  return s.locate(p);
}

std::vector<Located> locate_points(const FineMesh& mesh, const std::vector<double>& xyz, int threads) {
  require_volume(mesh);
  if (xyz.size() % 3 != 0) throw Error(ErrorKind::Usage, "locate_points: coordinates are not a multiple of 3");
  const size_t n = xyz.size() / 3;
  std::vector<Located> out(n);
  threads = std::max(1, std::min<int>(threads, static_cast<int>(std::max<size_t>(1, n / 64))));
  const std::vector<double> super = super_bounds(mesh.tables().group_bounds);
  auto work = [&](size_t first, size_t end) {
    Searcher s{mesh, super, {}};
    for (size_t i = first; i < end; ++i) out[i] = s.locate({xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]});
  };
  if (threads == 1) {
    work(0, n);
    return out;
  }
  std::vector<std::thread> pool;
  std::vector<std::exception_ptr> errors(static_cast<size_t>(threads));
  for (int k = 0; k < threads; ++k)
    pool.emplace_back([&, k] {
      try {
        work(n * k / threads, n * (k + 1) / threads);
      } catch (...) {
        errors[k] = std::current_exception();
      }
    });
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  return out;
}

}  // namespace dicer
