// ReadExodus: the Exodus reader against the nine real Exodus files in
// tests/data (facts from PROVENANCE.md, checked there with ncdump, netCDF4
// and meshio, not with this reader) and against small fixtures written with
// the Exodus library.
#include <exodusII.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "exodus_fixture.hpp"
#include "isolated.hpp"
#include "test_support.hpp"

namespace {

using dicer::CoarseMesh;
using dicer::Id;
using dicer::Mode;
using dicer::test::data_path;
using dicer::test::TempDir;
using namespace dicer::test;  // Exodus fixtures

CoarseMesh read(const std::string& name) { return dicer::read_exodus(data_path(name)); }

// Structural invariants every mesh from the reader must satisfy.
void expect_consistent(const CoarseMesh& m) {
  const Id V = m.num_vertices();
  const Id E = m.num_elements();
  EXPECT_EQ(static_cast<Id>(m.y.size()), V);
  EXPECT_EQ(static_cast<Id>(m.z.size()), V);
  EXPECT_EQ(static_cast<Id>(m.vertex_file_id.size()), V);
  EXPECT_EQ(static_cast<Id>(m.conn.size()), E * m.corners_per_element());
  EXPECT_EQ(static_cast<Id>(m.element_file_id.size()), E);
  EXPECT_EQ(static_cast<Id>(m.element_block.size()), E);
  EXPECT_TRUE(m.vertex_geo_dim.empty());
  EXPECT_TRUE(m.vertex_geo_tag.empty());
  for (Id v : m.conn) ASSERT_TRUE(v >= 0 && v < V) << v;
  for (auto b : m.element_block) ASSERT_TRUE(b >= 0 && b < static_cast<std::int32_t>(m.blocks.size())) << b;
  for (Id v = 0; v < V; ++v)
    ASSERT_TRUE(std::isfinite(m.x[v]) && std::isfinite(m.y[v]) && std::isfinite(m.z[v])) << v;
  std::set<Id> ids(m.vertex_file_id.begin(), m.vertex_file_id.end());
  EXPECT_EQ(static_cast<Id>(ids.size()), V) << "vertex file ids must be unique";
  std::set<Id> eids(m.element_file_id.begin(), m.element_file_id.end());
  EXPECT_EQ(static_cast<Id>(eids.size()), E) << "element file ids must be unique";
  for (const auto& s : m.side_sets) {
    ASSERT_EQ(s.element.size(), s.side.size());
    for (std::size_t i = 0; i < s.element.size(); ++i) {
      ASSERT_TRUE(s.element[i] >= 0 && s.element[i] < E);
      ASSERT_TRUE(s.side[i] >= 0 && s.side[i] < 6);
    }
  }
  for (const auto& s : m.node_sets)
    for (Id v : s.vertex) ASSERT_TRUE(v >= 0 && v < V);
}

std::vector<std::int64_t> block_ids(const CoarseMesh& m) {
  std::vector<std::int64_t> ids;
  for (const auto& b : m.blocks) ids.push_back(b.id);
  return ids;
}

std::vector<Id> elements_per_block(const CoarseMesh& m) {
  std::vector<Id> n(m.blocks.size(), 0);
  for (auto b : m.element_block) ++n[static_cast<std::size_t>(b)];
  return n;
}

// Side set summary: id -> (name, size), plus the order of ids.
std::vector<std::int64_t> side_set_ids(const CoarseMesh& m) {
  std::vector<std::int64_t> ids;
  for (const auto& s : m.side_sets) ids.push_back(s.id);
  return ids;
}
const dicer::SideSet& side_set(const CoarseMesh& m, std::int64_t id) {
  for (const auto& s : m.side_sets)
    if (s.id == id) return s;
  throw std::runtime_error("no side set " + std::to_string(id));
}

bool identity(const std::vector<Id>& ids) {
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i] != static_cast<Id>(i) + 1) return false;
  return true;
}

