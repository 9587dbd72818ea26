// write_msh (Gmsh MSH 4.1, ASCII and binary) read back by real readers: the
// Gmsh 4.8 C++ API, meshio (tests/roundtrip/msh_check.py) and dicer's own
// MSH reader (read_coarse_mesh), for chunks of a diced volume mesh and for a
// diced surface mesh; plus the temp-file discipline on failure (disk full).
#include <fcntl.h>
#include <gmsh.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

FineMesh dice_file(const std::string& name) {
  IntervalRequest req;
  req.global = 2;
  return FineMesh::dice(read_coarse_mesh(test::data_path(name)), req);
}

std::unique_ptr<ExportChunk> make_chunk(const FineMesh& m, Id k, Id count) {
  const auto ranges = plan_chunks(m, count);
  auto c = std::make_unique<ExportChunk>(m, ranges[static_cast<std::size_t>(k)]);
  c->prepare(MeshSets{m.coarse()->side_sets, m.coarse()->node_sets});
  return c;
}

// What the writer should put in the file, from the chunk alone.
struct Expected {
  std::map<std::int32_t, Id> per_block;             // block index -> elements
  std::vector<std::pair<std::size_t, Id>> sets;     // (set index, written members) for sets with members
  Id boundary = 0;
};

bool side_written(Mode mode, int side) { return mode == Mode::Volume ? side >= 0 && side <= 5 : side >= 2 && side <= 5; }

Expected expected(const ExportChunk& c) {
  Expected e;
  for (auto b : c.element_block()) ++e.per_block[b];
  for (std::size_t s = 0; s < c.side_sets().size(); ++s) {
    Id n = 0;
    for (auto side : c.side_sets()[s].side) n += side_written(c.mode(), side);
    if (n > 0) e.sets.push_back({s, n}), e.boundary += n;
  }
  return e;
}

std::string block_name(const Block& b) { return b.name.empty() ? "block " + std::to_string(b.id) : b.name; }
std::string set_name(const ExportChunk::SideMembers& s) {
  return s.name.empty() ? "sideset " + std::to_string(s.id) : s.name;
}

// Global node ids (+1) of the corners of side `side` of fine element `id`.
std::vector<std::size_t> side_tags(const FineMesh& m, Id id, int side) {
  const FineElement fe = m.element(id);
  if (m.mode() == Mode::Volume) {
    std::vector<std::size_t> t;
    for (int q = 0; q < 4; ++q) t.push_back(static_cast<std::size_t>(fe.nodes[kHexSideCorners[side][q]]) + 1);
    return t;
  }
  const int a = side - 2;
  return {static_cast<std::size_t>(fe.nodes[a]) + 1, static_cast<std::size_t>(fe.nodes[(a + 1) % 4]) + 1};
}

std::vector<std::string> temp_leftovers(const std::filesystem::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp-") != std::string::npos) out.push_back(e.path().string());
  return out;
}

