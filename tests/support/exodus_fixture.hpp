#pragma once
// Small Exodus files written with the Exodus library itself, for the tests
// of the Exodus reader (unit and bad_inputs). Header-only.
#include <exodusII.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace dicer::test {

// A small Exodus file written with the Exodus library itself (test fixture).
struct FixtureBlock {
  std::int64_t id = 1;
  std::string type = "HEX8";
  std::int64_t nodes_per_element = 8;
  std::vector<std::int64_t> conn;  // 1-based node numbers
  std::string name;
};
struct FixtureSideSet {
  std::int64_t id = 1;
  std::vector<std::int64_t> element, side;  // 1-based, as Exodus stores them
};
struct FixtureNodeSet {
  std::int64_t id = 1;
  std::vector<std::int64_t> node;  // 1-based
};
struct Fixture {
  int create_mode = EX_CLOBBER;  // | EX_NETCDF4 for an HDF5-based file
  int num_dim = 3;
  std::vector<double> x, y, z;
  bool write_coords = true;
  std::vector<FixtureBlock> blocks;
  std::vector<FixtureSideSet> side_sets;
  std::vector<FixtureNodeSet> node_sets;
  std::vector<std::int64_t> node_map, elem_map;  // empty: none stored
};

// Two unit hexes side by side along x: nodes (i, j, k), i in 0..2, j, k in 0..1,
// node number 1 + i + 3 j + 6 k; elements 1 and 2 in block 1.
inline Fixture two_hexes() {
  Fixture f;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 3; ++i) {
        f.x.push_back(i);
        f.y.push_back(j);
        f.z.push_back(k);
      }
  FixtureBlock b;
  for (int i = 0; i < 2; ++i) {
    const std::int64_t n = 1 + i;
    for (std::int64_t v : {n, n + 1, n + 4, n + 3, n + 6, n + 7, n + 10, n + 9}) b.conn.push_back(v);
  }
  f.blocks.push_back(b);
  return f;
}

inline void exo_check(int rc, const char* what) {
  if (rc < 0) throw std::runtime_error(std::string("fixture: ") + what + " failed");
}

inline void write_exodus(const std::string& path, const Fixture& f) {
  int cpu_ws = 8, io_ws = 8;
  const int exoid = ex_create(path.c_str(), f.create_mode, &cpu_ws, &io_ws);
  if (exoid < 0) throw std::runtime_error("fixture: ex_create failed for " + path);
  ex_set_int64_status(exoid, EX_ALL_INT64_API);
  std::int64_t num_elem = 0;
  for (const auto& b : f.blocks) num_elem += static_cast<std::int64_t>(b.conn.size()) / b.nodes_per_element;
  exo_check(ex_put_init(exoid, "dicer fixture", f.num_dim, static_cast<std::int64_t>(f.x.size()), num_elem,
                        static_cast<std::int64_t>(f.blocks.size()), static_cast<std::int64_t>(f.node_sets.size()),
                        static_cast<std::int64_t>(f.side_sets.size())),
            "ex_put_init");
  if (f.write_coords)
    exo_check(ex_put_coord(exoid, f.x.data(), f.y.data(), f.num_dim >= 3 ? f.z.data() : nullptr), "ex_put_coord");
  if (!f.node_map.empty()) exo_check(ex_put_id_map(exoid, EX_NODE_MAP, f.node_map.data()), "node map");
  if (!f.elem_map.empty()) exo_check(ex_put_id_map(exoid, EX_ELEM_MAP, f.elem_map.data()), "elem map");
  for (const auto& b : f.blocks) {
    const std::int64_t n = static_cast<std::int64_t>(b.conn.size()) / b.nodes_per_element;
    exo_check(ex_put_block(exoid, EX_ELEM_BLOCK, b.id, b.type.c_str(), n, b.nodes_per_element, 0, 0, 0),
              "ex_put_block");
    if (n > 0) exo_check(ex_put_conn(exoid, EX_ELEM_BLOCK, b.id, b.conn.data(), nullptr, nullptr), "ex_put_conn");
    if (!b.name.empty()) exo_check(ex_put_name(exoid, EX_ELEM_BLOCK, b.id, b.name.c_str()), "ex_put_name");
  }
  for (const auto& s : f.side_sets) {
    exo_check(ex_put_set_param(exoid, EX_SIDE_SET, s.id, static_cast<std::int64_t>(s.element.size()), 0),
              "side set param");
    exo_check(ex_put_set(exoid, EX_SIDE_SET, s.id, s.element.data(), s.side.data()), "side set");
  }
  for (const auto& s : f.node_sets) {
    exo_check(ex_put_set_param(exoid, EX_NODE_SET, s.id, static_cast<std::int64_t>(s.node.size()), 0),
              "node set param");
    exo_check(ex_put_set(exoid, EX_NODE_SET, s.id, s.node.data(), nullptr), "node set");
  }
  exo_check(ex_close(exoid), "ex_close");
}

// Two unit quads side by side along x on z = 0 in block 3 (QUAD4 or SHELL4):
// nodes 1 + i + 3 j, i in 0..2, j in 0..1.
inline Fixture two_quads(const char* type = "QUAD4") {
  Fixture f;
  f.x = {0, 1, 2, 0, 1, 2};
  f.y = {0, 0, 0, 1, 1, 1};
  f.z = {0, 0, 0, 0, 0, 0};
  FixtureBlock b;
  b.id = 3;
  b.type = type;
  b.nodes_per_element = 4;
  b.conn = {1, 2, 5, 4, 2, 3, 6, 5};
  f.blocks.push_back(b);
  return f;
}

inline FixtureBlock block_of(std::int64_t id, const char* type, std::int64_t nodes_per_element,
                             std::vector<std::int64_t> conn, const char* name = "") {
  FixtureBlock b;
  b.id = id;
  b.type = type;
  b.nodes_per_element = nodes_per_element;
  b.conn = std::move(conn);
  b.name = name;
  return b;
}

}  // namespace dicer::test
