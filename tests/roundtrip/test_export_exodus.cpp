// write_exodus against real readers: the Exodus II C library (every
// coordinate and every element compared with FineMesh through the id maps),
// the project's own read_coarse_mesh, and meshio + netCDF4-python
// (tests/roundtrip/exodus_check.py).
#include <exodusII.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netcdf.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "test_support.hpp"


using namespace dicer;

namespace {

constexpr const char* kPython = "/usr/bin/python3";

// ------------------------------------------------------------ the mesh under test

struct Diced {
  FineMesh mesh;
  MeshSets sets;
};

Diced dice(CoarseMesh coarse, Id global = 2) {
  IntervalRequest req;
  req.global = global;
  Diced d{FineMesh::dice(std::move(coarse), req), {}};
  d.sets = MeshSets{d.mesh.coarse()->side_sets, d.mesh.coarse()->node_sets};
  return d;
}
Diced dice_file(const std::string& name, Id global = 2) {
  return dice(read_coarse_mesh(test::data_path(name)), global);
}

// ------------------------------------------------------------ read back with the Exodus library

struct ExoBlock {
  std::int64_t id = 0, count = 0, nodes_per_element = 0;
  std::string name, type;
  std::vector<std::int64_t> conn;
};
struct ExoSet {
  std::int64_t id = 0;
  std::string name;
  std::vector<std::int64_t> entries, extra;  // side set: elements, sides; node set: nodes
};
struct ExoFile {
  ex_init_params init{};
  int format = -1;  // nc_inq_format
  std::vector<double> x, y, z;
  std::vector<std::string> coord_names;
  std::vector<std::int64_t> node_map, elem_map;
  std::vector<ExoBlock> blocks;
  std::vector<ExoSet> side_sets, node_sets;
};

std::vector<std::string> get_names(int exoid, ex_entity_type type, std::int64_t count) {
  std::vector<std::vector<char>> buf(static_cast<std::size_t>(count), std::vector<char>(257, '\0'));
  std::vector<char*> ptr;
  for (auto& b : buf) ptr.push_back(b.data());
  std::vector<std::string> out;
  if (count == 0) return out;
  EXPECT_GE(ex_get_names(exoid, type, ptr.data()), 0);
  for (auto& b : buf) out.emplace_back(b.data());
  return out;
}

std::vector<ExoSet> get_sets(int exoid, ex_entity_type type, std::int64_t count) {
  std::vector<std::int64_t> ids(static_cast<std::size_t>(count));
  if (count > 0) {
    EXPECT_GE(ex_get_ids(exoid, type, ids.data()), 0);
  }
  const auto names = get_names(exoid, type, count);
  std::vector<ExoSet> sets;
  for (std::size_t s = 0; s < ids.size(); ++s) {
    ExoSet set;
    set.id = ids[s];
    set.name = names[s];
    std::int64_t n = 0, df = 0;
    EXPECT_GE(ex_get_set_param(exoid, type, set.id, &n, &df), 0);
    set.entries.resize(static_cast<std::size_t>(n));
    set.extra.resize(type == EX_SIDE_SET ? static_cast<std::size_t>(n) : 0);
    if (n > 0) {
      EXPECT_GE(ex_get_set(exoid, type, set.id, set.entries.data(), type == EX_SIDE_SET ? set.extra.data() : nullptr),
                0);
    }
    sets.push_back(std::move(set));
  }
  return sets;
}

ExoFile read_exo(const std::string& path) {
  ex_opts(0);
  int cpu = 8, io = 0;
  float version = 0;
  const int exoid = ex_open(path.c_str(), EX_READ, &cpu, &io, &version);
  ExoFile f;
  EXPECT_GE(exoid, 0) << path;
  if (exoid < 0) return f;
  EXPECT_GE(ex_set_int64_status(exoid, EX_ALL_INT64_API), 0);
  EXPECT_GE(ex_set_max_name_length(exoid, 256), 0);
  EXPECT_EQ(nc_inq_format(exoid, &f.format), 0);
  EXPECT_EQ(ex_get_init_ext(exoid, &f.init), 0);
  const auto nn = static_cast<std::size_t>(f.init.num_nodes), ne = static_cast<std::size_t>(f.init.num_elem);
  f.x.resize(nn), f.y.resize(nn), f.z.resize(nn);
  if (nn > 0) {
    EXPECT_EQ(ex_get_coord(exoid, f.x.data(), f.y.data(), f.z.data()), 0);
  }
  {
    char names[3][257] = {};
    char* ptr[3] = {names[0], names[1], names[2]};
    EXPECT_EQ(ex_get_coord_names(exoid, ptr), 0);
    for (auto* p : ptr) f.coord_names.emplace_back(p);
  }
  f.node_map.resize(nn), f.elem_map.resize(ne);
  if (nn > 0) {
    EXPECT_EQ(ex_get_id_map(exoid, EX_NODE_MAP, f.node_map.data()), 0);
  }
  if (ne > 0) {
    EXPECT_EQ(ex_get_id_map(exoid, EX_ELEM_MAP, f.elem_map.data()), 0);
  }
  std::vector<std::int64_t> ids(static_cast<std::size_t>(f.init.num_elem_blk));
  if (!ids.empty()) {
    EXPECT_EQ(ex_get_ids(exoid, EX_ELEM_BLOCK, ids.data()), 0);
  }
  const auto names = get_names(exoid, EX_ELEM_BLOCK, f.init.num_elem_blk);
  for (std::size_t b = 0; b < ids.size(); ++b) {
    ExoBlock blk;
    blk.id = ids[b];
    blk.name = names[b];
    char type[MAX_STR_LENGTH + 1] = {};
    std::int64_t edges = 0, faces = 0, attrs = 0;
    EXPECT_EQ(ex_get_block(exoid, EX_ELEM_BLOCK, blk.id, type, &blk.count, &blk.nodes_per_element, &edges, &faces,
                           &attrs),
              0);
    blk.type = type;
    blk.conn.resize(static_cast<std::size_t>(blk.count * blk.nodes_per_element));
    if (blk.count > 0) {
      EXPECT_EQ(ex_get_conn(exoid, EX_ELEM_BLOCK, blk.id, blk.conn.data(), nullptr, nullptr), 0);
    }
    f.blocks.push_back(std::move(blk));
  }
  f.side_sets = get_sets(exoid, EX_SIDE_SET, f.init.num_side_sets);
  f.node_sets = get_sets(exoid, EX_NODE_SET, f.init.num_node_sets);
  ex_close(exoid);
  return f;
}

// Chunk element index -> 0-based position in the file (blocks in MeshInfo
// order, elements in chunk order within a block), the writer's contract.
std::vector<Id> expected_file_positions(const ExportChunk& c) {
  const std::size_t nblocks = c.mesh().info().blocks.size();
  std::vector<Id> pos(static_cast<std::size_t>(c.num_elements()));
  Id next = 0;
  for (std::size_t b = 0; b < nblocks; ++b)
    for (Id e = 0; e < c.num_elements(); ++e)
      if (static_cast<std::size_t>(c.element_block()[static_cast<std::size_t>(e)]) == b)
        pos[static_cast<std::size_t>(e)] = next++;
  return pos;
}

// Everything in the file against the chunk and (through the maps) the FineMesh.
void check_against_mesh(const ExoFile& f, const ExportChunk& c) {
  const FineMesh& m = c.mesh();
  const bool volume = c.mode() == Mode::Volume;
  ASSERT_EQ(f.format, NC_FORMAT_NETCDF4);
  EXPECT_EQ(f.init.num_dim, 3);
  ASSERT_EQ(f.init.num_nodes, c.num_nodes());
  ASSERT_EQ(f.init.num_elem, c.num_elements());
  EXPECT_EQ(f.coord_names, (std::vector<std::string>{"x", "y", "z"}));

  // Nodes: every coordinate bit-equal to FineMesh::node(map - 1).
  for (std::size_t v = 0; v < f.node_map.size(); ++v) {
    ASSERT_EQ(f.node_map[v], c.node_global()[v] + 1) << v;
    const Vec3 p = m.node(f.node_map[v] - 1);
    ASSERT_EQ(std::bit_cast<std::uint64_t>(f.x[v]), std::bit_cast<std::uint64_t>(p.x)) << v;
    ASSERT_EQ(std::bit_cast<std::uint64_t>(f.y[v]), std::bit_cast<std::uint64_t>(p.y)) << v;
    ASSERT_EQ(std::bit_cast<std::uint64_t>(f.z[v]), std::bit_cast<std::uint64_t>(p.z)) << v;
  }

  // Blocks: those with elements in the chunk, in MeshInfo order.
  const auto& info = m.info();
  std::vector<std::size_t> present;
  for (std::size_t b = 0; b < info.blocks.size(); ++b)
    if (std::count(c.element_block().begin(), c.element_block().end(), static_cast<std::int32_t>(b)) > 0)
      present.push_back(b);
  ASSERT_EQ(f.blocks.size(), present.size());
  std::size_t fe = 0;  // file element position
  std::set<std::int64_t> seen;
  for (std::size_t i = 0; i < present.size(); ++i) {
    const ExoBlock& blk = f.blocks[i];
    SCOPED_TRACE("block " + std::to_string(blk.id));
    EXPECT_EQ(blk.id, info.blocks[present[i]].id);
    EXPECT_EQ(blk.name, info.blocks[present[i]].name.substr(0, 255));  // names over 255 are cut
    EXPECT_EQ(blk.type, volume ? "HEX8" : "SHELL4");
    ASSERT_EQ(blk.nodes_per_element, c.corners());
    for (std::int64_t e = 0; e < blk.count; ++e, ++fe) {
      ASSERT_LT(fe, f.elem_map.size());
      const FineElement el = m.element(f.elem_map[fe] - 1);
      ASSERT_TRUE(seen.insert(el.id).second) << "element " << el.id << " written twice";
      ASSERT_EQ(el.block, static_cast<std::int32_t>(present[i])) << el.id;
      for (int k = 0; k < c.corners(); ++k) {
        const std::int64_t local = blk.conn[static_cast<std::size_t>(e * c.corners() + k)];
        ASSERT_GE(local, 1);
        ASSERT_LE(local, f.init.num_nodes);
        ASSERT_EQ(f.node_map[static_cast<std::size_t>(local - 1)] - 1, el.nodes[static_cast<std::size_t>(k)])
            << "element " << el.id << " corner " << k;
      }
    }
  }
  EXPECT_EQ(fe, static_cast<std::size_t>(c.num_elements()));
  // Every element of the chunk, exactly once.
  for (Id g : c.element_global()) EXPECT_TRUE(seen.count(g)) << g;

  // Side sets: the chunk's, elements as file positions, sides 1-based.
  const auto pos = expected_file_positions(c);
  ASSERT_EQ(f.side_sets.size(), c.side_sets().size());
  for (std::size_t s = 0; s < f.side_sets.size(); ++s) {
    const ExoSet& got = f.side_sets[s];
    const auto& want = c.side_sets()[s];
    SCOPED_TRACE("side set " + std::to_string(want.id));
    EXPECT_EQ(got.id, want.id);
    EXPECT_EQ(got.name, want.name.substr(0, 255));
    ASSERT_EQ(got.entries.size(), want.element.size());
    for (std::size_t i = 0; i < got.entries.size(); ++i) {
      ASSERT_EQ(got.entries[i], pos[static_cast<std::size_t>(want.element[i])] + 1) << i;
      ASSERT_EQ(got.extra[i], want.side[i] + 1) << i;
      // The file's own maps name the same fine element.
      ASSERT_EQ(f.elem_map[static_cast<std::size_t>(got.entries[i] - 1)] - 1,
                c.element_global()[static_cast<std::size_t>(want.element[i])]);
    }
  }
  ASSERT_EQ(f.node_sets.size(), c.node_sets().size());
  for (std::size_t s = 0; s < f.node_sets.size(); ++s) {
    const ExoSet& got = f.node_sets[s];
    const auto& want = c.node_sets()[s];
    SCOPED_TRACE("node set " + std::to_string(want.id));
    EXPECT_EQ(got.id, want.id);
    EXPECT_EQ(got.name, want.name.substr(0, 255));
    ASSERT_EQ(got.entries.size(), want.node.size());
    for (std::size_t i = 0; i < got.entries.size(); ++i) ASSERT_EQ(got.entries[i], want.node[i] + 1) << i;
  }
}

// ------------------------------------------------------------ meshio (exodus_check.py)

using Proc = test::CliResult;
// Without a shell; the foreign python's variables must not leak into Debian's.
Proc run(const std::vector<std::string>& argv) { return test::run_process(argv, {}, test::kForeignPythonEnv); }

// exodus_check.py prints one `"key": value` per line; the value's text.
std::string field(const std::string& json, const std::string& key) {
  const std::string prefix = "\"" + key + "\": ";
  std::istringstream in(json);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::string v = line.substr(prefix.size());
    if (!v.empty() && v.back() == ',') v.pop_back();
    return v;
  }
  return "<missing " + key + ">";
}

