// read_msh on the bundled real Gmsh files, on Gmsh's own binary and 4.1
// re-saves of them, and on small hand-written fixtures (sparse tags, names,
// sets, byte-swapped binary).
#include <gmock/gmock.h>
#include <gmsh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "test_support.hpp"

using dicer::CoarseMesh;
using dicer::Id;
using dicer::Mode;
using dicer::test::data_path;
using dicer::test::TempDir;
using dicer::test::write_file;
using testing::HasSubstr;

namespace {

// A mesh described by file ids only, so that two files with the same content
// but a different node/element order compare equal.
struct ById {
  std::map<Id, std::array<double, 3>> coords;  // node tag -> x, y, z
  std::map<Id, std::vector<Id>> cells;         // element tag -> corner node tags
};

ById by_id(const CoarseMesh& m) {
  ById r;
  for (Id v = 0; v < m.num_vertices(); ++v) r.coords[m.vertex_file_id[v]] = {m.x[v], m.y[v], m.z[v]};
  const int n = m.corners_per_element();
  for (Id e = 0; e < m.num_elements(); ++e) {
    std::vector<Id>& c = r.cells[m.element_file_id[e]];
    for (int k = 0; k < n; ++k) c.push_back(m.vertex_file_id[m.conn[e * n + k]]);
  }
  return r;
}

// Checks the structural invariants the reader promises.
void expect_consistent(const CoarseMesh& m) {
  const Id nv = m.num_vertices();
  EXPECT_EQ(m.y.size(), m.x.size());
  EXPECT_EQ(m.z.size(), m.x.size());
  EXPECT_EQ(static_cast<Id>(m.vertex_file_id.size()), nv);
  EXPECT_EQ(static_cast<Id>(m.vertex_geo_dim.size()), nv);
  EXPECT_EQ(static_cast<Id>(m.vertex_geo_tag.size()), nv);
  EXPECT_EQ(m.conn.size() % m.corners_per_element(), 0u);
  EXPECT_EQ(static_cast<Id>(m.element_file_id.size()), m.num_elements());
  EXPECT_EQ(static_cast<Id>(m.element_block.size()), m.num_elements());
  for (Id v : m.conn) ASSERT_TRUE(v >= 0 && v < nv);
  for (auto b : m.element_block) ASSERT_TRUE(b >= 0 && b < static_cast<int>(m.blocks.size()));
  for (std::size_t i = 1; i < m.blocks.size(); ++i) EXPECT_LT(m.blocks[i - 1].id, m.blocks[i].id);
  for (const auto& s : m.side_sets) {
    ASSERT_EQ(s.element.size(), s.side.size());
    for (std::size_t i = 0; i < s.element.size(); ++i) {
      ASSERT_TRUE(s.element[i] >= 0 && s.element[i] < m.num_elements());
      if (m.mode == Mode::Volume) {
        EXPECT_TRUE(s.side[i] >= 0 && s.side[i] <= 5);
      } else {
        EXPECT_TRUE(s.side[i] >= 2 && s.side[i] <= 5);
      }
    }
  }
}

// Re-saves `src` with Gmsh (MSH `version`, binary or ASCII) as `dst`.
void gmsh_resave(const std::string& src, const std::string& dst, double version, bool binary) {
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::open(src);
  gmsh::option::setNumber("Mesh.Binary", binary ? 1 : 0);
  gmsh::option::setNumber("Mesh.MshFileVersion", version);
  gmsh::write(dst);
  gmsh::finalize();
}

// The same mesh keyed by coordinates: Gmsh keeps coordinates and corner
// order on a re-save but may renumber nodes and elements (it does for the
// sparse tags of the deal.II file).
using Point = std::array<double, 3>;
struct ByCoords {
  std::map<Point, int> geo_dim;                                   // every node
  std::map<std::vector<Point>, std::pair<Id, std::string>> cells;  // corners -> block
  std::set<std::tuple<Id, std::vector<Point>, int>> sides;         // set id, element, side
};

ByCoords by_coords(const CoarseMesh& m) {
  ByCoords r;
  for (Id v = 0; v < m.num_vertices(); ++v) r.geo_dim[{m.x[v], m.y[v], m.z[v]}] = m.vertex_geo_dim[v];
  EXPECT_EQ(static_cast<Id>(r.geo_dim.size()), m.num_vertices()) << "nodes at the same position";
  const int n = m.corners_per_element();
  std::vector<std::vector<Point>> corners(m.num_elements());
  for (Id e = 0; e < m.num_elements(); ++e) {
    for (int k = 0; k < n; ++k) {
      const Id v = m.conn[e * n + k];
      corners[e].push_back({m.x[v], m.y[v], m.z[v]});
    }
    const auto& b = m.blocks[m.element_block[e]];
    r.cells[corners[e]] = {b.id, b.name};
  }
  for (const auto& s : m.side_sets)
    for (std::size_t i = 0; i < s.element.size(); ++i) r.sides.insert({s.id, corners[s.element[i]], s.side[i]});
  return r;
}

// Compares two reads of the same mesh: counts, coordinates, connectivity
// (as corner positions, and as file ids where Gmsh kept the node tags),
// blocks and side sets. Node classification is compared only when asked
// (MSH 2.2 derives it from elements, MSH 4.1 states it).
// Returns whether the node tags were the same (and so compared too).
// without_group0: b is an MSH 2.2 resave of MSH 4.1 file a, where physical
// group 0's elements carry tag 0, which means "none" in MSH 2.2 (Gmsh's own
// reader lists group 0 for a 4.1 file and not for its 2.2 resave).
bool expect_same_mesh(const CoarseMesh& a, const CoarseMesh& b, bool compare_geo, bool without_group0 = false) {
  EXPECT_EQ(a.mode, b.mode);
  EXPECT_EQ(a.num_vertices(), b.num_vertices());
  EXPECT_EQ(a.num_elements(), b.num_elements());
  ByCoords ca = by_coords(a);
  const ByCoords cb = by_coords(b);
  if (without_group0) std::erase_if(ca.sides, [](const auto& s) { return std::get<0>(s) == 0; });
  EXPECT_EQ(ca.cells, cb.cells);
  EXPECT_EQ(ca.sides, cb.sides);
  if (compare_geo) {
    EXPECT_EQ(ca.geo_dim, cb.geo_dim);
  } else {
    std::vector<Point> pa, pb;
    for (const auto& [p, d] : ca.geo_dim) pa.push_back(p);
    for (const auto& [p, d] : cb.geo_dim) pb.push_back(p);
    EXPECT_EQ(pa, pb);
  }
  const ById ia = by_id(a), ib = by_id(b);
  std::vector<Id> tags_a = a.vertex_file_id, tags_b = b.vertex_file_id;
  std::sort(tags_a.begin(), tags_a.end());
  std::sort(tags_b.begin(), tags_b.end());
  if (tags_a == tags_b) {  // Gmsh kept the node tags: compare by them too
    EXPECT_EQ(ia.coords, ib.coords);  // Gmsh writes %.16g: round-trips exactly
    std::multiset<std::vector<Id>> cells_a, cells_b;
    for (const auto& [tag, c] : ia.cells) cells_a.insert(c);
    for (const auto& [tag, c] : ib.cells) cells_b.insert(c);
    EXPECT_EQ(cells_a, cells_b);
  }
  return tags_a == tags_b;
}

// geo_22_to_41: Gmsh's classification of MSH 2.2 nodes matches ours.
// tags_kept: Gmsh keeps the node tags of this file on every re-save.
void check_resaves(const std::string& name, bool geo_22_to_41, bool tags_kept) {
  SCOPED_TRACE(name);
  const CoarseMesh original = dicer::read_msh(data_path(name));
  const bool original_is_41 = name.find("v41") != std::string::npos || name.find("step-49") != std::string::npos;
  TempDir tmp;
  struct Variant {
    double version;
    bool binary;
  };
  for (Variant v : {Variant{2.2, true}, Variant{4.1, true}, Variant{4.1, false}, Variant{2.2, false}}) {
    SCOPED_TRACE("MSH " + std::to_string(v.version) + (v.binary ? " binary" : " ASCII"));
    const std::string out = tmp.path("resaved.msh");
    gmsh_resave(data_path(name), out, v.version, v.binary);
    const CoarseMesh m = dicer::read_msh(out);
    expect_consistent(m);
    const bool resaved_is_41 = v.version > 3;
    const bool same_tags =
        expect_same_mesh(original, m, original_is_41 == resaved_is_41 || geo_22_to_41, original_is_41 && !resaved_is_41);
    if (tags_kept) {
      EXPECT_TRUE(same_tags);
    }
  }
}

// Writes numbers in a chosen byte order (hand-made binary fixtures).
class Bytes {
 public:
  explicit Bytes(bool big_endian) : swap_(big_endian != (std::endian::native == std::endian::big)) {}
  Bytes& text(const std::string& s) {
    out_ += s;
    return *this;
  }
  Bytes& i32(std::int32_t v) { return put(v); }
  Bytes& u64(std::uint64_t v) { return put(v); }
  Bytes& f64(double v) { return put(v); }
  const std::string& str() const { return out_; }

