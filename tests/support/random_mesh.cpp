#include "random_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>

namespace dicer::test {

std::vector<std::array<int, 8>> hex_rotations() {
  // Generators: quarter turns about k (0->1->2->3) and about i.
  const std::array<int, 8> rk = {1, 2, 3, 0, 5, 6, 7, 4};
  const std::array<int, 8> ri = {3, 2, 6, 7, 0, 1, 5, 4};
  std::set<std::array<int, 8>> seen;
  std::vector<std::array<int, 8>> out, todo{{0, 1, 2, 3, 4, 5, 6, 7}};
  while (!todo.empty()) {
    auto p = todo.back();
    todo.pop_back();
    if (!seen.insert(p).second) continue;
    out.push_back(p);
    for (const auto& g : {rk, ri}) {
      std::array<int, 8> q;
      for (int k = 0; k < 8; ++k) q[k] = p[g[k]];
      todo.push_back(q);
    }
  }
  return out;
}

CoarseMesh random_box(const BoxSpec& s, std::mt19937_64& rng) {
  CoarseMesh m;
  m.source = "random_box";
  m.mode = Mode::Volume;
  const int nx = s.a + 1, ny = s.b + 1, nz = s.c + 1;
  std::uniform_real_distribution<double> jitter(-s.perturb, s.perturb);
  const Id nv = static_cast<Id>(nx) * ny * nz;
  std::vector<Id> perm(static_cast<size_t>(nv));
  std::iota(perm.begin(), perm.end(), Id{0});
  if (s.renumber) std::shuffle(perm.begin(), perm.end(), rng);
  m.x.resize(nv), m.y.resize(nv), m.z.resize(nv);
  auto vid = [&](int i, int j, int k) { return perm[i + nx * (j + ny * k)]; };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const bool inner = i > 0 && i < s.a && j > 0 && j < s.b && k > 0 && k < s.c;
        const Id v = vid(i, j, k);
        m.x[v] = i + (inner ? jitter(rng) : 0.0);
        m.y[v] = 1.3 * j + (inner ? jitter(rng) : 0.0);
        m.z[v] = 0.7 * k + (inner ? jitter(rng) : 0.0);
      }
  const auto rots = hex_rotations();
  std::uniform_int_distribution<size_t> pick(0, rots.size() - 1);
  m.blocks.clear();
  for (int b = 0; b < s.blocks; ++b) m.blocks.push_back({10 + b, "slab" + std::to_string(b)});
  for (int k = 0; k < s.c; ++k)
    for (int j = 0; j < s.b; ++j)
      for (int i = 0; i < s.a; ++i) {
        const Id c[8] = {vid(i, j, k),         vid(i + 1, j, k),         vid(i + 1, j + 1, k),
                         vid(i, j + 1, k),     vid(i, j, k + 1),         vid(i + 1, j, k + 1),
                         vid(i + 1, j + 1, k + 1), vid(i, j + 1, k + 1)};
        const auto& r = s.rotate ? rots[pick(rng)] : rots[0];
        for (int q = 0; q < 8; ++q) m.conn.push_back(c[r[q]]);
        m.element_block.push_back(std::min(s.blocks - 1, i * s.blocks / std::max(1, s.a)));
      }
  validate_coarse_mesh(m);
  return m;
}

CoarseMesh random_quad_sheet(int a, int b, bool renumber, std::mt19937_64& rng) {
  CoarseMesh m;
  m.source = "random_quad_sheet";
  m.mode = Mode::Surface;
  const int nx = a + 1, ny = b + 1;
  const Id nv = static_cast<Id>(nx) * ny;
  std::vector<Id> perm(static_cast<size_t>(nv));
  std::iota(perm.begin(), perm.end(), Id{0});
  if (renumber) std::shuffle(perm.begin(), perm.end(), rng);
  m.x.resize(nv), m.y.resize(nv), m.z.resize(nv);
  auto vid = [&](int i, int j) { return perm[i + nx * j]; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Id v = vid(i, j);
      const double th = 0.25 * i;
      m.x[v] = 3 * std::cos(th), m.y[v] = 3 * std::sin(th), m.z[v] = 0.5 * j;
    }
  std::uniform_int_distribution<int> rot(0, 3);
  for (int j = 0; j < b; ++j)
    for (int i = 0; i < a; ++i) {
      const Id c[4] = {vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)};
      const int r = renumber ? rot(rng) : 0;
      for (int q = 0; q < 4; ++q) m.conn.push_back(c[(q + r) % 4]);
    }
  validate_coarse_mesh(m);
  return m;
}

}  // namespace dicer::test