std::vector<double> numbers(const std::string& list) {  // "[a, b, c]"
  std::vector<double> out;
  std::string body = list.size() >= 2 ? list.substr(1, list.size() - 2) : "";
  std::istringstream in(body);
  for (std::string tok; std::getline(in, tok, ',');) out.push_back(std::strtod(tok.c_str(), nullptr));
  return out;
}

std::uint64_t digest(const std::vector<std::uint64_t>& bits) {
  std::uint64_t d = 0;
  for (std::size_t i = 0; i < bits.size(); ++i) d += (i + 1) * bits[i];
  return d;
}
template <class T>
std::uint64_t digest_of(const std::vector<T>& v) {
  std::vector<std::uint64_t> bits;
  for (const T& x : v) bits.push_back(std::bit_cast<std::uint64_t>(x));
  return digest(bits);
}

std::string quoted(const std::string& s) { return "\"" + s + "\""; }

// Runs exodus_check.py on `path` and compares with the file as the Exodus
// library read it (itself checked against the mesh by check_against_mesh).
void check_with_meshio(const std::string& path, const ExoFile& f, const ExportChunk& c) {
  if (!std::filesystem::exists(kPython)) {
    DICER_SKIP_OR_FAIL_IN_CI("no " << kPython);
  }
  const Proc p = run({kPython, std::string(DICER_SOURCE_DIR) + "/tests/roundtrip/exodus_check.py", path});
  if (p.exit_code == 77) {
    DICER_SKIP_OR_FAIL_IN_CI(p.err);
  }
  ASSERT_EQ(p.exit_code, 0) << p.err << p.out;
  const std::string& j = p.out;
  const bool volume = c.mode() == Mode::Volume;

  EXPECT_EQ(field(j, "format"), quoted("NETCDF4"));
  // Global ids (+ 1) are stored 64-bit: they outgrow 32 bits before a chunk does.
  EXPECT_EQ(field(j, "id_types"), "[\"int64\", \"int64\", \"int64\"]");
  EXPECT_EQ(field(j, "num_points"), std::to_string(c.num_nodes()));
  std::string cells = "[", ids = "[", names = "[", types = "[";
  for (std::size_t b = 0; b < f.blocks.size(); ++b) {
    const std::string sep = b ? ", " : "";
    cells += sep + "[" + quoted(volume ? "hexahedron" : "quad") + ", " + std::to_string(f.blocks[b].count) + "]";
    ids += sep + std::to_string(f.blocks[b].id);
    names += sep + quoted(f.blocks[b].name);
    types += sep + quoted(volume ? "HEX8" : "SHELL4");
  }
  EXPECT_EQ(field(j, "cells"), cells + "]");
  EXPECT_EQ(field(j, "block_ids"), ids + "]");
  EXPECT_EQ(field(j, "block_names"), names + "]");
  EXPECT_EQ(field(j, "block_types"), types + "]");

  // Points: three bit-exact, all of them through the digest.
  const std::size_t n = static_cast<std::size_t>(c.num_nodes());
  ASSERT_GT(n, 0u);
  const std::pair<const char*, std::size_t> picks[] = {{"point_first", 0}, {"point_mid", n / 2}, {"point_last", n - 1}};
  for (const auto& [key, i] : picks) {
    const auto xyz = numbers(field(j, key));
    ASSERT_EQ(xyz.size(), 3u) << key << ": " << field(j, key);
    EXPECT_EQ(std::bit_cast<std::uint64_t>(xyz[0]), std::bit_cast<std::uint64_t>(c.x()[i])) << key;
    EXPECT_EQ(std::bit_cast<std::uint64_t>(xyz[1]), std::bit_cast<std::uint64_t>(c.y()[i])) << key;
    EXPECT_EQ(std::bit_cast<std::uint64_t>(xyz[2]), std::bit_cast<std::uint64_t>(c.z()[i])) << key;
  }
  std::vector<double> flat;
  for (std::size_t i = 0; i < n; ++i) flat.insert(flat.end(), {c.x()[i], c.y()[i], c.z()[i]});
  EXPECT_EQ(field(j, "point_digest"), std::to_string(digest_of(flat)));
  std::vector<std::int64_t> conn;
  for (const ExoBlock& b : f.blocks)
    for (std::int64_t v : b.conn) conn.push_back(v - 1);
  EXPECT_EQ(field(j, "conn_digest"), std::to_string(digest_of(conn)));
  EXPECT_EQ(field(j, "node_map_digest"), std::to_string(digest_of(f.node_map)));
  EXPECT_EQ(field(j, "elem_map_digest"), std::to_string(digest_of(f.elem_map)));

  std::string ss = "[";
  for (std::size_t s = 0; s < f.side_sets.size(); ++s) {
    const ExoSet& set = f.side_sets[s];
    ss += (s ? ", [" : "[") + std::to_string(set.id) + ", " + quoted(set.name) + ", " +
          std::to_string(set.entries.size()) + ", " + std::to_string(digest_of(set.entries)) + ", " +
          std::to_string(digest_of(set.extra)) + "]";
  }
  EXPECT_EQ(field(j, "side_sets"), ss + "]");
  std::string ns = "[";
  for (std::size_t s = 0; s < f.node_sets.size(); ++s) {
    const ExoSet& set = f.node_sets[s];
    ns += (s ? ", [" : "[") + std::to_string(set.id) + ", " + quoted(set.name) + ", " +
          std::to_string(set.entries.size()) + ", " + std::to_string(digest_of(set.entries)) + "]";
  }
  EXPECT_EQ(field(j, "node_sets"), ns + "]");
  // meshio's own point sets ({name: size}): checked when names are distinct
  // and no set is empty (meshio pairs names with node_ns* variables, which an
  // empty set does not have).
  std::set<std::string> distinct;
  bool simple = true;
  for (const auto& set : c.node_sets()) simple = simple && distinct.insert(set.name).second && !set.node.empty();
  if (simple && !c.node_sets().empty()) {
    std::string ps = "{";
    for (std::size_t s = 0; s < c.node_sets().size(); ++s)
      ps += (s ? ", " : "") + quoted(c.node_sets()[s].name.substr(0, 255)) + ": " +
            std::to_string(c.node_sets()[s].node.size());
    EXPECT_EQ(field(j, "point_sets"), ps + "}");
  }
}