 private:
  template <class T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (swap_) std::reverse(b, b + sizeof(T));
    out_.append(b, sizeof(T));
    return *this;
  }
  bool swap_;
  std::string out_;
};

// Unit cube hex, node tags 11..18 (bottom 11-14, top 15-18), listed out of
// order; a quad on the bottom face in a physical surface.
const double kCube[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const int kNodeOrder[8] = {13, 11, 14, 12, 15, 16, 17, 18};  // file order of node tags

std::string binary41(bool big_endian) {
  Bytes b(big_endian);
  b.text("$MeshFormat\n4.1 1 8\n").i32(1).text("\n$EndMeshFormat\n");
  b.text("$PhysicalNames\n2\n3 4 \"solid\"\n2 6 \"bottom\"\n$EndPhysicalNames\n");
  b.text("$Entities\n").u64(0).u64(0).u64(1).u64(1);
  b.i32(2);
  for (int k = 0; k < 6; ++k) b.f64(0);
  b.u64(1).i32(6).u64(0);
  b.i32(1);
  for (int k = 0; k < 6; ++k) b.f64(0);
  b.u64(1).i32(4).u64(1).i32(2);
  b.text("\n$EndEntities\n");
  b.text("$Nodes\n").u64(2).u64(8).u64(11).u64(18);
  for (int block = 0; block < 2; ++block) {
    b.i32(block == 0 ? 2 : 3).i32(block == 0 ? 2 : 1).i32(0).u64(4);
    for (int i = 0; i < 4; ++i) b.u64(kNodeOrder[4 * block + i]);
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) b.f64(kCube[kNodeOrder[4 * block + i] - 11][c]);
  }
  b.text("\n$EndNodes\n");
  b.text("$Elements\n").u64(2).u64(2).u64(1).u64(2);
  b.i32(2).i32(2).i32(3).u64(1).u64(1).u64(11).u64(14).u64(13).u64(12);
  b.i32(3).i32(1).i32(5).u64(1).u64(2);
  for (int t = 11; t <= 18; ++t) b.u64(t);
  b.text("\n$EndElements\n");
  return b.str();
}