TEST(ReadExodus, DiskOutRefLegacyCubit1996) {
  const CoarseMesh m = read("vtkdata_disk_out_ref.ex2");
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.source, data_path("vtkdata_disk_out_ref.ex2"));
  EXPECT_EQ(m.num_vertices(), 8499);
  EXPECT_EQ(m.num_elements(), 7472);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1}));
  EXPECT_EQ(m.blocks[0].name, "");
  // Side sets in file order (not sorted), with their sizes.
  EXPECT_EQ(side_set_ids(m), (std::vector<std::int64_t>{1, 5, 3, 6, 2, 7, 4}));
  const std::map<std::int64_t, std::size_t> sizes = {{1, 418}, {2, 180}, {3, 828}, {4, 238},
                                                     {5, 108}, {6, 216}, {7, 964}};
  for (const auto& [id, size] : sizes) EXPECT_EQ(side_set(m, id).element.size(), size) << "side set " << id;
  ASSERT_EQ(m.node_sets.size(), 3u);
  for (const auto& s : m.node_sets) EXPECT_EQ(s.vertex.size(), 1u);
  // The legacy all-zero `elem_map` must not become the element ids.
  EXPECT_TRUE(identity(m.element_file_id));
  EXPECT_TRUE(identity(m.vertex_file_id));
  // float32 coordinates in the old combined `coord` variable, widened exactly.
  double rmax = 0, zmin = 1e300, zmax = -1e300;
  for (Id v = 0; v < m.num_vertices(); ++v) {
    ASSERT_EQ(static_cast<double>(static_cast<float>(m.x[v])), m.x[v]);
    ASSERT_EQ(static_cast<double>(static_cast<float>(m.z[v])), m.z[v]);
    rmax = std::max(rmax, std::hypot(m.x[v], m.y[v]));
    zmin = std::min(zmin, m.z[v]);
    zmax = std::max(zmax, m.z[v]);
  }
  EXPECT_NEAR(rmax, 5.75, 1e-4);
  EXPECT_NEAR(zmin, -10.0, 1e-4);
  EXPECT_NEAR(zmax, 10.16, 1e-4);
}

TEST(ReadExodus, MugTwoBlocksWithGappedIds) {
  const CoarseMesh m = read("vtkdata_mug.e");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 3774);
  EXPECT_EQ(m.num_elements(), 2476);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1, 76}));
  EXPECT_EQ(elements_per_block(m), (std::vector<Id>{1716, 760}));
  // Elements are in file order, block after block.
  EXPECT_TRUE(std::is_sorted(m.element_block.begin(), m.element_block.end()));
  EXPECT_EQ(side_set_ids(m), (std::vector<std::int64_t>{2, 1}));
  EXPECT_EQ(side_set(m, 2).name, "top");
  EXPECT_EQ(side_set(m, 2).element.size(), 76u);
  EXPECT_EQ(side_set(m, 1).name, "bottom");
  EXPECT_EQ(side_set(m, 1).element.size(), 478u);
  ASSERT_EQ(m.node_sets.size(), 2u);
  EXPECT_EQ(m.node_sets[0].id, 2);
  EXPECT_EQ(m.node_sets[0].vertex.size(), 114u);
  EXPECT_EQ(m.node_sets[1].id, 1);
  EXPECT_EQ(m.node_sets[1].vertex.size(), 498u);
  // elem_num_map is a non-identity permutation of 1..n.
  EXPECT_FALSE(identity(m.element_file_id));
  std::vector<Id> sorted = m.element_file_id;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_TRUE(identity(sorted));
}

TEST(ReadExodus, PincellThreeBlocks) {
  const CoarseMesh m = read("cardinal_pincell.e");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 6180);
  EXPECT_EQ(m.num_elements(), 5310);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1, 2, 3}));
  EXPECT_EQ(elements_per_block(m), (std::vector<Id>{1652, 2124, 1534}));
  ASSERT_EQ(m.side_sets.size(), 3u);
  EXPECT_EQ(m.side_sets[0].name, "bottom");
  EXPECT_EQ(m.side_sets[0].element.size(), 90u);
  EXPECT_EQ(m.side_sets[1].name, "top");
  EXPECT_EQ(m.side_sets[1].element.size(), 90u);
  EXPECT_EQ(m.side_sets[2].name, "surface");
  EXPECT_EQ(m.side_sets[2].element.size(), 1416u);
  EXPECT_TRUE(m.node_sets.empty());
  EXPECT_FALSE(identity(m.vertex_file_id));
}