std::vector<std::string> leftovers(const std::filesystem::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

// ------------------------------------------------------------------ tests

TEST(ExportExodus, MugChunksReadBackThroughExodusLibrary) {
  const Diced d = dice_file("vtkdata_mug.e");
  const auto ranges = plan_chunks(d.mesh, 2);
  ASSERT_EQ(ranges.size(), 2u);
  test::TempDir tmp;
  std::set<Id> nodes, elements;
  std::map<std::int64_t, std::size_t> side_total;
  for (const ChunkRange& r : ranges) {
    SCOPED_TRACE("chunk " + std::to_string(r.index));
    ExportChunk c(d.mesh, r);
    c.prepare(d.sets);
    const std::string path = tmp.path("mug_" + std::to_string(r.index) + ".e");
    write_exodus(c, path);
    const ExoFile f = read_exo(path);
    ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
    for (auto g : f.node_map) nodes.insert(g - 1);
    for (auto g : f.elem_map) EXPECT_TRUE(elements.insert(g - 1).second) << "element in two chunks: " << g - 1;
    for (const ExoSet& s : f.side_sets) side_total[s.id] += s.entries.size();
  }
  // Both chunks together: the whole fine mesh, each element once.
  EXPECT_EQ(static_cast<Id>(nodes.size()), d.mesh.num_nodes());
  EXPECT_EQ(static_cast<Id>(elements.size()), d.mesh.num_elements());
  // Mug: two blocks, side sets top and bottom; refining by 2 quarters each coarse side.
  ASSERT_EQ(d.mesh.info().blocks.size(), 2u);
  for (const SideSet& s : d.sets.side_sets) EXPECT_EQ(side_total[s.id], 4 * s.element.size()) << s.name;
  // Nothing but the two files in the folder (temporaries renamed away).
  EXPECT_EQ(leftovers(tmp.dir()), (std::vector<std::string>{"mug_0.e", "mug_1.e"}));
}

TEST(ExportExodus, ReadCoarseMeshReadsTheExport) {
  const Diced d = dice_file("vtkdata_mug.e");
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 2)[1]);
  c.prepare(d.sets);
  test::TempDir tmp;
  const std::string path = tmp.path("mug.exo");
  write_exodus(c, path);
  const CoarseMesh back = read_coarse_mesh(path);  // validates handedness, ranges, duplicates
  EXPECT_EQ(back.mode, Mode::Volume);
  EXPECT_EQ(back.num_elements(), c.num_elements());
  EXPECT_EQ(back.num_vertices(), c.num_nodes());
  std::set<std::int32_t> present(c.element_block().begin(), c.element_block().end());
  ASSERT_EQ(back.blocks.size(), present.size());
  std::size_t i = 0;
  for (std::int32_t b : present) {
    EXPECT_EQ(back.blocks[i].id, d.mesh.info().blocks[static_cast<std::size_t>(b)].id);
    EXPECT_EQ(back.blocks[i].name, d.mesh.info().blocks[static_cast<std::size_t>(b)].name);
    ++i;
  }
  // Ids in the file are global ids + 1.
  for (std::size_t v = 0; v < back.vertex_file_id.size(); ++v)
    ASSERT_EQ(back.vertex_file_id[v], c.node_global()[v] + 1);
  std::vector<Id> elem_ids(back.element_file_id.begin(), back.element_file_id.end());
  std::sort(elem_ids.begin(), elem_ids.end());
  std::vector<Id> want(c.element_global().begin(), c.element_global().end());
  for (Id& g : want) ++g;
  EXPECT_EQ(elem_ids, want);
  ASSERT_EQ(back.side_sets.size(), c.side_sets().size());
  for (std::size_t s = 0; s < back.side_sets.size(); ++s) {
    EXPECT_EQ(back.side_sets[s].name, c.side_sets()[s].name);
    EXPECT_EQ(back.side_sets[s].element.size(), c.side_sets()[s].element.size());
    // Same sides on the same fine elements.
    std::multiset<std::pair<Id, int>> got, exp;
    for (std::size_t k = 0; k < back.side_sets[s].element.size(); ++k)
      got.insert({back.element_file_id[static_cast<std::size_t>(back.side_sets[s].element[k])] - 1,
                  back.side_sets[s].side[k]});
    for (std::size_t k = 0; k < c.side_sets()[s].element.size(); ++k)
      exp.insert({c.element_global()[static_cast<std::size_t>(c.side_sets()[s].element[k])], c.side_sets()[s].side[k]});
    EXPECT_EQ(got, exp);
  }
  ASSERT_EQ(back.node_sets.size(), c.node_sets().size());
  for (std::size_t s = 0; s < back.node_sets.size(); ++s)
    EXPECT_EQ(back.node_sets[s].vertex, c.node_sets()[s].node);
  // And it dices again: the export is a valid coarse mesh.
  IntervalRequest req;
  req.global = 1;
  EXPECT_EQ(FineMesh::dice(back, req).num_elements(), c.num_elements());
}