std::string binary22(bool big_endian) {
  Bytes b(big_endian);
  b.text("$MeshFormat\n2.2 1 8\n").i32(1).text("\n$EndMeshFormat\n");
  b.text("$PhysicalNames\n2\n3 4 \"solid\"\n2 6 \"bottom\"\n$EndPhysicalNames\n");
  b.text("$Nodes\n8\n");
  for (int t : kNodeOrder) {
    b.i32(t);
    for (int c = 0; c < 3; ++c) b.f64(kCube[t - 11][c]);
  }
  b.text("\n$EndNodes\n");
  b.text("$Elements\n2\n");
  b.i32(3).i32(1).i32(2).i32(1).i32(6).i32(2).i32(11).i32(14).i32(13).i32(12);
  b.i32(5).i32(1).i32(2).i32(2).i32(4).i32(1);
  for (int t = 11; t <= 18; ++t) b.i32(t);
  b.text("\n$EndElements\n");
  return b.str();
}

void expect_tiny_cube(const CoarseMesh& m) {
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  ASSERT_EQ(m.num_vertices(), 8);
  ASSERT_EQ(m.num_elements(), 1);
  EXPECT_EQ(m.vertex_file_id, std::vector<Id>(kNodeOrder, kNodeOrder + 8));
  for (int v = 0; v < 8; ++v) {
    const double* c = kCube[kNodeOrder[v] - 11];
    EXPECT_EQ(m.vertex(v), (dicer::Vec3{c[0], c[1], c[2]}));
  }
  EXPECT_EQ(m.conn, (std::vector<Id>{1, 3, 0, 2, 4, 5, 6, 7}));
  EXPECT_EQ(m.element_file_id, std::vector<Id>{2});
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 4);
  EXPECT_EQ(m.blocks[0].name, "solid");
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].id, 6);
  EXPECT_EQ(m.side_sets[0].name, "bottom");
  EXPECT_EQ(m.side_sets[0].element, std::vector<Id>{0});
  EXPECT_EQ(m.side_sets[0].side, std::vector<std::int8_t>{4});  // corners 0,3,2,1
  EXPECT_TRUE(m.warnings.empty());
}

CoarseMesh read_text(const std::string& text) {
  TempDir tmp;
  const std::string path = tmp.path("fixture.msh");
  write_file(path, text);
  return dicer::read_msh(path);
}

}  // namespace

// ---------------------------------------------------------------------------
// Real files (counts from tests/data/PROVENANCE.md)

TEST(ReadMsh, FiredrakeCubeMsh22Ascii) {
  const CoarseMesh m = dicer::read_msh(data_path("firedrake_cube_hex.msh"));
  expect_consistent(m);
  EXPECT_EQ(m.source, data_path("firedrake_cube_hex.msh"));
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_vertices(), 989);
  EXPECT_EQ(m.num_elements(), 768);
  // No physical groups: the block is the elementary volume.
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 1);
  EXPECT_EQ(m.blocks[0].name, "entity 1");
  EXPECT_TRUE(m.side_sets.empty());
  EXPECT_TRUE(m.node_sets.empty());
  // First lines of $Nodes: "1 0 0 1", "2 0 0 0".
  EXPECT_EQ(m.vertex_file_id[0], 1);
  EXPECT_EQ(m.vertex(0), (dicer::Vec3{0, 0, 1}));
  EXPECT_EQ(m.vertex(1), (dicer::Vec3{0, 0, 0}));
  // Classification from the lowest element holding a node: 8 box corners on
  // points, 12 edges x 3 nodes on lines, the rest on faces or inside.
  int by_dim[4] = {0, 0, 0, 0};
  for (auto d : m.vertex_geo_dim) {
    ASSERT_TRUE(d >= 0 && d <= 3);
    ++by_dim[d];
  }
  EXPECT_EQ(by_dim[0], 8);
  EXPECT_EQ(by_dim[1], 36);
  EXPECT_EQ(by_dim[0] + by_dim[1] + by_dim[2] + by_dim[3], 989);
  EXPECT_EQ(m.vertex_geo_dim[0], 0);  // node 1 is the corner (0,0,1)
}

TEST(ReadMsh, DealiiGridMsh41WithPhysicalGroups) {
  const CoarseMesh m = dicer::read_msh(data_path("dealii_grid_in_msh_01.3da.v41.msh"));
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_vertices(), 462);
  EXPECT_EQ(m.num_elements(), 200);
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 2);
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].id, 1);
  EXPECT_EQ(m.side_sets[0].element.size(), 460u);
  std::set<std::pair<Id, int>> distinct;
  for (std::size_t i = 0; i < 460; ++i) distinct.insert({m.side_sets[0].element[i], m.side_sets[0].side[i]});
  EXPECT_EQ(distinct.size(), 460u);
  EXPECT_TRUE(m.warnings.empty());
  // Classification from $Nodes entity blocks: this file lists every node on
  // a surface entity.
  for (std::size_t v = 0; v < m.vertex_geo_dim.size(); ++v) EXPECT_EQ(m.vertex_geo_dim[v], 2);
  EXPECT_EQ(m.vertex_file_id[0], 1);
  EXPECT_EQ(m.vertex_geo_tag[0], 18);  // first block: "2 18 0 12"
}