TEST(ReadExodus, CylindersInteriorSideSet) {
  const CoarseMesh m = read("cardinal_cylinders.exo");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 10944);
  EXPECT_EQ(m.num_elements(), 9128);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1, 2}));
  EXPECT_EQ(elements_per_block(m), (std::vector<Id>{2492, 6636}));
  EXPECT_EQ(side_set(m, 1).name, "outer");
  EXPECT_EQ(side_set(m, 1).element.size(), 882u);
  EXPECT_EQ(side_set(m, 2).name, "interface");
  EXPECT_EQ(side_set(m, 2).element.size(), 448u);
  EXPECT_FALSE(identity(m.vertex_file_id));
}

TEST(ReadExodus, BrickNodeMapGapsAndElementMapOffset) {
  const CoarseMesh m = read("cardinal_brick.e");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 4665);
  EXPECT_EQ(m.num_elements(), 3486);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{3}));
  const std::vector<std::pair<std::string, std::size_t>> sets = {
      {"left_pin", 308}, {"right_pin", 308}, {"left", 196}, {"right", 196}, {"bottom_brick", 249}};
  ASSERT_EQ(m.side_sets.size(), sets.size());
  for (std::size_t i = 0; i < sets.size(); ++i) {
    EXPECT_EQ(m.side_sets[i].name, sets[i].first);
    EXPECT_EQ(m.side_sets[i].element.size(), sets[i].second) << sets[i].first;
  }
  EXPECT_EQ(*std::max_element(m.vertex_file_id.begin(), m.vertex_file_id.end()), 5925);
  EXPECT_EQ(*std::min_element(m.element_file_id.begin(), m.element_file_id.end()), 1457);
  EXPECT_EQ(*std::max_element(m.element_file_id.begin(), m.element_file_id.end()), 4942);
}

TEST(ReadExodus, TrisoNamedBlocks) {
  const CoarseMesh m = read("cardinal_triso_solid.e");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 4998);
  EXPECT_EQ(m.num_elements(), 3960);
  ASSERT_EQ(m.blocks.size(), 2u);
  EXPECT_EQ(m.blocks[0].id, 1);
  EXPECT_EQ(m.blocks[0].name, "graphite");
  EXPECT_EQ(m.blocks[1].id, 2);
  EXPECT_EQ(m.blocks[1].name, "compacts");
  EXPECT_EQ(elements_per_block(m), (std::vector<Id>{1980, 1980}));
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].name, "fluid_solid_interface");
  EXPECT_EQ(m.side_sets[0].element.size(), 216u);
}

TEST(ReadExodus, SphereHexTypeString) {
  const CoarseMesh m = read("cardinal_sphere.e");  // element type "HEX", not "HEX8"
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_vertices(), 321);
  EXPECT_EQ(m.num_elements(), 256);
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].id, 1);
  EXPECT_EQ(m.side_sets[0].element.size(), 96u);
  double rmax = 0;
  for (Id v = 0; v < m.num_vertices(); ++v) rmax = std::max(rmax, std::sqrt(m.x[v] * m.x[v] + m.y[v] * m.y[v] + m.z[v] * m.z[v]));
  EXPECT_NEAR(rmax, 1.5, 1e-6);
}

TEST(ReadExodus, PrismElevenNamedSideSets) {
  const CoarseMesh m = read("cardinal_prism.exo");
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 2400);
  EXPECT_EQ(m.num_elements(), 1863);
  EXPECT_EQ(elements_per_block(m), (std::vector<Id>{972, 891}));
  EXPECT_EQ(side_set_ids(m), (std::vector<std::int64_t>{1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12}));
  const std::map<std::string, std::size_t> sizes = {
      {"vol1_top", 81},   {"interface", 81},  {"vol1_face1", 108}, {"vol1_face2", 108},
      {"vol1_face3", 108}, {"vol1_face4", 108}, {"vol2_top", 81},   {"vol2_face1", 99},
      {"vol2_face2", 99}, {"vol2_face3", 99}, {"vol2_face4", 99}};
  for (const auto& s : m.side_sets) {
    ASSERT_TRUE(sizes.count(s.name)) << s.name;
    EXPECT_EQ(s.element.size(), sizes.at(s.name)) << s.name;
  }
}