TEST(ExportExodus, MeshioReadsMugChunks) {
  const Diced d = dice_file("vtkdata_mug.e");
  test::TempDir tmp;
  for (const ChunkRange& r : plan_chunks(d.mesh, 2)) {
    SCOPED_TRACE("chunk " + std::to_string(r.index));
    ExportChunk c(d.mesh, r);
    c.prepare(d.sets);
    const std::string path = tmp.path("mug_" + std::to_string(r.index) + ".e");
    write_exodus(c, path);
    const ExoFile f = read_exo(path);
    ASSERT_NO_FATAL_FAILURE(check_with_meshio(path, f, c));
    if (::testing::Test::IsSkipped()) return;
  }
}

TEST(ExportExodus, SurfaceShellRoundTrip) {
  const Diced d = dice_file("libmesh_cylinder_shell.exo");
  ASSERT_EQ(d.mesh.mode(), Mode::Surface);
  test::TempDir tmp;
  for (const ChunkRange& r : plan_chunks(d.mesh, 2)) {
    SCOPED_TRACE("chunk " + std::to_string(r.index));
    ExportChunk c(d.mesh, r);
    c.prepare(d.sets);
    const std::string path = tmp.path("shell_" + std::to_string(r.index) + ".exo");
    write_exodus(c, path);
    const ExoFile f = read_exo(path);
    ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
    const CoarseMesh back = read_coarse_mesh(path);
    EXPECT_EQ(back.mode, Mode::Surface);
    EXPECT_EQ(back.num_elements(), c.num_elements());
    ASSERT_NO_FATAL_FAILURE(check_with_meshio(path, f, c));
    if (::testing::Test::IsSkipped()) return;
  }
}