TEST(ReadMsh, DealiiStep49Msh41IsSurfaceMode) {
  const CoarseMesh m = dicer::read_msh(data_path("dealii_step-49_example.msh"));
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.corners_per_element(), 4);
  EXPECT_EQ(m.num_vertices(), 835);
  EXPECT_EQ(m.num_elements(), 744);
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 2);
  // Curves carry physical tags 0 (deal.ii's default boundary id: a group
  // in MSH 4.1, as Gmsh's reader lists it), 1, 2 and 3: Gmsh counts 156,
  // 12, 8 and 8 lines, the 184 of the boundary.
  ASSERT_EQ(m.side_sets.size(), 4u);
  std::map<Id, std::size_t> sides;
  for (const auto& s : m.side_sets) sides[s.id] += s.element.size();
  EXPECT_EQ(sides, (std::map<Id, std::size_t>{{0, 156}, {1, 12}, {2, 8}, {3, 8}}));
  EXPECT_TRUE(m.warnings.empty());
  for (auto z : m.z) EXPECT_EQ(z, 0.0);
}

// ---------------------------------------------------------------------------
// Gmsh's own re-saves (binary 2.2, binary 4.1, ASCII 4.1/2.2) read the same.

TEST(ReadMsh, GmshResavesOfFiredrakeCubeMatch) { check_resaves("firedrake_cube_hex.msh", true, true); }
TEST(ReadMsh, GmshResavesOfDealiiGridMatch) { check_resaves("dealii_grid_in_msh_01.3da.v41.msh", false, false); }
TEST(ReadMsh, GmshResavesOfStep49Match) { check_resaves("dealii_step-49_example.msh", false, true); }

// ---------------------------------------------------------------------------
// Hand-made binary files, in both byte orders.

TEST(ReadMsh, Binary41BothByteOrders) {
  SCOPED_TRACE("little endian");
  expect_tiny_cube(read_text(binary41(false)));
  SCOPED_TRACE("big endian");
  const CoarseMesh m = read_text(binary41(true));
  expect_tiny_cube(m);
  EXPECT_EQ(m.vertex_geo_dim, (std::vector<std::int8_t>{2, 2, 2, 2, 3, 3, 3, 3}));
  EXPECT_EQ(m.vertex_geo_tag, (std::vector<std::int32_t>{2, 2, 2, 2, 1, 1, 1, 1}));
}

TEST(ReadMsh, Binary22BothByteOrders) {
  SCOPED_TRACE("little endian");
  expect_tiny_cube(read_text(binary22(false)));
  SCOPED_TRACE("big endian");
  const CoarseMesh m = read_text(binary22(true));
  expect_tiny_cube(m);
  // Bottom nodes lie on the quad (entity 2), top nodes only on the hex (1).
  EXPECT_EQ(m.vertex_geo_dim, (std::vector<std::int8_t>{2, 2, 2, 2, 3, 3, 3, 3}));
  EXPECT_EQ(m.vertex_geo_tag, (std::vector<std::int32_t>{2, 2, 2, 2, 1, 1, 1, 1}));
}

// ---------------------------------------------------------------------------
// ASCII fixtures

// Two hexes stacked in z; nodes 1-12 (sparse tags x10, out of order).
const char* const kTwoHexNodes22 =
    "$Nodes\n12\n"
    "120 0 1 2\n10 0 0 0\n20 1 0 0\n30 1 1 0\n40 0 1 0\n50 0 0 1\n60 1 0 1\n70 1 1 1\n80 0 1 1\n"
    "90 0 0 2\n100 1 0 2\n110 1 1 2\n"
    "$EndNodes\n";

TEST(ReadMsh, Msh22NamesBlocksSetsAndSparseTags) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") +
                           "$PhysicalNames\n4\n3 7 \"water\"\n3 5 \"steel\"\n2 3 \"top face\"\n0 9 \"corner\"\n"
                           "$EndPhysicalNames\n" +
                           kTwoHexNodes22 +
                           "$Elements\n5\n"
                           "100 5 2 7 1 50 60 70 80 90 100 110 120\n"
                           "7 5 2 5 2 10 20 30 40 50 60 70 80\n"
                           "3 3 2 3 4 90 100 110 120\n"
                           "4 15 2 9 5 10\n"
                           "5 1 2 0 6 10 20\n"
                           "$EndElements\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.vertex_file_id, (std::vector<Id>{120, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110}));
  EXPECT_EQ(m.element_file_id, (std::vector<Id>{100, 7}));  // file order
  EXPECT_EQ(m.conn, (std::vector<Id>{5, 6, 7, 8, 9, 10, 11, 0, 1, 2, 3, 4, 5, 6, 7, 8}));
  ASSERT_EQ(m.blocks.size(), 2u);  // ordered by id
  EXPECT_EQ(m.blocks[0].id, 5);
  EXPECT_EQ(m.blocks[0].name, "steel");
  EXPECT_EQ(m.blocks[1].id, 7);
  EXPECT_EQ(m.blocks[1].name, "water");
  EXPECT_EQ(m.element_block, (std::vector<std::int32_t>{1, 0}));
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].id, 3);
  EXPECT_EQ(m.side_sets[0].name, "top face");
  EXPECT_EQ(m.side_sets[0].element, std::vector<Id>{0});
  EXPECT_EQ(m.side_sets[0].side, std::vector<std::int8_t>{5});  // top: corners 4,5,6,7
  ASSERT_EQ(m.node_sets.size(), 1u);
  EXPECT_EQ(m.node_sets[0].id, 9);
  EXPECT_EQ(m.node_sets[0].name, "corner");
  EXPECT_EQ(m.node_sets[0].vertex, std::vector<Id>{1});
  // Lowest element holding each node: point (10), line (20), quad (90..120),
  // hex (the rest).
  EXPECT_EQ(m.vertex_geo_dim, (std::vector<std::int8_t>{2, 0, 1, 3, 3, 3, 3, 3, 3, 2, 2, 2}));
  EXPECT_EQ(m.vertex_geo_tag, (std::vector<std::int32_t>{4, 5, 6, 2, 2, 1, 1, 1, 1, 4, 4, 4}));
  EXPECT_TRUE(m.warnings.empty());
}

