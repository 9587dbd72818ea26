#include "dicer/sheets.hpp"

#include <algorithm>
#include <array>
#include <numeric>

namespace dicer {
namespace {

struct UnionFind {
  std::vector<Id> parent;
  explicit UnionFind(Id n) : parent(static_cast<size_t>(n)) { std::iota(parent.begin(), parent.end(), Id{0}); }
  Id find(Id a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  // The smaller id becomes the root so roots are the lowest edge of a sheet.
  void unite(Id a, Id b) {
    a = find(a), b = find(b);
    if (a == b) return;
    if (a < b) parent[b] = a;
    else parent[a] = b;
  }
};

}  // namespace

Sheets find_sheets(const CoarseMesh& mesh, const Topology& t) {
  const Id ne = t.num_edges(), nf = t.num_faces();
  UnionFind uf(ne);
  for (Id f = 0; f < nf; ++f) {
    uf.unite(t.face_edge[4 * f + 0], t.face_edge[4 * f + 1]);
    uf.unite(t.face_edge[4 * f + 2], t.face_edge[4 * f + 3]);
  }
  Sheets s;
  s.edge_sheet.resize(static_cast<size_t>(ne));
  std::vector<Id> root_sheet(static_cast<size_t>(ne), -1);
  for (Id e = 0; e < ne; ++e) {  // roots are met in increasing order
    const Id r = uf.find(e);
    if (root_sheet[r] < 0) {
      root_sheet[r] = s.num_sheets();
      s.edge_count.push_back(0);
    }
    s.edge_sheet[e] = root_sheet[r];
    ++s.edge_count[root_sheet[r]];
  }
  // (sheet, block) pairs, each element's own distinct sheets first: the
  // parallel edges of an element share a sheet, so 3 pairs an element (2
  // for a quad) where one per edge held 12 (192 bytes a hex, the peak of
  // dicing a large mesh).
  std::vector<std::pair<Id, std::int32_t>> pairs;
  const int epe = t.edges_per_element();
  pairs.reserve(static_cast<size_t>(t.num_elements()) * (epe == 12 ? 3 : 2));
  for (Id h = 0; h < t.num_elements(); ++h) {
    std::array<Id, 12> mine;
    mine.fill(-1);  // a quad's 8 unused slots: one -1, skipped
    for (int k = 0; k < epe; ++k) mine[k] = s.edge_sheet[t.elem_edge[h * epe + k]];
    std::sort(mine.begin(), mine.end());
    const auto end = std::unique(mine.begin(), mine.end());
    for (auto it = mine.begin(); it != end; ++it)
      if (*it >= 0) pairs.emplace_back(*it, mesh.element_block[h]);
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  s.block_offset.assign(static_cast<size_t>(s.num_sheets()) + 1, 0);
  for (const auto& p : pairs) ++s.block_offset[p.first + 1];
  for (Id i = 0; i < s.num_sheets(); ++i) s.block_offset[i + 1] += s.block_offset[i];
  for (const auto& p : pairs) s.block_index.push_back(p.second);
  return s;
}

SheetDirections orient_sheets(const Topology& t, const Sheets& s) {
  const Id ne = t.num_edges(), nf = t.num_faces();
  // Each face links its opposite sides; `same` when both run the face's
  // axis the same way in their canonical (lo -> hi) directions. CSR.
  std::vector<Id> offset(static_cast<size_t>(ne) + 1, 0);
  for (Id f = 0; f < nf; ++f)
    for (int k = 0; k < 4; ++k) ++offset[t.face_edge[4 * f + k] + 1];
  for (Id e = 0; e < ne; ++e) offset[e + 1] += offset[e];
  std::vector<Id> fill(offset.begin(), offset.end() - 1), link(static_cast<size_t>(offset.back()));
  std::vector<std::uint8_t> same(link.size());
  for (Id f = 0; f < nf; ++f) {
    const Id* v = &t.face_v[4 * f];
    for (int k = 0; k < 4; k += 2) {
      const Id a = t.face_edge[4 * f + k], b = t.face_edge[4 * f + k + 1];
      const bool fa = v[kQuadEdge[k][0]] < v[kQuadEdge[k][1]], fb = v[kQuadEdge[k + 1][0]] < v[kQuadEdge[k + 1][1]];
      link[fill[a]] = b, same[fill[a]++] = fa == fb;
      link[fill[b]] = a, same[fill[b]++] = fa == fb;
    }
  }
  SheetDirections d;
  d.edge_flip.assign(static_cast<size_t>(ne), 0);
  d.twisted.assign(static_cast<size_t>(s.num_sheets()), 0);
  std::vector<std::uint8_t> seen(static_cast<size_t>(ne), 0);
  std::vector<Id> queue;
  for (Id root = 0; root < ne; ++root) {  // the first edge met of a sheet is its lowest
    if (seen[root]) continue;
    seen[root] = 1;
    queue.assign(1, root);
    while (!queue.empty()) {
      const Id e = queue.back();
      queue.pop_back();
      for (Id i = offset[e]; i < offset[e + 1]; ++i) {
        const Id o = link[i];
        const std::uint8_t flip = d.edge_flip[e] ^ (same[i] ? 0 : 1);
        if (!seen[o]) {
          seen[o] = 1, d.edge_flip[o] = flip;
          queue.push_back(o);
        } else if (d.edge_flip[o] != flip) {
          d.twisted[s.edge_sheet[o]] = 1;
        }
      }
    }
  }
  return d;
}

}  // namespace dicer