TEST(ExportExodus, LongNamesAreKept) {
  CoarseMesh coarse = read_coarse_mesh(test::data_path("vtkdata_mug.e"));
  ASSERT_FALSE(coarse.blocks.empty());
  ASSERT_FALSE(coarse.side_sets.empty());
  ASSERT_FALSE(coarse.node_sets.empty());
  const std::string block_name = "a_block_name_well_beyond_the_classic_32_character_limit";
  const std::string side_name = "the_side_set_that_also_has_a_very_long_descriptive_name";
  coarse.blocks[0].name = block_name;
  coarse.side_sets[0].name = side_name;
  const std::string node_name(300, 'n');  // beyond netCDF's 256: cut to 255
  coarse.node_sets[0].name = node_name;
  const Diced d = dice(std::move(coarse), 1);
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0]);
  c.prepare(d.sets);
  test::TempDir tmp;
  const std::string path = tmp.path("names.e");
  // The library prints name warnings straight to stderr; the writer must not
  // give it cause to: capture fd 2 around the write.
  const std::string err_path = tmp.path("stderr.txt");
  std::fflush(stderr);
  const int saved = ::dup(2);
  const int err_fd = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  ASSERT_GE(saved, 0);
  ASSERT_GE(err_fd, 0);
  ::dup2(err_fd, 2);
  ::close(err_fd);
  try {
    write_exodus(c, path);
  } catch (...) {
    ::dup2(saved, 2);
    ::close(saved);
    throw;
  }
  std::fflush(stderr);
  ::dup2(saved, 2);
  ::close(saved);
  EXPECT_EQ(test::read_file(err_path), "");
  const ExoFile f = read_exo(path);
  EXPECT_EQ(f.node_sets.at(0).name, node_name.substr(0, 255));
  ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
  ASSERT_NO_FATAL_FAILURE(check_with_meshio(path, f, c));
  ASSERT_FALSE(f.blocks.empty());
  EXPECT_EQ(f.blocks[0].name, block_name);
  EXPECT_EQ(f.side_sets[0].name, side_name);
  EXPECT_EQ(read_coarse_mesh(path).blocks[0].name, block_name);
}