// Opens `path` with the Gmsh API and checks everything against the chunk.
void check_with_gmsh(const ExportChunk& c, const std::string& path) {
  const FineMesh& m = c.mesh();
  const bool vol = c.mode() == Mode::Volume;
  const int dim = vol ? 3 : 2;
  const Expected ex = expected(c);
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  struct Fin {
    ~Fin() { gmsh::finalize(); }
  } fin;
  ASSERT_NO_THROW(gmsh::open(path)) << path;

  // Nodes: every node, coordinates bit-equal to the fine mesh.
  std::vector<std::size_t> tags;
  std::vector<double> xyz, par;
  gmsh::model::mesh::getNodes(tags, xyz, par, -1, -1, false, false);
  ASSERT_EQ(tags.size(), static_cast<std::size_t>(c.num_nodes())) << path;
  std::vector<std::size_t> sorted = tags;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 0; i < sorted.size(); ++i)
    ASSERT_EQ(sorted[i], static_cast<std::size_t>(c.node_global()[i]) + 1) << i;
  for (std::size_t i = 0; i < tags.size(); ++i) {
    const Vec3 p = m.node(static_cast<Id>(tags[i]) - 1);
    ASSERT_EQ(xyz[3 * i], p.x) << "node tag " << tags[i];
    ASSERT_EQ(xyz[3 * i + 1], p.y) << "node tag " << tags[i];
    ASSERT_EQ(xyz[3 * i + 2], p.z) << "node tag " << tags[i];
  }

  // Cells: all of them, tags = global id + 1, connectivity = element().nodes + 1.
  std::vector<std::size_t> etags, enodes;
  gmsh::model::mesh::getElementsByType(vol ? 5 : 3, etags, enodes);
  ASSERT_EQ(etags.size(), static_cast<std::size_t>(c.num_elements()));
  std::vector<std::size_t> esorted = etags;
  std::sort(esorted.begin(), esorted.end());
  for (std::size_t i = 0; i < esorted.size(); ++i)
    ASSERT_EQ(esorted[i], static_cast<std::size_t>(c.element_global()[i]) + 1) << i;
  const std::size_t nc = static_cast<std::size_t>(c.corners());
  for (std::size_t i = 0; i < etags.size(); i += (i % 53 == 0 ? 1 : 37)) {
    const FineElement fe = m.element(static_cast<Id>(etags[i]) - 1);
    for (std::size_t q = 0; q < nc; ++q)
      ASSERT_EQ(enodes[nc * i + q], static_cast<std::size_t>(fe.nodes[q]) + 1) << "element tag " << etags[i];
  }

  // Boundary elements of the side sets.
  std::vector<std::size_t> btags, bnodes;
  gmsh::model::mesh::getElementsByType(vol ? 3 : 1, btags, bnodes);
  EXPECT_EQ(btags.size(), static_cast<std::size_t>(ex.boundary));
  EXPECT_EQ(std::set<std::size_t>(btags.begin(), btags.end()).size(), btags.size()) << "boundary tags repeat";
  for (auto t : btags) EXPECT_GT(t, static_cast<std::size_t>(m.num_elements()));

  // Physical groups: one per block present, one per side set with members.
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups, dim);
  ASSERT_EQ(groups.size(), ex.per_block.size());
  const auto& blocks = m.info().blocks;
  for (const auto& [b, n] : ex.per_block) {
    const Block& blk = blocks[static_cast<std::size_t>(b)];
    ASSERT_GT(blk.id, 0);  // the fixtures' ids are usable as physical tags
    const int tag = static_cast<int>(blk.id);
    std::string name;
    gmsh::model::getPhysicalName(dim, tag, name);
    EXPECT_EQ(name, block_name(blk));
    std::vector<int> ents;
    gmsh::model::getEntitiesForPhysicalGroup(dim, tag, ents);
    ASSERT_EQ(ents.size(), 1u) << name;
    std::vector<std::size_t> t, nt;
    gmsh::model::mesh::getElementsByType(vol ? 5 : 3, t, nt, ents[0]);
    EXPECT_EQ(t.size(), static_cast<std::size_t>(n)) << name;
    for (auto et : t) ASSERT_EQ(m.element(static_cast<Id>(et) - 1).block, b) << name;
  }
  gmsh::vectorpair side_groups;
  gmsh::model::getPhysicalGroups(side_groups, dim - 1);
  ASSERT_EQ(side_groups.size(), ex.sets.size());
  for (const auto& [s, n] : ex.sets) {
    const auto& ss = c.side_sets()[s];
    ASSERT_GE(ss.id, 0);
    const int tag = static_cast<int>(ss.id);
    std::string name;
    gmsh::model::getPhysicalName(dim - 1, tag, name);
    // Group 0 (step-49's default boundary) goes unnamed: Gmsh would put its
    // name on group 1.
    EXPECT_EQ(name, ss.id == 0 ? std::string() : set_name(ss));
    std::vector<int> ents;
    gmsh::model::getEntitiesForPhysicalGroup(dim - 1, tag, ents);
    ASSERT_EQ(ents.size(), 1u) << name;
    std::vector<std::size_t> t, nt;
    gmsh::model::mesh::getElementsByType(vol ? 3 : 1, t, nt, ents[0]);
    ASSERT_EQ(t.size(), static_cast<std::size_t>(n)) << name;
    // In member order: the fine element's side corners, Exodus side order.
    const std::size_t k = vol ? 4 : 2;
    std::size_t i = 0;
    for (std::size_t q = 0; q < ss.element.size(); ++q) {
      if (!side_written(c.mode(), ss.side[q])) continue;
      const Id g = c.element_global()[static_cast<std::size_t>(ss.element[q])];
      const auto want = side_tags(m, g, ss.side[q]);
      for (std::size_t a = 0; a < k; ++a) ASSERT_EQ(nt[k * i + a], want[a]) << name << " member " << q;
      ++i;
    }
  }
}