TEST(ReadExodus, CylinderShellIsSurfaceMode) {
  const CoarseMesh m = read("libmesh_cylinder_shell.exo");
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.corners_per_element(), 4);
  EXPECT_EQ(m.num_vertices(), 457);
  EXPECT_EQ(m.num_elements(), 416);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{11}));
  EXPECT_EQ(side_set_ids(m), (std::vector<std::int64_t>{7, 8, 9, 10, 11, 12}));
  const std::size_t edge_sizes[4] = {16, 24, 16, 24};
  for (int i = 0; i < 4; ++i) {
    const auto& s = m.side_sets[static_cast<std::size_t>(i)];
    EXPECT_EQ(s.element.size(), edge_sizes[i]);
    for (auto side : s.side) EXPECT_TRUE(side >= 2 && side <= 5) << "edge sides are 2..5, got " << int(side);
  }
  EXPECT_EQ(side_set(m, 11).element.size(), 416u);
  for (auto side : side_set(m, 11).side) EXPECT_EQ(side, 0);
  EXPECT_EQ(side_set(m, 12).element.size(), 416u);
  for (auto side : side_set(m, 12).side) EXPECT_EQ(side, 1);
  const std::size_t node_sizes[4] = {17, 25, 17, 25};
  ASSERT_EQ(m.node_sets.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(m.node_sets[static_cast<std::size_t>(i)].id, 7 + i);
    EXPECT_EQ(m.node_sets[static_cast<std::size_t>(i)].vertex.size(), node_sizes[i]);
  }
}

TEST(ReadExodus, FixtureWithoutMapsNumbersFromOne) {
  TempDir tmp;
  const std::string path = tmp.path("plain.e");
  write_exodus(path, two_hexes());
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(m.num_vertices(), 12);
  EXPECT_EQ(m.num_elements(), 2);
  EXPECT_EQ(m.vertex_file_id, (std::vector<Id>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}));
  EXPECT_EQ(m.element_file_id, (std::vector<Id>{1, 2}));
  // 0-based connectivity in the file's (VTK) order.
  EXPECT_EQ(std::vector<Id>(m.conn.begin(), m.conn.begin() + 8), (std::vector<Id>{0, 1, 4, 3, 6, 7, 10, 9}));
  EXPECT_DOUBLE_EQ(m.x[2], 2.0);
  EXPECT_DOUBLE_EQ(m.z[11], 1.0);
  EXPECT_TRUE(m.warnings.empty());
}

TEST(ReadExodus, Netcdf4FixtureReads) {
  TempDir tmp;
  const std::string path = tmp.path("hdf5.e");
  Fixture f = two_hexes();
  f.create_mode = EX_CLOBBER | EX_NETCDF4;
  f.side_sets.push_back({4, {2}, {2}});
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(m.num_elements(), 2);
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].element, (std::vector<Id>{1}));
  EXPECT_EQ(m.side_sets[0].side, (std::vector<std::int8_t>{1}));
}

TEST(ReadExodus, ElementTypeIsCaseInsensitive) {
  TempDir tmp;
  for (const char* type : {"hex8", "Hexahedron", "hex"}) {
    const std::string path = tmp.path(std::string(type) + ".e");
    Fixture f = two_hexes();
    f.blocks[0].type = type;
    write_exodus(path, f);
    const CoarseMesh m = dicer::read_exodus(path);
    EXPECT_EQ(m.mode, Mode::Volume) << type;
    EXPECT_EQ(m.num_elements(), 2) << type;
  }
}

TEST(ReadExodus, ZeroElementMapFallsBackWithWarning) {
  TempDir tmp;
  const std::string path = tmp.path("zeros.e");
  Fixture f = two_hexes();
  f.elem_map = {0, 0};
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  EXPECT_EQ(m.element_file_id, (std::vector<Id>{1, 2}));
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("all zeros"), std::string::npos) << m.warnings[0];
}

TEST(ReadExodus, DuplicateNodeMapFallsBackWithWarning) {
  TempDir tmp;
  const std::string path = tmp.path("dup.e");
  Fixture f = two_hexes();
  f.node_map = {5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 5};
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  EXPECT_TRUE(identity(m.vertex_file_id));
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("duplicate"), std::string::npos) << m.warnings[0];
}

TEST(ReadExodus, EmptyBlockIsKept) {
  TempDir tmp;
  const std::string path = tmp.path("empty_block.e");
  Fixture f = two_hexes();
  FixtureBlock empty;
  empty.id = 9;
  empty.name = "nothing";
  FixtureBlock second = f.blocks[0];
  second.id = 4;
  f.blocks[0].conn.resize(8);   // block 1: element 1
  second.conn.erase(second.conn.begin(), second.conn.begin() + 8);  // block 4: element 2
  f.blocks = {f.blocks[0], empty, second};
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1, 9, 4}));
  EXPECT_EQ(m.blocks[1].name, "nothing");
  EXPECT_EQ(m.element_block, (std::vector<std::int32_t>{0, 2}));
}