TEST(ExportExodus, ReplacesAnExistingFile) {
  const Diced d = dice_file("vtkdata_mug.e", 1);
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0]);
  c.prepare(d.sets);
  test::TempDir tmp;
  const std::string path = tmp.path("out.e");
  test::write_file(path, "old contents");
  write_exodus(c, path);
  EXPECT_EQ(read_exo(path).init.num_elem, c.num_elements());
  EXPECT_EQ(leftovers(tmp.dir()), (std::vector<std::string>{"out.e"}));
}

TEST(ExportExodus, FailureIsAnIoErrorAndLeavesNothing) {
  const Diced d = dice_file("vtkdata_mug.e", 1);
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0]);
  c.prepare(d.sets);
  test::TempDir tmp;
  const std::string missing = tmp.path("no/such/dir/out.e");
  try {
    write_exodus(c, missing);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io);
    EXPECT_NE(std::string(e.what()).find(missing + ": cannot open the output folder"), std::string::npos) << e.what();
  }
  // The destination is a directory: refused before anything is written
  // (a usage error: the user named a folder, not a file).
  const std::string dir = tmp.path("taken");
  std::filesystem::create_directories(dir + "/inside");
  try {
    write_exodus(c, dir);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    EXPECT_NE(std::string(e.what()).find(dir + ": is a directory"), std::string::npos) << e.what();
  }
  EXPECT_EQ(leftovers(tmp.dir()), (std::vector<std::string>{"taken"}));
}

