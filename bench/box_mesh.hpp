#pragma once
// A generated box of coarse hexes, apart from bench_util.hpp so that a
// program without Google Benchmark (sweep_scaling) can use it.
#include <string>

#include "dicer/coarse_mesh.hpp"

namespace dicer::bench {

// nx x ny x nz unit hexes in one block, vertices numbered x fastest, hexes
// in HEX8 order (bottom face then top face, counter-clockwise seen from +z):
// the mesh scripts/bench_box_msh.py writes as MSH, built in memory so a
// benchmark needs no input file.
inline CoarseMesh box_coarse_mesh(Id nx, Id ny, Id nz) {
  CoarseMesh m;
  m.source = "box " + std::to_string(nx) + "x" + std::to_string(ny) + "x" + std::to_string(nz);
  auto v = [&](Id i, Id j, Id k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  for (Id k = 0; k <= nz; ++k)
    for (Id j = 0; j <= ny; ++j)
      for (Id i = 0; i <= nx; ++i) {
        m.x.push_back(static_cast<double>(i)), m.y.push_back(static_cast<double>(j)), m.z.push_back(static_cast<double>(k));
        m.vertex_file_id.push_back(v(i, j, k) + 1);
      }
  for (Id k = 0; k < nz; ++k)
    for (Id j = 0; j < ny; ++j)
      for (Id i = 0; i < nx; ++i) {
        for (Id c : {v(i, j, k), v(i + 1, j, k), v(i + 1, j + 1, k), v(i, j + 1, k), v(i, j, k + 1), v(i + 1, j, k + 1),
                     v(i + 1, j + 1, k + 1), v(i, j + 1, k + 1)})
          m.conn.push_back(c);
        m.element_file_id.push_back(static_cast<Id>(m.element_file_id.size()) + 1);
        m.element_block.push_back(0);
      }
  m.blocks.push_back(Block{1, "box"});
  return m;
}

}  // namespace dicer::bench