using Proc = test::CliResult;
// Without a shell; the foreign python's variables must not leak into Debian's.
Proc run(const std::vector<std::string>& args) { return test::run_process(args, {}, test::kForeignPythonEnv); }

// The value text of `"key": value` in msh_check.py's one-key-per-line output.
std::string json_value(const std::string& json, const std::string& key) {
  const std::string k = "\"" + key + "\": ";
  std::istringstream in(json);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(k, 0) == 0) {
      std::string v = line.substr(k.size());
      if (!v.empty() && v.back() == ',') v.pop_back();
      return v;
    }
  return {};
}
std::vector<double> json_doubles(const std::string& v) {
  std::vector<double> out;
  std::string s = v;
  for (char& ch : s)
    if (ch == '[' || ch == ']' || ch == ',') ch = ' ';
  std::istringstream in(s);
  for (std::string tok; in >> tok;) out.push_back(std::strtod(tok.c_str(), nullptr));
  return out;
}

// meshio: counts, physical names and tags, and the first cell's corner
// coordinates (bit-equal), against the chunk.
void check_with_meshio(const ExportChunk& c, const std::string& path, bool* skipped) {
  *skipped = false;
  const Proc p = run({"/usr/bin/python3", std::string(DICER_SOURCE_DIR) + "/tests/roundtrip/msh_check.py", path});
  if (p.exit_code == 77 || p.exit_code == 127) {
    *skipped = true;
    return;
  }
  ASSERT_EQ(p.exit_code, 0) << p.err << p.out;
  const FineMesh& m = c.mesh();
  const bool vol = c.mode() == Mode::Volume;
  const int dim = vol ? 3 : 2;
  const std::string cell = vol ? "hexahedron" : "quad", side = vol ? "quad" : "line";
  const Expected ex = expected(c);
  EXPECT_EQ(json_value(p.out, "points"), std::to_string(c.num_nodes())) << p.out;
  EXPECT_EQ(json_value(p.out, "cells_" + cell), std::to_string(c.num_elements())) << p.out;
  if (ex.boundary > 0) {
    EXPECT_EQ(json_value(p.out, "cells_" + side), std::to_string(ex.boundary)) << p.out;
  }
  const auto& blocks = m.info().blocks;
  for (const auto& blk : blocks)
    EXPECT_EQ(json_value(p.out, "physical_" + std::to_string(dim) + "_" + std::to_string(blk.id)),
              "\"" + block_name(blk) + "\"")
        << p.out;
  for (const auto& ss : c.side_sets())
    if (ss.id != 0) {  // group 0 goes unnamed (above)
      EXPECT_EQ(json_value(p.out, "physical_" + std::to_string(dim - 1) + "_" + std::to_string(ss.id)),
                "\"" + set_name(ss) + "\"")
          << p.out;
    }
  for (const auto& [b, n] : ex.per_block)
    EXPECT_EQ(json_value(p.out, "tagged_" + cell + "_" + std::to_string(blocks[static_cast<std::size_t>(b)].id)),
              std::to_string(n))
        << p.out;
  for (const auto& [s, n] : ex.sets)
    EXPECT_EQ(json_value(p.out, "tagged_" + side + "_" + std::to_string(c.side_sets()[s].id)), std::to_string(n))
        << p.out;
  // The first cell in the file: the lowest global id of the first block present.
  const std::int32_t first_block = ex.per_block.begin()->first;
  Id first = -1;
  for (std::size_t e = 0; e < c.element_global().size() && first < 0; ++e)
    if (c.element_block()[e] == first_block) first = c.element_global()[e];
  const FineElement fe = m.element(first);
  const auto got = json_doubles(json_value(p.out, "first_" + cell));
  ASSERT_EQ(got.size(), 3u * static_cast<std::size_t>(c.corners())) << p.out;
  for (int q = 0; q < c.corners(); ++q) {
    const Vec3 v = m.node(fe.nodes[q]);
    EXPECT_EQ(got[3 * q], v.x);
    EXPECT_EQ(got[3 * q + 1], v.y);
    EXPECT_EQ(got[3 * q + 2], v.z);
  }
}

class ExportMshPrism : public ::testing::TestWithParam<bool> {};

}  // namespace