TEST(ReadMsh, ElementsWithoutPhysicalGroupGetEntityBlocksAboveThePhysicalIds) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 +
                           "$Elements\n2\n"
                           "1 5 2 8 1 10 20 30 40 50 60 70 80\n"
                           "2 5 2 0 8 50 60 70 80 90 100 110 120\n"
                           "$EndElements\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  ASSERT_EQ(m.blocks.size(), 2u);
  EXPECT_EQ(m.blocks[0].id, 8);
  EXPECT_EQ(m.blocks[1].id, 9);
  EXPECT_EQ(m.blocks[1].name, "entity 8");
  EXPECT_EQ(m.element_block, (std::vector<std::int32_t>{0, 1}));
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_THAT(m.warnings[0], HasSubstr("no physical group"));
}

TEST(ReadMsh, BoundaryQuadMatchingNoFaceIsSkippedWithOneWarning) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 +
                           "$Elements\n4\n"
                           "1 5 2 1 1 10 20 30 40 50 60 70 80\n"
                           "2 3 2 2 3 10 20 70 80\n"   // a diagonal plane: no face
                           "3 3 2 2 3 10 60 110 40\n"  // no face either
                           "4 3 2 2 3 10 40 30 20\n"   // bottom, side 4
                           "$EndElements\n";
  const CoarseMesh m = read_text(text);
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].element, std::vector<Id>{0});
  EXPECT_EQ(m.side_sets[0].side, std::vector<std::int8_t>{4});
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_THAT(m.warnings[0], HasSubstr("2 quadrangles"));
  EXPECT_THAT(m.warnings[0], HasSubstr("element 2"));
}

TEST(ReadMsh, Msh41AsciiSurfaceWithParametricNodesAndSkippedSections) {
  // Two quads side by side on z = 0, edges in physical curve 11 "left" and
  // 12; nodes of the curve entity carry a parametric coordinate.
  const std::string text =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
      "$Comments\nanything $Nodes here\n$EndCommentsNot\n$EndComments\n"
      "$PhysicalNames\n2\n1 11 \"left\"\n2 20 \"plate\"\n$EndPhysicalNames\n"
      "$Entities\n0 2 1 0\n"
      "1 0 0 0 0 1 0 1 11 0\n"
      "2 2 0 0 2 1 0 2 12 13 0\n"
      "5 0 0 0 2 1 0 1 20 2 1 2\n"
      "$EndEntities\n"
      "$Nodes\n2 6 1 6\n"
      "1 1 1 2\n1\n4\n0 0 0 0\n0 1 0 1\n"
      "2 5 0 4\n2\n3\n5\n6\n1 0 0\n2 0 0\n2 1 0\n1 1 0\n"
      "$EndNodes\n"
      "$Elements\n3 4 1 4\n"
      "1 1 1 1\n3 1 4\n"
      "1 2 1 1\n4 3 5\n"
      "2 5 3 2\n1 1 2 6 4\n2 2 3 5 6\n"
      "$EndElements\n"
      "$NodeData\n1\n\"x\"\n1\n0.0\n3\n0\n1\n1\n1 0.5\n$EndNodeData\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.vertex_file_id, (std::vector<Id>{1, 4, 2, 3, 5, 6}));
  EXPECT_EQ(m.vertex(1), (dicer::Vec3{0, 1, 0}));
  EXPECT_EQ(m.conn, (std::vector<Id>{0, 2, 5, 1, 2, 3, 4, 5}));
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 20);
  EXPECT_EQ(m.blocks[0].name, "plate");
  ASSERT_EQ(m.side_sets.size(), 3u);
  EXPECT_EQ(m.side_sets[0].id, 11);
  EXPECT_EQ(m.side_sets[0].name, "left");
  EXPECT_EQ(m.side_sets[0].element, std::vector<Id>{0});
  EXPECT_EQ(m.side_sets[0].side, std::vector<std::int8_t>{5});  // edge (3,0)
  // Curve 2 is in physical groups 12 and 13: its line goes to both.
  EXPECT_EQ(m.side_sets[1].id, 12);
  EXPECT_EQ(m.side_sets[2].id, 13);
  EXPECT_EQ(m.side_sets[1].element, std::vector<Id>{1});
  EXPECT_EQ(m.side_sets[1].side, std::vector<std::int8_t>{3});  // edge (1,2)
  EXPECT_EQ(m.vertex_geo_dim, (std::vector<std::int8_t>{1, 1, 2, 2, 2, 2}));
  EXPECT_EQ(m.vertex_geo_tag, (std::vector<std::int32_t>{1, 1, 5, 5, 5, 5}));
}

// A surface entity in two physical groups (its quads go to the first's
// block) and a $Periodic section (not applied): both said, neither silent.
TEST(ReadMsh, Msh41ElementsInSeveralGroupsAndPeriodicSectionAreSaid) {
  const std::string text =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
      "$PhysicalNames\n2\n2 20 \"plate\"\n2 21 \"skin\"\n$EndPhysicalNames\n"
      "$Entities\n0 0 1 0\n"
      "5 0 0 0 2 1 0 2 20 21 0\n"
      "$EndEntities\n"
      "$Nodes\n1 6 1 6\n"
      "2 5 0 6\n1\n2\n3\n4\n5\n6\n0 0 0\n1 0 0\n2 0 0\n2 1 0\n1 1 0\n0 1 0\n"
      "$EndNodes\n"
      "$Elements\n1 2 1 2\n"
      "2 5 3 2\n1 1 2 5 6\n2 2 3 4 5\n"
      "$EndElements\n"
      "$Periodic\n1\n1 1 2\n0\n0\n$EndPeriodic\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 20);
  EXPECT_EQ(m.blocks[0].name, "plate");
  std::string all;
  for (const auto& w : m.warnings) all += w + "\n";
  EXPECT_THAT(all, HasSubstr("2 quadrangles are in physical groups 20 \"plate\", 21 \"skin\": each was put in the block of the first, 20"));
  EXPECT_THAT(all, HasSubstr("$Periodic section is not applied"));
  EXPECT_EQ(m.warnings.size(), 2u) << all;
}