TEST(ReadExodus, ShellBlockInHexFileIsSkipped) {
  TempDir tmp;
  const std::string path = tmp.path("hex_and_shell.e");
  Fixture f = two_hexes();
  FixtureBlock shells;
  shells.id = 100;
  shells.type = "SHELL4";
  shells.nodes_per_element = 4;
  shells.conn = {1, 4, 5, 2};  // the bottom face of element 1
  FixtureBlock hex2 = f.blocks[0];
  hex2.id = 2;
  f.blocks[0].conn.resize(8);
  hex2.conn.erase(hex2.conn.begin(), hex2.conn.begin() + 8);
  f.blocks = {f.blocks[0], shells, hex2};   // file elements: hex, shell, hex
  f.elem_map = {10, 20, 30};
  f.side_sets.push_back({1, {1, 2, 3}, {5, 1, 6}});  // element 2 is the shell
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_elements(), 2);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1, 2}));
  EXPECT_EQ(m.element_file_id, (std::vector<Id>{10, 30}));
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].element, (std::vector<Id>{0, 1}));
  EXPECT_EQ(m.side_sets[0].side, (std::vector<std::int8_t>{4, 5}));
  ASSERT_EQ(m.warnings.size(), 2u);  // skipped block, dropped side
  EXPECT_NE(m.warnings[0].find("block 100 (1 SHELL4)"), std::string::npos) << m.warnings[0];
  EXPECT_NE(m.warnings[1].find("side set 1"), std::string::npos) << m.warnings[1];
}

// One rule for lower-dimensional blocks (README, Inputs): in a hex mesh,
// shells, beams and spheres are skipped with one warning naming each block;
// in a quad mesh, beams and spheres are.
TEST(ReadExodus, LowerDimensionalBlocksInAHexMeshAreSkippedWithOneWarning) {
  TempDir tmp;
  const std::string path = tmp.path("hex_beam_shell_sphere.e");
  Fixture f = two_hexes();
  f.blocks[0].name = "solid";
  f.blocks.push_back(block_of(7, "BAR2", 2, {1, 2, 2, 3}, "beams"));
  f.blocks.push_back(block_of(8, "SHELL4", 4, {1, 4, 5, 2}));
  f.blocks.push_back(block_of(9, "SPHERE", 1, {12}, "mass"));
  f.blocks.push_back(block_of(10, "BEAM3", 3, {1, 2, 3}));
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_elements(), 2);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{1}));
  ASSERT_EQ(m.warnings.size(), 1u);
  const std::string& w = m.warnings[0];
  for (const char* part : {"lower dimension than the hexahedra", "block 7 \"beams\" (2 BAR2)", "block 8 (1 SHELL4)",
                           "block 9 \"mass\" (1 SPHERE)", "block 10 (1 BEAM3)"})
    EXPECT_NE(w.find(part), std::string::npos) << "missing '" << part << "' in: " << w;
  EXPECT_EQ(dicer::read_coarse_mesh(path).num_elements(), 2) << "and the mesh is diceable";
}

TEST(ReadExodus, BeamsInAQuadMeshAreSkipped) {
  TempDir tmp;
  const std::string path = tmp.path("quad_beam.e");
  Fixture f = two_quads("SHELL4");
  f.blocks.push_back(block_of(4, "TRUSS", 2, {1, 2}, "stiffener"));
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.num_elements(), 2);
  EXPECT_EQ(block_ids(m), (std::vector<std::int64_t>{3}));
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("lower dimension than the quadrilaterals"), std::string::npos) << m.warnings[0];
  EXPECT_NE(m.warnings[0].find("block 4 \"stiffener\" (1 TRUSS)"), std::string::npos) << m.warnings[0];
}

TEST(ReadExodus, SecondOrderShellsInAHexMeshAreSkippedToo) {
  TempDir tmp;
  const std::string path = tmp.path("hex_quad8.e");
  Fixture f = two_hexes();
  f.blocks.push_back(block_of(5, "QUAD8", 8, {1, 2, 5, 4, 1, 2, 5, 4}));
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  EXPECT_EQ(m.num_elements(), 2);
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("block 5 (1 QUAD8)"), std::string::npos) << m.warnings[0];
}