TEST_P(ExportMshPrism, GmshApiReadsEveryChunk) {
  const bool binary = GetParam();
  const FineMesh m = dice_file("cardinal_prism.exo");
  test::TempDir tmp;
  Id total = 0;
  for (Id k = 0; k < 2; ++k) {
    const auto c = make_chunk(m, k, 2);
    total += c->num_elements();
    const std::string path = tmp.path("prism" + std::to_string(k) + ".msh");
    ASSERT_GT(expected(*c).sets.size(), 1u);  // the checks below are not vacuous
    write_msh(*c, path, binary);
    EXPECT_TRUE(temp_leftovers(tmp.dir()).empty());
    SCOPED_TRACE(path);
    check_with_gmsh(*c, path);
  }
  EXPECT_EQ(total, m.num_elements());
}

TEST_P(ExportMshPrism, MeshioReadsEveryChunk) {
  const bool binary = GetParam();
  const FineMesh m = dice_file("cardinal_prism.exo");
  test::TempDir tmp;
  for (Id k = 0; k < 2; ++k) {
    const auto c = make_chunk(m, k, 2);
    const std::string path = tmp.path("prism" + std::to_string(k) + ".msh");
    write_msh(*c, path, binary);
    SCOPED_TRACE(path);
    bool skipped = false;
    check_with_meshio(*c, path, &skipped);
    if (skipped) DICER_SKIP_OR_FAIL_IN_CI("meshio (python3-meshio) is not available to /usr/bin/python3");
  }
}