TEST(ReadMsh, TinyCoordinatesUnderflowToZero) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") +
                           "$Nodes\n4\n1 0 0 1e-400\n2 +1.0e+00 0 -1e-320\n3 1 1 0\n4 0 1 0\n$EndNodes\n"
                           "$Elements\n1\n1 3 0 1 2 3 4\n$EndElements\n";
  const CoarseMesh m = read_text(text);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.z[0], 0.0);
  EXPECT_EQ(m.x[1], 1.0);
  EXPECT_LT(m.z[1], 0.0);
  // No tags: block is entity 0, nodes classified to it.
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 0);
  EXPECT_EQ(m.vertex_geo_dim, (std::vector<std::int8_t>{2, 2, 2, 2}));
}

TEST(ReadMsh, WindowsLineEndings) {
  std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 +
                     "$Elements\n1\n1 5 2 0 1 10 20 30 40 50 60 70 80\n$EndElements\n";
  std::string crlf;
  for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  const CoarseMesh m = read_text(crlf);
  EXPECT_EQ(m.num_vertices(), 12);
  EXPECT_EQ(m.num_elements(), 1);
  EXPECT_EQ(m.vertex(11), (dicer::Vec3{1, 1, 2}));
}

// Gmsh's MSH 2 writer lists an element once per physical group it is in,
// with the same tag and nodes: kept once, in its first group, with a warning.
TEST(ReadMsh, Msh22ElementRepeatedForASecondPhysicalGroupIsKeptOnce) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 +
                           "$Elements\n3\n"
                           "1 5 2 4 1 10 20 30 40 50 60 70 80\n"
                           "1 5 2 6 1 10 20 30 40 50 60 70 80\n"
                           "2 5 2 4 1 50 60 70 80 90 100 110 120\n"
                           "$EndElements\n";
  const CoarseMesh m = read_text(text);
  EXPECT_EQ(m.num_elements(), 2);
  ASSERT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.blocks[0].id, 4);
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_THAT(m.warnings[0], HasSubstr("listed again"));
  // A repeated tag with different nodes is still an error.
  const std::string bad = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 +
                          "$Elements\n2\n"
                          "1 5 2 4 1 10 20 30 40 50 60 70 80\n"
                          "1 5 2 6 1 50 60 70 80 90 100 110 120\n"
                          "$EndElements\n";
  EXPECT_THROW(read_text(bad), dicer::Error);
}

// ---------------------------------------------------------------------------
// Sections Gmsh skips, wherever they are (Gmsh and meshio read these files).

namespace {

const std::string kTwoHexElements22 =
    "$Elements\n2\n"
    "1 5 2 4 1 10 20 30 40 50 60 70 80\n"
    "2 5 2 4 1 50 60 70 80 90 100 110 120\n"
    "$EndElements\n";

// Number of nodes Gmsh itself reads from `path` (an independent reader).
std::size_t gmsh_node_count(const std::string& path) {
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::open(path);
  std::vector<std::size_t> tags;
  std::vector<double> coords, params;
  gmsh::model::mesh::getNodes(tags, coords, params);
  gmsh::finalize();
  return tags.size();
}

}  // namespace

TEST(ReadMsh, UnknownSectionsBeforeMeshFormatAreSkipped) {
  const std::string plain = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") + kTwoHexNodes22 + kTwoHexElements22;
  const std::string commented = "$Comments\nwritten by hand; $MeshFormat is not here\n$EndComments\n"
                                "$Foo\n1 2 3\n$EndFoo\n" +
                                plain + "$Bar\n$EndBar\n";
  TempDir tmp;
  const std::string path = tmp.path("commented.msh");
  write_file(path, commented);
  EXPECT_EQ(gmsh_node_count(path), 12u) << "Gmsh itself reads this file";
  const CoarseMesh a = read_text(plain);
  for (const CoarseMesh& b : {dicer::read_msh(path), dicer::read_coarse_mesh(path)}) {
    expect_consistent(b);
    EXPECT_EQ(b.num_elements(), 2);
    EXPECT_EQ(by_id(b).coords, by_id(a).coords);
    EXPECT_EQ(by_id(b).cells, by_id(a).cells);
  }
}

TEST(ReadMsh, Binary41AfterAComment) {
  TempDir tmp;
  const std::string path = tmp.path("commented_binary.msh");
  write_file(path, "\n$Comments\nbinary data follows\n$EndComments\n" + binary41(false));
  expect_tiny_cube(dicer::read_coarse_mesh(path));
}

// ---------------------------------------------------------------------------
// MSH 1 ($NOD / $ELM), written by Gmsh itself.