TEST(ReadExodus, PlanarQuad4FileIsSurfaceWithZeroZ) {
  TempDir tmp;
  const std::string path = tmp.path("quads2d.e");
  Fixture f;
  f.num_dim = 2;
  f.x = {0, 1, 2, 0, 1, 2};
  f.y = {0, 0, 0, 1, 1, 1};
  f.z = {7, 7, 7, 7, 7, 7};  // not written for num_dim 2
  FixtureBlock quads;
  quads.id = 3;
  quads.type = "QUAD4";
  quads.nodes_per_element = 4;
  quads.conn = {1, 2, 5, 4, 2, 3, 6, 5};
  f.blocks.push_back(quads);
  f.side_sets.push_back({2, {1, 2}, {1, 4}});  // QUAD4 sides are edges 1..4
  f.node_sets.push_back({6, {3, 6}});
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_exodus(path);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.num_elements(), 2);
  for (double z : m.z) EXPECT_EQ(z, 0.0);
  ASSERT_EQ(m.side_sets.size(), 1u);
  // Stored in shell numbering: edges are sides 2..5.
  EXPECT_EQ(m.side_sets[0].side, (std::vector<std::int8_t>{2, 5}));
  ASSERT_EQ(m.node_sets.size(), 1u);
  EXPECT_EQ(m.node_sets[0].vertex, (std::vector<Id>{2, 5}));
}

}  // namespace

// netCDF-4 (HDF5) files are read in a child process (readers/isolated.hpp):
// the mesh that comes back is the one an in-process read gives, every field.
TEST(ReadExodus, Netcdf4ReadInAChildEqualsTheReadInProcess) {
  TempDir tmp;
  const std::string path = tmp.path("hdf5.e");
  Fixture f = two_hexes();
  f.create_mode = EX_CLOBBER | EX_NETCDF4;
  f.blocks[0].name = "steel";
  f.side_sets.push_back({4, {2, 1}, {2, 5}});
  f.node_sets.push_back({7, {1, 2, 12}});
  f.node_map = {11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22};
  write_exodus(path, f);
  const CoarseMesh child = dicer::read_exodus(path);
  ::setenv("DICER_READER_IN_PROCESS", "1", 1);
  const CoarseMesh here = dicer::read_exodus(path);
  ::unsetenv("DICER_READER_IN_PROCESS");
  expect_consistent(child);
  EXPECT_EQ(child.conn, here.conn);
  EXPECT_EQ(child.x, here.x);
  EXPECT_EQ(child.vertex_file_id, here.vertex_file_id);
  EXPECT_EQ(child.vertex_file_id[0], 11);
  ASSERT_EQ(child.blocks.size(), 1u);
  EXPECT_EQ(child.blocks[0].name, "steel");
  ASSERT_EQ(child.side_sets.size(), 1u);
  EXPECT_EQ(child.side_sets[0].element, here.side_sets[0].element);
  EXPECT_EQ(child.side_sets[0].side, here.side_sets[0].side);
  ASSERT_EQ(child.node_sets.size(), 1u);
  EXPECT_EQ(child.node_sets[0].vertex, here.node_sets[0].vertex);
  EXPECT_EQ(dicer::pack_mesh(child), dicer::pack_mesh(here)) << "some other field differs";
}

TEST(ReadExodus, TheIsolatedReadersStreamRoundTripsAndRefusesTruncation) {
  CoarseMesh m;
  m.source = "a.e";
  m.mode = Mode::Surface;
  m.x = {0, 1, 1, 0}, m.y = {0, 0, 1, 1}, m.z = {0, 0, 0, 0.5};
  m.vertex_file_id = {5, 6, 7, 8};
  m.conn = {0, 1, 2, 3};
  m.element_file_id = {9};
  m.element_block = {0};
  m.blocks = {{3, "skin"}};
  m.side_sets = {{2, "edge", {0}, {3}}};
  m.node_sets = {{4, "", {1, 2}}};
  m.vertex_geo_dim = {0, 1, 2, 2};
  m.vertex_geo_tag = {1, 2, 3, 3};
  m.warnings = {"reoriented 1 element"};
  const std::string bytes = dicer::pack_mesh(m);
  const CoarseMesh back = dicer::unpack_mesh(bytes, "a.e");
  EXPECT_EQ(dicer::pack_mesh(back), bytes);
  EXPECT_EQ(back.mode, Mode::Surface);
  EXPECT_EQ(back.side_sets[0].side, (std::vector<std::int8_t>{3}));
  EXPECT_EQ(back.warnings, m.warnings);
  EXPECT_EQ(back.vertex_geo_tag, m.vertex_geo_tag);
  for (std::size_t cut : {std::size_t{0}, std::size_t{7}, bytes.size() / 2, bytes.size() - 1}) {
    try {
      dicer::unpack_mesh(bytes.substr(0, cut), "a.e");
      ADD_FAILURE() << "truncated at " << cut;
    } catch (const dicer::Error& e) {
      EXPECT_EQ(e.kind(), dicer::ErrorKind::BadInput);
    }
  }
  EXPECT_THROW(dicer::unpack_mesh(bytes + "x", "a.e"), dicer::Error);
}

