// VtkHdfWriter against the real reader: VTK 9.1's vtkHDFReader (python3-vtk9,
// tests/roundtrip/vtkhdf_check.py) reads every partition as a piece, and the
// HDF5 layout is checked here with the HDF5 C library.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"
#include "test_support.hpp"


using namespace dicer;

namespace {

constexpr const char* kPython = "/usr/bin/python3";

// ------------------------------------------------------------ a tiny JSON reader
// Numbers keep their text so doubles are parsed once, by strtod, bit-exactly.
struct Json {
  enum Kind { Null, Number, String, Array, Object, Bool } kind = Null;
  std::string text;  // number text or string value
  bool flag = false;
  std::vector<Json> items;
  std::map<std::string, Json> fields;

  const Json& operator[](const std::string& k) const {
    auto it = fields.find(k);
    if (it == fields.end()) throw std::runtime_error("JSON: no field " + k);
    return it->second;
  }
  const Json& operator[](size_t i) const { return items.at(i); }
  std::int64_t integer() const { return std::stoll(text); }
  double number() const { return std::strtod(text.c_str(), nullptr); }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& s) : s_(s) {}
  Json parse() {
    Json v = value();
    skip();
    if (p_ != s_.size()) throw std::runtime_error("JSON: trailing text");
    return v;
  }

 private:
  void skip() {
    while (p_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[p_]))) ++p_;
  }
  char peek() {
    skip();
    if (p_ >= s_.size()) throw std::runtime_error("JSON: unexpected end");
    return s_[p_];
  }
  void expect(char c) {
    if (peek() != c) throw std::runtime_error(std::string("JSON: expected ") + c + " at " + std::to_string(p_));
    ++p_;
  }
  std::string string() {
    expect('"');
    std::string out;
    while (p_ < s_.size() && s_[p_] != '"') {
      if (s_[p_] == '\\') ++p_;  // escapes: enough for paths and names
      out += s_[p_++];
    }
    ++p_;
    return out;
  }
  Json value() {
    Json v;
    const char c = peek();
    if (c == '{') {
      v.kind = Json::Object;
      ++p_;
      if (peek() == '}') return ++p_, v;
      for (;;) {
        std::string k = string();
        expect(':');
        v.fields[k] = value();
        if (peek() == ',') { ++p_; continue; }
        expect('}');
        return v;
      }
    }
    if (c == '[') {
      v.kind = Json::Array;
      ++p_;
      if (peek() == ']') return ++p_, v;
      for (;;) {
        v.items.push_back(value());
        if (peek() == ',') { ++p_; continue; }
        expect(']');
        return v;
      }
    }
    if (c == '"') {
      v.kind = Json::String;
      v.text = string();
      return v;
    }
    const size_t start = p_;
    while (p_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[p_])) || std::string("+-.").find(s_[p_]) != std::string::npos))
      ++p_;
    v.text = s_.substr(start, p_ - start);
    if (v.text == "true" || v.text == "false") v.kind = Json::Bool, v.flag = v.text == "true";
    else if (v.text == "null") v.kind = Json::Null;
    else if (!v.text.empty()) v.kind = Json::Number;
    else throw std::runtime_error("JSON: bad value at " + std::to_string(start));
    return v;
  }
  const std::string& s_;
  size_t p_ = 0;
};

// ------------------------------------------------------------ helpers
using Proc = test::CliResult;
// Without a shell; the foreign python's variables must not leak into Debian's.
Proc run(const std::vector<std::string>& argv) { return test::run_process(argv, {}, test::kForeignPythonEnv); }

std::string check_script() { return std::string(DICER_SOURCE_DIR) + "/tests/roundtrip/vtkhdf_check.py"; }

// A diced mesh and its prepared chunks.
struct Exported {
  FineMesh mesh;
  std::vector<std::unique_ptr<ExportChunk>> chunks;
};

std::unique_ptr<Exported> dice_and_chunk(const std::string& file, Id global, Id parts) {
  auto e = std::make_unique<Exported>();
  IntervalRequest req;
  req.global = global;
  e->mesh = FineMesh::dice(read_coarse_mesh(test::data_path(file)), req);
  const MeshSets sets{e->mesh.coarse()->side_sets, e->mesh.coarse()->node_sets};
  for (const ChunkRange& r : plan_chunks(e->mesh, parts)) {
    e->chunks.push_back(std::make_unique<ExportChunk>(e->mesh, r));
    e->chunks.back()->prepare(sets);
  }
  return e;
}