namespace {

// A 2 x 1 x 1 box meshed by Gmsh into 2 x 2 x 2 hexes, with a physical
// volume 7 "solid", the two end faces in physical surface 4 "ends" and a
// corner in physical point 9; written as MSH `version` (ASCII).
void gmsh_box(const std::string& path, double version) {
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::model::add("box");
  gmsh::model::occ::addBox(0, 0, 0, 2, 1, 1);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair entities;
  gmsh::model::getEntities(entities, 1);
  for (const auto& [dim, tag] : entities) gmsh::model::mesh::setTransfiniteCurve(tag, 3);
  gmsh::model::getEntities(entities, 2);
  for (const auto& [dim, tag] : entities) {
    gmsh::model::mesh::setTransfiniteSurface(tag);
    gmsh::model::mesh::setRecombine(2, tag);
  }
  gmsh::model::mesh::setTransfiniteVolume(1);
  gmsh::model::addPhysicalGroup(3, {1}, 7);
  gmsh::model::setPhysicalName(3, 7, "solid");
  gmsh::model::addPhysicalGroup(2, {1, 2}, 4);
  gmsh::model::setPhysicalName(2, 4, "ends");
  gmsh::model::addPhysicalGroup(0, {1}, 9);
  gmsh::model::mesh::generate(3);
  gmsh::option::setNumber("Mesh.MshFileVersion", version);
  gmsh::option::setNumber("Mesh.Binary", 0);
  gmsh::write(path);
  gmsh::finalize();
}

}  // namespace

TEST(ReadMsh, Msh1WrittenByGmshReadsLikeMsh22And41) {
  TempDir tmp;
  const std::string v1 = tmp.path("box_v1.msh"), v22 = tmp.path("box_v22.msh"), v41 = tmp.path("box_v41.msh");
  gmsh_box(v1, 1.0);
  gmsh_box(v22, 2.2);
  gmsh_box(v41, 4.1);
  ASSERT_EQ(dicer::test::read_file(v1).rfind("$NOD\n", 0), 0u) << "Gmsh wrote MSH 1";
  const CoarseMesh m1 = dicer::read_coarse_mesh(v1);
  expect_consistent(m1);
  EXPECT_EQ(m1.mode, Mode::Volume);
  EXPECT_EQ(m1.num_vertices(), 27);  // 3 x 3 x 3 grid points
  EXPECT_EQ(m1.num_elements(), 8);
  ASSERT_EQ(m1.blocks.size(), 1u);
  EXPECT_EQ(m1.blocks[0].id, 7);
  EXPECT_EQ(m1.blocks[0].name, "");  // MSH 1 has no names
  ASSERT_EQ(m1.side_sets.size(), 1u);
  EXPECT_EQ(m1.side_sets[0].id, 4);
  EXPECT_EQ(m1.side_sets[0].element.size(), 8u);  // 2 x 2 quads on each end
  ASSERT_EQ(m1.node_sets.size(), 1u);
  EXPECT_EQ(m1.node_sets[0].id, 9);
  EXPECT_EQ(m1.node_sets[0].vertex.size(), 1u);
  EXPECT_TRUE(m1.warnings.empty());

  // The same mesh through MSH 2.2 (names dropped: MSH 1 cannot carry them)
  // and MSH 4.1 (which states the classification instead of implying it).
  CoarseMesh m22 = dicer::read_coarse_mesh(v22);
  EXPECT_EQ(m22.blocks[0].name, "solid");
  for (auto& b : m22.blocks) b.name.clear();
  for (auto& s : m22.side_sets) s.name.clear();
  EXPECT_TRUE(expect_same_mesh(m1, m22, true));
  EXPECT_EQ(m1.node_sets[0].vertex, m22.node_sets[0].vertex);
  CoarseMesh m41 = dicer::read_coarse_mesh(v41);
  for (auto& b : m41.blocks) b.name.clear();
  for (auto& s : m41.side_sets) s.name.clear();
  expect_same_mesh(m1, m41, false);
}

TEST(ReadMsh, Msh1WithoutPhysicalGroups) {
  // A hex in elementary entity 12 and a point in entity 3; reg-phys 0 is "none".
  const std::string text =
      "$NOD\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$ENDNOD\n"
      "$ELM\n2\n"
      "3 5 0 12 8 1 2 3 4 5 6 7 8\n"
      "4 15 0 3 1 1\n"
      "$ENDELM\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  EXPECT_EQ(m.element_file_id, std::vector<Id>{3});
  ASSERT_EQ(m.blocks.size(), 1u);  // no physical group: the elementary entity
  EXPECT_EQ(m.blocks[0].id, 12);
  EXPECT_EQ(m.blocks[0].name, "entity 12");
  EXPECT_EQ(m.vertex_geo_dim[0], 0);  // on the point element
  EXPECT_EQ(m.vertex_geo_tag[0], 3);
}

// ---------------------------------------------------------------------------
// Lower-dimensional elements (README, Inputs): boundary quads, lines and
// points are sets; anything else below the mesh's dimension is skipped with
// one warning naming where it was.

TEST(ReadMsh, LowerDimensionalElementsOfAHexMeshAreSkippedWithOneWarning) {
  const std::string text = std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n") +
                           "$PhysicalNames\n3\n2 7 \"skin\"\n1 12 \"beam\"\n3 1 \"solid\"\n$EndPhysicalNames\n" +
                           kTwoHexNodes22 +
                           "$Elements\n7\n"
                           "1 5 2 1 1 10 20 30 40 50 60 70 80\n"
                           "2 5 2 1 1 50 60 70 80 90 100 110 120\n"
                           "3 2 2 7 4 10 20 30\n"         // triangles in physical surface 7
                           "4 2 2 7 4 10 30 40\n"
                           "5 8 2 0 9 10 20 30\n"         // a 3-node line in no group: classification only
                           "6 1 2 12 5 90 100\n"          // a line in physical curve 12
                           "7 3 2 7 4 10 40 30 20\n"      // a quad of the same group: a side
                           "$EndElements\n";
  const CoarseMesh m = read_text(text);
  expect_consistent(m);
  EXPECT_EQ(m.mode, Mode::Volume);
  EXPECT_EQ(m.num_elements(), 2);
  ASSERT_EQ(m.side_sets.size(), 1u);
  EXPECT_EQ(m.side_sets[0].id, 7);
  EXPECT_EQ(m.side_sets[0].element.size(), 1u);
  ASSERT_EQ(m.warnings.size(), 1u);
  const std::string& w = m.warnings[0];
  EXPECT_THAT(w, HasSubstr("lower dimension than the hexahedra"));
  EXPECT_THAT(w, HasSubstr("2 triangle (type 2) in physical group 7 \"skin\""));
  EXPECT_THAT(w, testing::Not(HasSubstr("type 8")));
  EXPECT_THAT(w, HasSubstr("1 line (type 1) in physical group 12 \"beam\""));
}