TEST(ExportExodus, BoxSelectionWithEmptySets) {
  const Diced d = dice_file("vtkdata_mug.e");
  // The lower part of the mug: some sets have no member here; they are still
  // written (empty), so every chunk file names the same sets.
  double zmin = 1e300, zmax = -1e300;
  const CoarseMesh& coarse = *d.mesh.coarse();
  for (double z : coarse.z) zmin = std::min(zmin, z), zmax = std::max(zmax, z);
  const Box box{{-1e9, -1e9, -1e9}, {1e9, 1e9, zmin + 0.25 * (zmax - zmin)}};
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0], box);
  c.prepare(d.sets);
  ASSERT_GT(c.num_elements(), 0);
  ASSERT_LT(c.num_elements(), d.mesh.num_elements());
  bool some_empty = false;
  for (const auto& s : c.side_sets()) some_empty = some_empty || s.element.empty();
  for (const auto& s : c.node_sets()) some_empty = some_empty || s.node.empty();
  EXPECT_TRUE(some_empty) << "the box was meant to leave a set empty";
  test::TempDir tmp;
  const std::string path = tmp.path("box.e");
  write_exodus(c, path);
  const ExoFile f = read_exo(path);
  ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
  const CoarseMesh back = read_coarse_mesh(path);
  EXPECT_EQ(back.num_elements(), c.num_elements());
  EXPECT_EQ(back.side_sets.size(), c.side_sets().size());
  ASSERT_NO_FATAL_FAILURE(check_with_meshio(path, f, c));
}