void write_all(const Exported& e, const std::string& path) {
  VtkHdfWriter w(path, static_cast<Id>(e.chunks.size()));
  for (const auto& c : e.chunks) w.write_partition(*c);
  w.finish();
}

// Runs the VTK reader. `missing` is set when the reader is not installed
// (the test skips, or fails under CI); `error` when it rejected the file.
struct VtkResult {
  std::string missing, error;
  Json json;
};

VtkResult read_with_vtk(const std::string& path) {
  VtkResult r;
  if (::access(kPython, X_OK) != 0) {
    r.missing = std::string(kPython) + " not found (Debian's python3 with python3-vtk9 and python3-h5py)";
    return r;
  }
  const Proc p = run({kPython, check_script(), path});
  if (p.exit_code == 77) {
    r.missing = std::string("VTK or h5py not importable by ") + kPython + ": " + p.err;
  } else if (p.exit_code != 0) {
    r.error = "vtkHDFReader rejected " + path + " (exit " + std::to_string(p.exit_code) + "):\n" + p.err + p.out;
  } else {
    try {
      r.json = JsonParser(p.out).parse();
    } catch (const std::exception& ex) {
      r.error = std::string(ex.what()) + "\n" + p.out;
    }
  }
  return r;
}

#define READ_WITH_VTK(result, path)                               \
  const VtkResult result = read_with_vtk(path);                   \
  if (!result.missing.empty()) {                                  \
    DICER_SKIP_OR_FAIL_IN_CI(result.missing);                     \
  }                                                               \
  ASSERT_TRUE(result.error.empty()) << result.error

// Compares what VTK read with the chunks and the mesh.
void compare(const Exported& e, const Json& r, std::uint8_t cell_type) {
  const FineMesh& m = e.mesh;
  EXPECT_EQ(r["partitions"].integer(), static_cast<Id>(e.chunks.size()));
  EXPECT_EQ(r["h5"]["type"].text, "UnstructuredGrid");
  ASSERT_EQ(r["h5"]["version"].items.size(), 2u);
  EXPECT_EQ(r["h5"]["version"][0].integer(), 1);
  EXPECT_EQ(r["h5"]["version"][1].integer(), 0);
  ASSERT_EQ(r["pieces"].items.size(), e.chunks.size());
  Id cells = 0, points = 0, samples = 0;
  for (size_t k = 0; k < e.chunks.size(); ++k) {
    const ExportChunk& c = *e.chunks[k];
    const Json& p = r["pieces"][k];
    SCOPED_TRACE("piece " + std::to_string(k));
    EXPECT_EQ(p["piece"].integer(), static_cast<Id>(k));
    EXPECT_EQ(p["points"].integer(), c.num_nodes());
    EXPECT_EQ(p["cells"].integer(), c.num_elements());
    EXPECT_EQ(p["points_type"].text, "double");
    ASSERT_EQ(p["cell_types"].items.size(), 1u);
    EXPECT_EQ(p["cell_types"][0].integer(), cell_type);
    EXPECT_TRUE(p["offsets_ok"].flag);
    std::set<std::int64_t> want_blocks, got_blocks;
    for (std::int32_t b : c.element_block()) want_blocks.insert(m.info().blocks[static_cast<size_t>(b)].id);
    for (const Json& b : p["block_ids"].items) got_blocks.insert(b.integer());
    EXPECT_EQ(got_blocks, want_blocks);
    ASSERT_EQ(p["element_ids"].items.size(), 2u);
    EXPECT_EQ(p["element_ids"][0].integer(), c.element_global().front());
    EXPECT_EQ(p["element_ids"][1].integer(), c.element_global().back());
    for (const Json& s : p["samples"].items) {
      const Id gid = s[0].integer();
      ASSERT_GE(gid, 0);
      ASSERT_LT(gid, m.num_nodes());
      const Vec3 want = m.node(gid);
      EXPECT_EQ(std::bit_cast<std::uint64_t>(s[1].number()), std::bit_cast<std::uint64_t>(want.x)) << "node " << gid;
      EXPECT_EQ(std::bit_cast<std::uint64_t>(s[2].number()), std::bit_cast<std::uint64_t>(want.y)) << "node " << gid;
      EXPECT_EQ(std::bit_cast<std::uint64_t>(s[3].number()), std::bit_cast<std::uint64_t>(want.z)) << "node " << gid;
      ++samples;
    }
    cells += c.num_elements(), points += c.num_nodes();
  }
  EXPECT_GT(samples, 0);
  EXPECT_EQ(cells, m.num_elements());
  EXPECT_EQ(r["whole"]["cells"].integer(), m.num_elements());
  EXPECT_EQ(r["whole"]["points"].integer(), points);  // boundary nodes repeat per partition
  EXPECT_EQ(r["h5"]["shapes"]["Points"][0].integer(), points);
  EXPECT_EQ(r["h5"]["shapes"]["Points"][1].integer(), 3);
  EXPECT_EQ(r["h5"]["shapes"]["Offsets"][0].integer(), cells + static_cast<Id>(e.chunks.size()));
  EXPECT_EQ(r["h5"]["shapes"]["CellData/BlockId"][0].integer(), cells);
}