TEST_P(ExportMshPrism, DicerReaderReadsTheExport) {
  const bool binary = GetParam();
  const FineMesh m = dice_file("cardinal_prism.exo");
  test::TempDir tmp;
  for (Id k = 0; k < 2; ++k) {
    const auto c = make_chunk(m, k, 2);
    const std::string path = tmp.path("prism" + std::to_string(k) + ".msh");
    write_msh(*c, path, binary);
    const CoarseMesh back = read_coarse_mesh(path);
    EXPECT_EQ(back.mode, Mode::Volume);
    EXPECT_EQ(back.num_elements(), c->num_elements());
    EXPECT_EQ(back.num_vertices(), c->num_nodes());
    EXPECT_EQ(back.blocks.size(), expected(*c).per_block.size());
    // Same coordinates for every element's first corner (file ids = node tags).
    for (Id e = 0; e < back.num_elements(); e += 97) {
      const Id g = back.element_file_id[static_cast<std::size_t>(e)] - 1;
      const FineElement fe = m.element(g);
      for (int q = 0; q < 8; ++q) {
        const Id v = back.conn[static_cast<std::size_t>(8 * e + q)];
        EXPECT_EQ(back.vertex_file_id[static_cast<std::size_t>(v)] - 1, fe.nodes[q]);
        EXPECT_EQ(back.vertex(v), m.node(fe.nodes[q]));
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(ExportMsh, ExportMshPrism, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "Binary" : "Ascii"; });

TEST(ExportMsh, WholeMeshChunkAndMergedChunksHoldEveryElement) {
  const FineMesh m = dice_file("cardinal_prism.exo");
  test::TempDir tmp;
  const auto whole = make_chunk(m, 0, 1);
  Id boundary = 0;
  for (const auto& s : whole->side_sets()) boundary += static_cast<Id>(s.element.size());
  const std::string one = tmp.path("whole.msh");
  write_msh(*whole, one, true);
  std::vector<std::string> parts;
  for (Id k = 0; k < 4; ++k) {
    parts.push_back(tmp.path("part" + std::to_string(k) + ".msh"));
    write_msh(*make_chunk(m, k, 4), parts.back(), k % 2 == 1);
  }
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  struct Fin {
    ~Fin() { gmsh::finalize(); }
  } fin;
  // (Gmsh 4.8 fills its output vectors only when they come in empty.)
  std::vector<std::size_t> tags, btags;
  auto counts = [&] {
    std::vector<std::size_t> n1, n2;
    tags.clear(), btags.clear();
    gmsh::model::mesh::getElementsByType(5, tags, n1);
    gmsh::model::mesh::getElementsByType(3, btags, n2);
    return std::make_pair(tags.size(), btags.size());
  };
  // Elements per physical group (block or side set).
  auto groups = [] {
    std::map<std::pair<int, int>, std::size_t> out;
    gmsh::vectorpair g;
    gmsh::model::getPhysicalGroups(g);
    for (const auto& [dim, tag] : g) {
      std::vector<int> ents;
      gmsh::model::getEntitiesForPhysicalGroup(dim, tag, ents);  // once per merged file that names it
      for (int e : std::set<int>(ents.begin(), ents.end())) {
        std::vector<int> types;
        std::vector<std::vector<std::size_t>> et, nt;
        gmsh::model::mesh::getElements(types, et, nt, dim, e);
        for (const auto& v : et) out[{dim, tag}] += v.size();
      }
    }
    return out;
  };
  gmsh::open(one);
  EXPECT_EQ(counts(), std::make_pair(static_cast<std::size_t>(m.num_elements()), static_cast<std::size_t>(boundary)));
  const auto whole_groups = groups();
  EXPECT_GE(whole_groups.size(), 3u);  // the prism's block and side sets
  // The chunk files merge into the whole mesh: volume and boundary tags are
  // the same in every chunk and never collide, and so are entity tags: each
  // physical group holds what it holds in the whole file (entity tags
  // counted per chunk put side sets on each other's entities).
  gmsh::clear();
  gmsh::open(parts[0]);
  for (std::size_t k = 1; k < parts.size(); ++k) gmsh::merge(parts[k]);
  EXPECT_EQ(counts(), std::make_pair(static_cast<std::size_t>(m.num_elements()), static_cast<std::size_t>(boundary)));
  EXPECT_EQ(groups(), whole_groups);
  std::set<std::size_t> all(tags.begin(), tags.end());
  all.insert(btags.begin(), btags.end());
  EXPECT_EQ(all.size(), tags.size() + btags.size());
}

TEST(ExportMsh, SurfaceMeshWritesQuadsAndBoundaryLines) {
  Id lines = 0;
  for (const char* name : {"libmesh_cylinder_shell.exo", "dealii_step-49_example.msh"}) {
    SCOPED_TRACE(name);
    const FineMesh m = dice_file(name);
    ASSERT_EQ(m.mode(), Mode::Surface);
    test::TempDir tmp;
    const auto c = make_chunk(m, 0, 1);
    lines += expected(*c).boundary;
    for (bool binary : {false, true}) {
      const std::string path = tmp.path(binary ? "s.bin.msh" : "s.msh");
      write_msh(*c, path, binary);
      SCOPED_TRACE(path);
      check_with_gmsh(*c, path);
      if (::testing::Test::HasFatalFailure()) return;
      const CoarseMesh back = read_coarse_mesh(path);
      EXPECT_EQ(back.mode, Mode::Surface);
      EXPECT_EQ(back.num_elements(), m.num_elements());
      bool skipped = false;
      check_with_meshio(*c, path, &skipped);
      if (skipped) DICER_SKIP_OR_FAIL_IN_CI("meshio (python3-meshio) is not available to /usr/bin/python3");
    }
  }
  EXPECT_GT(lines, 0);  // boundary lines were written and checked
}

TEST(ExportMsh, ReplacesAnExistingFileAndFailsCleanly) {
  const FineMesh m = dice_file("cardinal_prism.exo");
  const auto c = make_chunk(m, 1, 2);
  test::TempDir tmp;
  const std::string path = tmp.path("out.msh");
  test::write_file(path, "old");
  write_msh(*c, path, false);
  EXPECT_EQ(test::read_file(path).rfind("$MeshFormat\n4.1 0 8\n", 0), 0u);
  EXPECT_TRUE(temp_leftovers(tmp.dir()).empty());

  // A folder that does not exist: Io, naming the path.
  const std::string missing = tmp.path("no/such/dir/out.msh");
  try {
    write_msh(*c, missing, true);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io);
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }

  // Disk full (a file size limit in a child process): Io, nothing left behind.
  const std::string full = tmp.path("full.msh");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit lim {
      100000, 100000
    };
    ::setrlimit(RLIMIT_FSIZE, &lim);
    int rc = 1;
    try {
      write_msh(*c, full, false);
    } catch (const Error& e) {
      rc = e.kind() == ErrorKind::Io && std::string(e.what()).find(full) != std::string::npos ? 0 : 2;
    }
    ::_exit(rc);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_FALSE(std::filesystem::exists(full));
  EXPECT_TRUE(temp_leftovers(tmp.dir()).empty());
}