// Second order (tests/geometry/test_second_order.cpp dices real ones): a
// HEX8 block and a HEX20 block in one file. The HEX20's nodes after its
// corners, in Exodus's order, are its mid nodes; the HEX8 has none; the
// mid nodes leave the vertices and the node sets.
TEST(ReadExodus, MixedHex8AndHex20BlocksKeepTheMidNodesApart) {
  TempDir tmp;
  const std::string path = tmp.path("mixed.e");
  Fixture f = two_hexes();
  const std::vector<std::int64_t> corners(f.blocks[0].conn.begin() + 8, f.blocks[0].conn.end());
  f.blocks[0].conn.resize(8);
  // Exodus HEX20: nodes 8..19 between these corners (the Exodus manual).
  const int edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 5}, {2, 6}, {3, 7}, {4, 5}, {5, 6}, {6, 7}, {7, 4}};
  FixtureBlock quadratic = block_of(2, "HEX20", 20, corners);
  std::vector<std::array<double, 3>> want;
  for (const auto& e : edges) {
    const std::int64_t a = corners[e[0]] - 1, b = corners[e[1]] - 1;
    want.push_back({0.5 * (f.x[a] + f.x[b]), 0.5 * (f.y[a] + f.y[b]) + 0.01, 0.5 * (f.z[a] + f.z[b])});
    f.x.push_back(want.back()[0]), f.y.push_back(want.back()[1]), f.z.push_back(want.back()[2]);
    quadratic.conn.push_back(static_cast<std::int64_t>(f.x.size()));
  }
  f.blocks.push_back(quadratic);
  f.node_sets.push_back({4, {1, 13, 24}});  // a corner and two mid nodes
  write_exodus(path, f);
  const CoarseMesh m = dicer::read_coarse_mesh(path);
  ASSERT_TRUE(m.second_order());
  EXPECT_EQ(m.num_vertices(), 12);
  ASSERT_EQ(m.mid.size(), 2u * dicer::kHexMidSlots);
  ASSERT_EQ(m.mid_x.size(), 12u);
  ASSERT_EQ(m.node_sets.size(), 1u);
  EXPECT_EQ(m.node_sets[0].vertex.size(), 1u);
  // Which element is the HEX20: the one of block 2 (index 1).
  for (Id e = 0; e < 2; ++e) {
    const bool hex20 = m.blocks[m.element_block[e]].id == 2;
    for (int s = 0; s < dicer::kHexMidSlots; ++s) {
      const Id q = m.mid[static_cast<size_t>(e) * dicer::kHexMidSlots + s];
      if (!hex20 || s >= 12) {
        EXPECT_EQ(q, -1) << "element " << e << " slot " << s;
        continue;
      }
      ASSERT_GE(q, 0);
      // Slot s is dicer's local edge s: its mid node sits between its corners (+0.01 in y).
      const dicer::Vec3 a = m.vertex(m.conn[8 * e + dicer::kHexEdge[s][0]]), b = m.vertex(m.conn[8 * e + dicer::kHexEdge[s][1]]);
      EXPECT_DOUBLE_EQ(m.mid_x[q], 0.5 * (a.x + b.x)) << s;
      EXPECT_DOUBLE_EQ(m.mid_y[q], 0.5 * (a.y + b.y) + 0.01) << s;
      EXPECT_DOUBLE_EQ(m.mid_z[q], 0.5 * (a.z + b.z)) << s;
      EXPECT_GE(m.mid_file_id[q], 13);
    }
  }
}