// ------------------------------------------------------------ HDF5-level readback
struct H5 {
  hid_t id;
  herr_t (*close)(hid_t);
  ~H5() {
    if (id >= 0) close(id);
  }
};

std::vector<std::int64_t> read_i64(hid_t file, const char* name) {
  H5 ds{H5Dopen2(file, name, H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) throw std::runtime_error(std::string("no dataset ") + name);
  H5 space{H5Dget_space(ds.id), H5Sclose};
  const hssize_t n = H5Sget_simple_extent_npoints(space.id);
  std::vector<std::int64_t> v(static_cast<size_t>(n));
  if (n > 0 && H5Dread(ds.id, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
    throw std::runtime_error(std::string("cannot read ") + name);
  return v;
}

// Every dataset of `file` against the chunks it was written from.
void check_layout(hid_t file, const Exported& ex) {
  const Exported* e = &ex;
  const hid_t fid = file;
  const auto np = read_i64(fid, "VTKHDF/NumberOfPoints"), nc = read_i64(fid, "VTKHDF/NumberOfCells"),
             nconn = read_i64(fid, "VTKHDF/NumberOfConnectivityIds"), conn = read_i64(fid, "VTKHDF/Connectivity"),
             off = read_i64(fid, "VTKHDF/Offsets"), gid = read_i64(fid, "VTKHDF/PointData/GlobalNodeId"),
             eid = read_i64(fid, "VTKHDF/CellData/GlobalElementId"), bid = read_i64(fid, "VTKHDF/CellData/BlockId");
  std::vector<double> xyz(gid.size() * 3);
  {
    H5 ds{H5Dopen2(fid, "VTKHDF/Points", H5P_DEFAULT), H5Dclose};
    ASSERT_GE(H5Dread(ds.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, xyz.data()), 0);
  }
  std::set<std::int64_t> blocks_seen(bid.begin(), bid.end());
  EXPECT_EQ(blocks_seen.size(), e->mesh.info().blocks.size());
  ASSERT_EQ(np.size(), e->chunks.size());
  size_t p0 = 0, c0 = 0, k0 = 0, o0 = 0;
  for (size_t k = 0; k < e->chunks.size(); ++k) {
    const ExportChunk& c = *e->chunks[k];
    SCOPED_TRACE("partition " + std::to_string(k));
    ASSERT_EQ(np[k], c.num_nodes());
    ASSERT_EQ(nc[k], c.num_elements());
    ASSERT_EQ(nconn[k], c.num_elements() * 8);
    for (Id i = 0; i < c.num_nodes(); ++i) {
      ASSERT_EQ(gid.at(p0 + i), c.node_global()[i]);
      ASSERT_EQ(std::bit_cast<std::uint64_t>(xyz[3 * (p0 + i)]), std::bit_cast<std::uint64_t>(c.x()[i]));
      ASSERT_EQ(std::bit_cast<std::uint64_t>(xyz[3 * (p0 + i) + 1]), std::bit_cast<std::uint64_t>(c.y()[i]));
      ASSERT_EQ(std::bit_cast<std::uint64_t>(xyz[3 * (p0 + i) + 2]), std::bit_cast<std::uint64_t>(c.z()[i]));
    }
    for (Id i = 0; i < c.num_elements(); ++i) {
      ASSERT_EQ(eid.at(c0 + i), c.element_global()[i]);
      ASSERT_EQ(bid.at(c0 + i), e->mesh.info().blocks[static_cast<size_t>(c.element_block()[i])].id);
    }
    for (size_t i = 0; i < c.connectivity().size(); ++i) ASSERT_EQ(conn.at(k0 + i), c.connectivity()[i]);
    for (Id i = 0; i <= c.num_elements(); ++i) ASSERT_EQ(off.at(o0 + i), 8 * i);
    p0 += c.num_nodes(), c0 += c.num_elements(), k0 += c.connectivity().size(), o0 += c.num_elements() + 1;
  }
  EXPECT_EQ(gid.size(), p0);
  EXPECT_EQ(eid.size(), c0);
  EXPECT_EQ(conn.size(), k0);
  EXPECT_EQ(off.size(), o0);
}

}  // namespace

TEST(ExportVtkHdf, SpherePartitionsReadByVtkHdfReader) {
  const auto e = dice_and_chunk("cardinal_sphere.e", 3, 3);
  test::TempDir dir;
  const std::string path = dir.path("sphere.vtkhdf");
  write_all(*e, path);
  ASSERT_TRUE(std::filesystem::exists(path));
  // Only the final file is left: the temporary was renamed.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.dir()), std::filesystem::directory_iterator()), 1);
  READ_WITH_VTK(v, path);
  const Json& r = v.json;
  EXPECT_EQ(r["vtk_version"].text.substr(0, 2), "9.");
  compare(*e, r, 12);
}

TEST(ExportVtkHdf, LayoutMatchesChunksExactly) {
  const auto e = dice_and_chunk("cardinal_pincell.e", 2, 3);  // three blocks
  ASSERT_GE(e->mesh.info().blocks.size(), 2u);
  test::TempDir dir;
  const std::string path = dir.path("sphere.vtkhdf");
  write_all(*e, path);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  H5 f{H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  {  // Type: a fixed-length ASCII string, as vtkHDFReader reads it
    H5 g{H5Gopen2(f.id, "VTKHDF", H5P_DEFAULT), H5Gclose};
    H5 a{H5Aopen(g.id, "Type", H5P_DEFAULT), H5Aclose};
    H5 t{H5Aget_type(a.id), H5Tclose};
    ASSERT_EQ(H5Tget_class(t.id), H5T_STRING);
    EXPECT_LE(H5Tis_variable_str(t.id), 0);
    std::string s(H5Tget_size(t.id), '\0');
    ASSERT_GE(H5Aread(a.id, t.id, s.data()), 0);
    EXPECT_EQ(s, "UnstructuredGrid");
    H5 v{H5Aopen(g.id, "Version", H5P_DEFAULT), H5Aclose};
    int version[2] = {-1, -1};
    ASSERT_GE(H5Aread(v.id, H5T_NATIVE_INT, version), 0);
    EXPECT_EQ(version[0], 1);
    EXPECT_EQ(version[1], 0);
    // Only filters every HDF5 build has (ParaView needs no plugin).
    H5 ds{H5Dopen2(f.id, "VTKHDF/Connectivity", H5P_DEFAULT), H5Dclose};
    H5 dcpl{H5Dget_create_plist(ds.id), H5Pclose};
    for (int i = 0; i < H5Pget_nfilters(dcpl.id); ++i) {
      unsigned flags = 0;
      size_t nelem = 0;
      const H5Z_filter_t id = H5Pget_filter2(dcpl.id, static_cast<unsigned>(i), &flags, &nelem, nullptr, 0, nullptr, nullptr);
      EXPECT_TRUE(id == H5Z_FILTER_DEFLATE || id == H5Z_FILTER_SHUFFLE) << "filter " << id;
    }
  }
  check_layout(f.id, *e);
}

// What dicer export writes: streamed chunks (ChunkStream), by default
// without filters, with --deflate byte shuffle + deflate; the same values
// as the held chunks either way, and vtkHDFReader reads both.
TEST(ExportVtkHdf, StreamedAndDeflatedFilesHoldTheChunksValues) {
  const auto e = dice_and_chunk("cardinal_pincell.e", 2, 3);  // three blocks
  test::TempDir dir;
  const MeshSets sets{e->mesh.coarse()->side_sets, e->mesh.coarse()->node_sets};
  std::map<int, std::string> files;
  for (int level : {0, 1, 6}) {
    files[level] = dir.path("deflate" + std::to_string(level) + ".vtkhdf");
    VtkHdfWriter w(files[level], static_cast<Id>(e->chunks.size()), level);
    for (const auto& c : e->chunks) w.write_partition(ChunkStream(e->mesh, c->range(), sets));
    w.finish();
  }
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  for (const auto& [level, path] : files) {
    SCOPED_TRACE("deflate " + std::to_string(level));
    H5 f{H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    ASSERT_GE(f.id, 0);
    for (const char* name : {"VTKHDF/Points", "VTKHDF/Connectivity", "VTKHDF/Types", "VTKHDF/CellData/BlockId"}) {
      H5 ds{H5Dopen2(f.id, name, H5P_DEFAULT), H5Dclose};
      H5 dcpl{H5Dget_create_plist(ds.id), H5Pclose};
      std::vector<H5Z_filter_t> filters;
      unsigned deflate_level = 0;
      for (int i = 0; i < H5Pget_nfilters(dcpl.id); ++i) {
        unsigned flags = 0, values[4] = {0, 0, 0, 0};
        size_t nelem = 4;
        filters.push_back(H5Pget_filter2(dcpl.id, static_cast<unsigned>(i), &flags, &nelem, values, 0, nullptr, nullptr));
        if (filters.back() == H5Z_FILTER_DEFLATE) deflate_level = values[0];
      }
      if (level == 0) {
        EXPECT_TRUE(filters.empty()) << name;
      } else {
        EXPECT_EQ(filters, (std::vector<H5Z_filter_t>{H5Z_FILTER_SHUFFLE, H5Z_FILTER_DEFLATE})) << name;
        EXPECT_EQ(deflate_level, static_cast<unsigned>(level)) << name;
      }
    }
    check_layout(f.id, *e);
  }
  EXPECT_LT(std::filesystem::file_size(files[1]), std::filesystem::file_size(files[0]));
  READ_WITH_VTK(v, files[1]);
  compare(*e, v.json, 12);
}

// Reproducible output: the same chunks written again a second later are
// the same bytes (HDF5 would record each object's times by default, in
// whole seconds), and no object of the file carries a time.
TEST(ExportVtkHdf, SameChunksWrittenTwiceAreTheSameBytes) {
  const auto e = dice_and_chunk("cardinal_sphere.e", 2, 2);
  test::TempDir dir;
  for (int level : {0, 1}) {
    SCOPED_TRACE("deflate " + std::to_string(level));
    const std::string a = dir.path("a" + std::to_string(level) + ".vtkhdf"),
                      b = dir.path("b" + std::to_string(level) + ".vtkhdf");
    for (const std::string* path : {&a, &b}) {
      if (path == &b) ::usleep(1'100'000);
      VtkHdfWriter w(*path, static_cast<Id>(e->chunks.size()), level);
      for (const auto& c : e->chunks) w.write_partition(*c);
      w.finish();
    }
    EXPECT_EQ(test::read_file(a), test::read_file(b));
    H5 f{H5Fopen(a.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    ASSERT_GE(f.id, 0);
    std::vector<std::string> timed;
    const H5O_iterate_t each = [](hid_t, const char* name, const H5O_info_t* info, void* out) -> herr_t {
      if (info->atime || info->mtime || info->ctime || info->btime) static_cast<std::vector<std::string>*>(out)->push_back(name);
      return 0;
    };
    ASSERT_GE(H5Ovisit2(f.id, H5_INDEX_NAME, H5_ITER_NATIVE, each, &timed, H5O_INFO_TIME), 0);
    EXPECT_TRUE(timed.empty()) << "objects with times: " << timed.front();
  }
}

TEST(ExportVtkHdf, SurfaceMeshExportsQuads) {
  const auto e = dice_and_chunk("libmesh_cylinder_shell.exo", 3, 2);
  ASSERT_EQ(e->mesh.mode(), Mode::Surface);
  test::TempDir dir;
  const std::string path = dir.path("shell.vtkhdf");
  write_all(*e, path);
  READ_WITH_VTK(v, path);
  compare(*e, v.json, 9);
}

TEST(ExportVtkHdf, InterruptedExportLeavesNothing) {
  const auto e = dice_and_chunk("cardinal_sphere.e", 2, 3);
  test::TempDir dir;
  const std::string path = dir.path("partial.vtkhdf");
  {
    VtkHdfWriter w(path, 3);
    w.write_partition(*e->chunks[0]);
    // The temporary exists while writing, under a hidden name.
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.dir()), std::filesystem::directory_iterator()), 1);
    EXPECT_FALSE(std::filesystem::exists(path));
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::is_empty(dir.dir()));
}

TEST(ExportVtkHdf, PartitionCountIsEnforced) {
  const auto e = dice_and_chunk("cardinal_sphere.e", 2, 2);
  test::TempDir dir;
  const std::string path = dir.path("count.vtkhdf");
  {
    VtkHdfWriter w(path, 2);
    w.write_partition(*e->chunks[0]);
    try {
      w.finish();
      FAIL() << "finish with 1 of 2 partitions";
    } catch (const Error& ex) {
      EXPECT_EQ(ex.kind(), ErrorKind::Usage);
      EXPECT_NE(std::string(ex.what()).find(path), std::string::npos);
    }
    w.write_partition(*e->chunks[1]);
    try {
      w.write_partition(*e->chunks[0]);
      FAIL() << "third partition of 2";
    } catch (const Error& ex) {
      EXPECT_EQ(ex.kind(), ErrorKind::Usage);
    }
    w.finish();
  }
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.dir()), std::filesystem::directory_iterator()), 1);
}

