#include "dicer/sheets.hpp"

#include <algorithm>
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
  std::vector<std::pair<Id, std::int32_t>> pairs;
  const int epe = t.edges_per_element();
  for (Id h = 0; h < t.num_elements(); ++h)
    for (int k = 0; k < epe; ++k) pairs.emplace_back(s.edge_sheet[t.elem_edge[h * epe + k]], mesh.element_block[h]);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  s.block_offset.assign(static_cast<size_t>(s.num_sheets()) + 1, 0);
  for (const auto& p : pairs) ++s.block_offset[p.first + 1];
  for (Id i = 0; i < s.num_sheets(); ++i) s.block_offset[i + 1] += s.block_offset[i];
  for (const auto& p : pairs) s.block_index.push_back(p.second);
  return s;
}

}  // namespace dicer