TEST(ReadMsh, SecondOrderLinesOfAQuadMeshAreBoundaryLinesIn41) {
  // A 3-node line (type 8) is a line: its ends are its corners, its middle
  // node must exist and is not kept; in no physical group it is only the
  // classification of its nodes, as a 2-node line, so no warning.
  const std::string text = std::string("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n") +
                           "$Nodes\n1 5 1 5\n2 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0 0\n$EndNodes\n"
                           "$Elements\n2 2 1 2\n2 1 3 1\n1 1 2 3 4\n1 3 8 1\n2 1 2 5\n$EndElements\n";
  const CoarseMesh m = read_text(text);
  EXPECT_EQ(m.mode, Mode::Surface);
  EXPECT_EQ(m.num_elements(), 1);
  EXPECT_TRUE(m.warnings.empty()) << m.warnings[0];
  EXPECT_FALSE(m.second_order());  // a line's middle node is no mid node of the quad
}

// Second order (tests/geometry/test_second_order.cpp dices real ones): a
// HEX20 (type 17) and a hex (type 5) in either order; the HEX20's nodes
// after its corners, in Gmsh's order, are its mid nodes, the hex has none.
TEST(ReadMsh, MixedFirstAndSecondOrderHexesIn22) {
  // Gmsh's HEX20: nodes 8..19 between these corners (Gmsh's documentation).
  const int edges[12][2] = {{0, 1}, {0, 3}, {0, 4}, {1, 2}, {1, 5}, {2, 3}, {2, 6}, {3, 7}, {4, 5}, {4, 7}, {5, 6}, {6, 7}};
  const double xyz[12][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1},
                             {1, 1, 1}, {0, 1, 1}, {2, 0, 0}, {2, 1, 0}, {2, 0, 1}, {2, 1, 1}};
  const int hex1[8] = {1, 2, 3, 4, 5, 6, 7, 8}, hex2[8] = {2, 9, 10, 3, 6, 11, 12, 7};
  for (const bool quadratic_first : {true, false}) {
    SCOPED_TRACE(quadratic_first ? "HEX20 first" : "HEX8 first");
    std::string nodes, elements;
    int count = 12;
    for (int v = 0; v < 12; ++v)
      nodes += std::to_string(v + 1) + " " + std::to_string(xyz[v][0]) + " " + std::to_string(xyz[v][1]) + " " +
               std::to_string(xyz[v][2]) + "\n";
    const int* q = quadratic_first ? hex1 : hex2;
    std::string hex20 = "1 17 2 1 1";
    for (int c = 0; c < 8; ++c) hex20 += " " + std::to_string(q[c]);
    for (const auto& e : edges) {
      const int a = q[e[0]] - 1, b = q[e[1]] - 1;
      nodes += std::to_string(++count) + " " + std::to_string(0.5 * (xyz[a][0] + xyz[b][0])) + " " +
               std::to_string(0.5 * (xyz[a][1] + xyz[b][1])) + " " + std::to_string(0.5 * (xyz[a][2] + xyz[b][2]) + 0.125) +
               "\n";
      hex20 += " " + std::to_string(count);
    }
    std::string hex8 = "2 5 2 1 1";
    for (int c = 0; c < 8; ++c) hex8 += " " + std::to_string((quadratic_first ? hex2 : hex1)[c]);
    elements = quadratic_first ? hex20 + "\n" + hex8 + "\n" : hex8 + "\n" + hex20 + "\n";
    const CoarseMesh m = read_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" + std::to_string(count) + "\n" +
                                   nodes + "$EndNodes\n$Elements\n2\n" + elements + "$EndElements\n");
    ASSERT_TRUE(m.second_order());
    EXPECT_EQ(m.num_vertices(), 12);
    ASSERT_EQ(m.mid.size(), 2u * dicer::kHexMidSlots);
    ASSERT_EQ(m.mid_x.size(), 12u);
    for (Id e = 0; e < 2; ++e) {
      const bool is20 = m.element_file_id[e] == 1;
      for (int s = 0; s < dicer::kHexMidSlots; ++s) {
        const Id k = m.mid[static_cast<size_t>(e) * dicer::kHexMidSlots + s];
        if (!is20 || s >= 12) {
          EXPECT_EQ(k, -1) << "element " << e << " slot " << s;
          continue;
        }
        ASSERT_GE(k, 0);
        // Slot s is dicer's local edge s: its mid node sits between its corners (+0.125 in z).
        const auto a = m.vertex(m.conn[8 * e + dicer::kHexEdge[s][0]]), b = m.vertex(m.conn[8 * e + dicer::kHexEdge[s][1]]);
        EXPECT_DOUBLE_EQ(m.mid_x[k], 0.5 * (a.x + b.x)) << s;
        EXPECT_DOUBLE_EQ(m.mid_y[k], 0.5 * (a.y + b.y)) << s;
        EXPECT_DOUBLE_EQ(m.mid_z[k], 0.5 * (a.z + b.z) + 0.125) << s;
      }
    }
  }
}