TEST(ExportVtkHdf, BadArgumentsAndPaths) {
  test::TempDir dir;
  try {
    VtkHdfWriter w(dir.path("zero.vtkhdf"), 0);
    FAIL() << "zero partitions";
  } catch (const Error& ex) {
    EXPECT_EQ(ex.kind(), ErrorKind::Usage);
  }
  const std::string missing = dir.path("no/such/folder/x.vtkhdf");
  try {
    VtkHdfWriter w(missing, 1);
    FAIL() << "missing folder";
  } catch (const Error& ex) {
    EXPECT_EQ(ex.kind(), ErrorKind::Io);
    EXPECT_EQ(std::string(ex.what()).rfind(missing, 0), 0u) << ex.what();
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir.dir()));
}

// --box with --chunks N: N partitions, each the box's part of one chunk;
// together exactly the elements `query --box --count` counts.
TEST(ExportVtkHdf, BoxWithChunksIsOnePartitionPerChunk) {
  test::TempDir dir;
  const std::string store = dir.path("s.dice.h5"), out = dir.path("box.vtkhdf");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", store}).exit_code, 0);
  const std::string box = "-0.3,-1,-1,1,0.4,1";
  const auto count = test::run_cli({"query", store, "--box", box, "--count"});
  ASSERT_EQ(count.exit_code, 0) << count.err;
  const auto r = test::run_cli({"export", store, "--box", box, "--chunks", "3", "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("in 3 chunks"), std::string::npos) << r.out;
  H5 fid{H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(fid.id, 0);
  const auto cells = read_i64(fid.id, "VTKHDF/NumberOfCells");
  ASSERT_EQ(cells.size(), 3u);
  EXPECT_GT(cells[0] + cells[1] + cells[2], 0);
  EXPECT_EQ(std::to_string(cells[0] + cells[1] + cells[2]) + "\n", count.out);
}

// A box with a NaN corner or lo above hi selects nothing: refused wherever a
// box enters the library (for_each_in_box, ExportChunk), not answered empty.
TEST(ExportBox, NotFiniteOrInvertedBoxesAreRefused) {
  test::TempDir dir;
  const std::string store = dir.path("s.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "1", "-o", store}).exit_code, 0);
  const FineMesh m = read_store(store);
  const ChunkRange all{0, 1, 0, m.num_coarse_elements(), m.num_elements()};
  Box nan_box, inverted;
  nan_box.lo = {std::nan(""), 0, 0}, nan_box.hi = {1, 1, 1};
  inverted.lo = {0, 1, 0}, inverted.hi = {1, 0, 1};
  for (const Box& b : {nan_box, inverted}) {
    try {
      for_each_in_box(m, b, [](const FineBlock&, Id) {});
      ADD_FAILURE() << "for_each_in_box took the box";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Usage) << e.what();
    }
    try {
      ExportChunk c(m, all, b);
      ADD_FAILURE() << "ExportChunk took the box";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Usage) << e.what();
    }
  }
}