TEST(ExportExodus, EmptySelectionWritesAnEmptyFile) {
  const Diced d = dice_file("vtkdata_mug.e", 1);
  const Box far{{1e6, 1e6, 1e6}, {2e6, 2e6, 2e6}};
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0], far);
  c.prepare(d.sets);
  ASSERT_EQ(c.num_elements(), 0);
  test::TempDir tmp;
  const std::string path = tmp.path("empty.e");
  write_exodus(c, path);
  const ExoFile f = read_exo(path);
  ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
  EXPECT_EQ(f.init.num_elem_blk, 0);
}

TEST(ExportExodus, ManyElementsSpanSeveralIdMapSlices) {
  // The writer sends id maps in slices of 65536 entries: more than two
  // slices of nodes and elements here, checked entry by entry. Set entries
  // beyond 65535 too (Exodus 6.02 stores set entries as 16-bit when asked for
  // 64-bit bulk data; the writer must not ask).
  const Diced d = dice_file("vtkdata_mug.e", 4);
  ExportChunk c(d.mesh, plan_chunks(d.mesh, 1)[0]);
  c.prepare(d.sets);
  ASSERT_GT(c.num_elements(), 2 * 65536);
  ASSERT_GT(c.num_nodes(), 2 * 65536);
  test::TempDir tmp;
  const std::string path = tmp.path("big.e");
  write_exodus(c, path);
  const ExoFile f = read_exo(path);
  ASSERT_NO_FATAL_FAILURE(check_against_mesh(f, c));
  std::int64_t largest = 0;
  for (const ExoSet& s : f.side_sets)
    for (std::int64_t e : s.entries) largest = std::max(largest, e);
  EXPECT_GT(largest, 65535);
}
