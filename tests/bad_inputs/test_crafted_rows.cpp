// Every column a command reads, crafted out of range in a store whose
// checksums are all valid (store_forge recomputes Fletcher32 and CRC-32):
// the command must answer Corrupt (exit 8) naming the dataset and the row,
// never crash or print a wrong mesh. The column layout comes from
// store/FORMAT.md (the tables of format 8), not from the code's enums.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;

namespace {

struct Store {
  std::string path;
  std::int64_t V, E, F, H, nodes, elements, sheets;
  bool volume;
};

std::int64_t attr(hid_t f, const char* name) {
  std::int64_t v = 0;
  hid_t a = H5Aopen(f, name, H5P_DEFAULT);
  H5Aread(a, H5T_NATIVE_INT64, &v);
  H5Aclose(a);
  return v;
}

const Store& store(bool volume) {
  static test::TempDir dir;
  static Store s[2];
  Store& out = s[volume];
  if (out.path.empty()) {
    out.path = dir.path(volume ? "v.dice.h5" : "s.dice.h5");
    // Interval 3 in volume: row 1 has an interior cell (1, 1, 1), whose
    // element(id) reads the row's grid alone (RowReader::element_grid).
    const auto r = test::run_cli({"dice", test::data_path(volume ? "cardinal_sphere.e" : "libmesh_cylinder_shell.exo"),
                                  "--interval", volume ? "3" : "2", "-o", out.path});
    if (r.exit_code != 0) throw std::runtime_error(r.err);
    hid_t f = H5Fopen(out.path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    out.V = attr(f, "coarse_vertices"), out.E = attr(f, "coarse_edges"), out.F = attr(f, "coarse_faces");
    out.H = attr(f, "coarse_elements"), out.nodes = attr(f, "fine_nodes"), out.elements = attr(f, "fine_elements");
    out.sheets = attr(f, "sheets");
    out.volume = volume;
    H5Fclose(f);
  }
  return out;
}

struct Column {
  std::string dataset;
  int col;
  const char* what;
  std::int64_t (*bad)(const Store&);  // an out-of-range value for it
};

// FORMAT.md, "topology/elements row": c corners, e edges, f faces.
std::vector<Column> element_columns(bool volume) {
  const int c = volume ? 8 : 4, e = volume ? 12 : 4, f = volume ? 6 : 1;
  std::vector<Column> out;
  const std::string ds = "topology/elements";
  for (int k = 0; k < c; ++k) out.push_back({ds, k, "corner vertex", [](const Store& s) { return s.V + 3; }});
  for (int k = 0; k < c; ++k) out.push_back({ds, c + k, "corner node", [](const Store& s) { return s.nodes; }});
  for (int k = 0; k < e; ++k) out.push_back({ds, 2 * c + k, "edge", [](const Store& s) { return s.E; }});
  for (int k = 0; k < e; ++k) out.push_back({ds, 2 * c + e + k, "edge node", [](const Store& s) { return s.nodes; }});
  for (int k = 0; k < f; ++k) out.push_back({ds, 2 * c + 2 * e + k, "face", [](const Store& s) { return -s.F; }});
  for (int k = 0; k < f; ++k)
    out.push_back({ds, 2 * c + 2 * e + f + k, "face node", [](const Store& s) { return s.nodes; }});
  const int base = 2 * (c + e + f);
  out.push_back({ds, base + 0, "node_first", [](const Store& s) { return s.nodes + 1; }});
  out.push_back({ds, base + 1, "element_first", [](const Store& s) { return s.elements; }});
  out.push_back({ds, base + 2, "cell_node", [](const Store& s) { return s.nodes; }});
  // base + 3: the input file's element id, any value is one.
  out.push_back({ds, base + 4, "block", [](const Store&) { return std::int64_t{99}; }});
  out.push_back({ds, base + 5, "flags", [](const Store&) { return std::int64_t{1} << 40; }});
  for (int k = 0; k < 3; ++k) out.push_back({ds, base + 6 + k, "interval", [](const Store&) { return std::int64_t{0}; }});
  // Format 8: the axes' grading (3 bits each: kind, flip) and their ratios
  // (float64 bits): unknown bits, a NaN, zero, negative and huge ratio.
  out.push_back({ds, base + 9, "grading", [](const Store&) { return std::int64_t{1} << 20; }});
  out.push_back({ds, base + 10, "ratio", [](const Store&) { return std::int64_t{0x7FF8000000000000}; }});  // NaN
  out.push_back({ds, base + 11, "ratio", [](const Store&) { return std::int64_t{0}; }});                   // 0.0
  if (volume)
    out.push_back({ds, base + 12, "ratio", [](const Store&) { return static_cast<std::int64_t>(0xBFF8000000000000ull); }});  // -1.5
  return out;
}

std::vector<Column> all_columns(bool volume) {
  std::vector<Column> out = element_columns(volume);
  const std::string ed = "topology/edges", fa = "topology/faces", vn = "topology/vertex_nodes";
  out.push_back({ed, 0, "lo", [](const Store& s) { return s.V; }});
  out.push_back({ed, 1, "hi", [](const Store&) { return std::int64_t{-1}; }});
  out.push_back({ed, 2, "n", [](const Store&) { return std::int64_t{0}; }});
  out.push_back({ed, 3, "node", [](const Store& s) { return s.nodes; }});
  out.push_back({ed, 4, "sheet", [](const Store& s) { return s.sheets; }});
  out.push_back({ed, 5, "owner element", [](const Store& s) { return s.H; }});
  out.push_back({ed, 6, "geometric owner", [](const Store&) { return std::int64_t{9} << 32; }});
  out.push_back({ed, 7, "bounding row", [](const Store&) { return std::int64_t{5}; }});
  out.push_back({ed, 8, "other element", [](const Store& s) { return s.H; }});
  out.push_back({ed, 9, "grading", [](const Store&) { return std::int64_t{4}; }});  // equal spacing "flipped": no direction
  out.push_back({ed, 10, "ratio", [](const Store&) { return static_cast<std::int64_t>(0x7E37E43C8800759Cull); }});  // 1e300
  for (int k = 0; k < 4; ++k) out.push_back({fa, k, "corner", [](const Store& s) { return s.V; }});
  for (int k = 0; k < 4; ++k) out.push_back({fa, 4 + k, "side edge", [](const Store& s) { return s.E + 1; }});
  out.push_back({fa, 8, "nu", [](const Store&) { return std::int64_t{0}; }});
  out.push_back({fa, 9, "nv", [](const Store&) { return std::int64_t{-4}; }});
  out.push_back({fa, 10, "node", [](const Store& s) { return s.nodes; }});
  out.push_back({fa, 11, "owner element", [](const Store&) { return std::int64_t{-2}; }});
  out.push_back({fa, 12, "geometric owner", [](const Store&) { return std::int64_t{-7}; }});
  out.push_back({fa, 13, "bounding row", [](const Store&) { return std::int64_t{0}; }});
  out.push_back({fa, 14, "other element", [](const Store&) { return std::int64_t{0}; }});  // not above the owner
  // Bounds are float64: a NaN's bits, and a lower bound above the upper.
  const std::string bo = "topology/element_bounds";
  out.push_back({bo, 0, "x lower bound", [](const Store&) { return std::int64_t{0x7FF8000000000000}; }});
  out.push_back({bo, 5, "z upper bound", [](const Store&) { return static_cast<std::int64_t>(0xC1E0000000000000ull); }});  // -2^31
  out.push_back({vn, 0, "owner element", [](const Store& s) { return s.H + 10; }});
  out.push_back({vn, 1, "corner slot", [](const Store&) { return std::int64_t{8}; }});
  out.push_back({vn, 2, "node", [](const Store& s) { return s.nodes; }});
  return out;
}

hsize_t width_of(hid_t f, const std::string& ds) {
  hid_t d = H5Dopen2(f, ds.c_str(), H5P_DEFAULT);
  hid_t sp = H5Dget_space(d);
  hsize_t dims[2] = {0, 0};
  H5Sget_simple_extent_dims(sp, dims, nullptr);
  H5Sclose(sp), H5Dclose(d);
  return dims[1];
}

void run_all(bool volume) {
  const Store& s = store(volume);
  const int row = 1;
  for (const Column& c : all_columns(volume)) {
    SCOPED_TRACE(c.dataset + " column " + std::to_string(c.col) + " (" + c.what + ")");
    test::TempDir tmp;
    const std::string bad = tmp.path("bad.dice.h5");
    fs::copy_file(s.path, bad);
    hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hsize_t w = width_of(f, c.dataset);
    const std::int64_t v = c.bad(s);
    test::forge_page(f, c.dataset, 0, [&](std::vector<std::uint8_t>& page) {
      std::memcpy(page.data() + (row * w + static_cast<hsize_t>(c.col)) * 8, &v, 8);
    }, true);
    H5Fclose(f);
    // verify reads every row of every table a command reads.
    const test::CliResult r = test::run_cli({"verify", bad});
    EXPECT_EQ(r.exit_code, 8) << r.err;
    EXPECT_NE(r.err.find(c.dataset + " row " + std::to_string(row) + ":"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    if (c.dataset == "topology/elements" && volume) {
      // FineMesh::node(id) of an interior node and element(id) of an
      // interior cell read only some columns of their row (element_grid):
      // any other column crafted must leave their answer exactly the intact
      // store's, and a column they read must make them fail, Corrupt naming
      // the table. (The CLI's query goes through the cursors, which decode
      // whole rows; these are the library's random queries.)
      const FineMesh good = read_store(s.path);
      MeshCursor cur;
      const ElementRow h = RowReader(good.tables(), cur).element(row);
      ASSERT_EQ(h.n, (std::array<Id, 3>{3, 3, 3}));
      const Id node = h.cell_node, element = h.element_first + 1 + 3 * (1 + 3 * 1);  // cell (1, 1, 1)
      const bool read_by_grid = c.col >= 2 * (8 + 12 + 6);  // the scalar columns
      auto check = [&](const char* what, auto&& query) {
        SCOPED_TRACE(what);
        try {
          const FineMesh forged = read_store(bad);  // inside: opening may find the row bad already
          MeshCursor fcur;
          const auto answer = query(forged, fcur);
          EXPECT_FALSE(read_by_grid) << "a crafted scalar column went unnoticed";
          EXPECT_TRUE(answer == query(good, cur)) << "a crafted column changed the answer";
        } catch (const Error& e) {
          EXPECT_EQ(e.kind(), ErrorKind::Corrupt) << e.what();
          EXPECT_NE(std::string(e.what()).find("topology/elements row "), std::string::npos) << e.what();
        }
      };
      check("node", [&](const FineMesh& m, MeshCursor& k) {
        const Vec3 p = m.node(node, k);
        return std::array<double, 3>{p.x, p.y, p.z};
      });
      check("element", [&](const FineMesh& m, MeshCursor& k) {
        const FineElement e = m.element(element, k);
        return std::make_tuple(e.nodes, e.block, e.coarse_element, e.ijk);
      });
    }
    if (c.dataset == "topology/elements" && (c.what == std::string("element_first") || c.what == std::string("flags") ||
                                              c.what == std::string("interval") || c.what == std::string("grading") ||
                                              c.what == std::string("ratio"))) {
      // Point location reads these of every candidate element (its grid
      // and curved flag) without decoding the whole row: the centre of
      // coarse element `row` is a point whose search reaches that row.
      FineMesh m = read_store(s.path);
      MeshCursor cur;
      Vec3 v[8];
      const RowReader R(m.tables(), cur);
      R.corner_xyz(row, v);
      double x = 0, y = 0, z = 0;
      for (int q = 0; q < R.corners(); ++q) x += v[q].x / R.corners(), y += v[q].y / R.corners(), z += v[q].z / R.corners();
      char pt[128];
      std::snprintf(pt, sizeof pt, "%.17g,%.17g,%.17g", x, y, z);
      const test::CliResult q = test::run_cli({"query", bad, "--point", pt});
      EXPECT_EQ(q.exit_code, 8) << q.err;
      EXPECT_NE(q.err.find(c.dataset + " row " + std::to_string(row) + ":"), std::string::npos) << q.err;
    }
    if (c.dataset == "topology/element_bounds") {
      // Point location scans the rows of a group from their page: it checks
      // them too (a NaN would hide its element, a silent -1). Node 0 is a
      // corner of coarse element 0: the search scans group 0, rows 0..31.
      const test::CliResult n0 = test::run_cli({"query", s.path, "--node", "0"});
      ASSERT_EQ(n0.exit_code, 0) << n0.err;
      std::istringstream in(n0.out);
      std::string word;
      long long id;
      double x, y, z;
      ASSERT_TRUE(in >> word >> id >> x >> y >> z) << n0.out;  // "node 0  x y z"
      char pt[128];
      std::snprintf(pt, sizeof pt, "%.17g,%.17g,%.17g", x, y, z);
      const test::CliResult q = test::run_cli({"query", bad, "--point", pt});
      EXPECT_EQ(q.exit_code, 8) << q.err;
      EXPECT_NE(q.err.find(c.dataset + " row " + std::to_string(row) + ":"), std::string::npos) << q.err;
    }
  }
}

}  // namespace

TEST(CraftedRows, EveryColumnOfAVolumeStoreIsChecked) { run_all(true); }
TEST(CraftedRows, EveryColumnOfASurfaceStoreIsChecked) { run_all(false); }

// The curved flag (bit 30 of an element's flags) set on a straight
// element: every column still valid, so only verify, which checks the bit
// against the element's edge and face rows (FORMAT.md), can tell; it does,
// naming the row. (A straight element's paths read no edge or face row,
// so a flag that lies the other way would silently give its owner and its
// curved neighbours different nodes.)
TEST(CraftedRows, ACurvedFlagThatTheRowsDoNotBearOutIsCorruptForVerify) {
  const Store& s = store(true);
  const int row = 1, flags = 2 * (8 + 12 + 6) + 5;  // element_columns: base + 5
  test::TempDir tmp;
  const std::string bad = tmp.path("bad.dice.h5");
  fs::copy_file(s.path, bad);
  ASSERT_EQ(test::run_cli({"verify", bad}).exit_code, 0);
  hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  const hsize_t w = width_of(f, "topology/elements");
  test::forge_page(f, "topology/elements", 0, [&](std::vector<std::uint8_t>& page) {
    std::int64_t v;
    std::memcpy(&v, page.data() + (row * w + flags) * 8, 8);
    ASSERT_EQ(v & (std::int64_t{1} << ElementRow::kCurvedBit), 0) << "the test store's elements are straight";
    v |= std::int64_t{1} << ElementRow::kCurvedBit;
    std::memcpy(page.data() + (row * w + flags) * 8, &v, 8);
  }, true);
  H5Fclose(f);
  const test::CliResult r = test::run_cli({"verify", bad});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  EXPECT_NE(r.err.find("topology/elements row 1: flagged curved, but no edge or face of it has moved nodes"),
            std::string::npos)
      << r.err;
}

// The page index the id searches rely on, lying by a little: the commands
// that search by that id answer Corrupt, and so does verify (it checks the
// index against the rows).
TEST(CraftedRows, ALyingPageIndexIsCorruptForEveryCommand) {
  const Store& s = store(true);
  for (const bool nodes : {true, false}) {
    const std::string ds = nodes ? "numbering/element_page_node" : "numbering/element_page_element";
    SCOPED_TRACE(ds);
    test::TempDir tmp;
    const std::string bad = tmp.path("bad.dice.h5");
    fs::copy_file(s.path, bad);
    hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    std::int64_t first = -1;  // page 1's first row's true first id
    test::forge_page(f, ds, 0, [&](std::vector<std::uint8_t>& page) {
      std::int64_t v;
      std::memcpy(&v, page.data() + 8, 8);
      first = v;
      v += 40;  // page 1's first row, 40 ids later than it is
      std::memcpy(page.data() + 8, &v, 8);
    }, true);
    H5Fclose(f);
    // The ids the lie moves are searched for in page 0, whose last row does
    // not hold them: every query of one of them, alone or as the start of a
    // range (the cursors look up their first id through the index, then
    // walk the rows), is Corrupt.
    EXPECT_EQ(test::run_cli({"verify", bad}).exit_code, 8);
    for (std::int64_t id = first; id < first + 40; id += 7) {
      const std::string one = std::to_string(id), range = one + ":" + std::to_string(id + 3);
      for (const std::string what : {nodes ? "--node" : "--element", nodes ? "--nodes" : "--elements"}) {
        const std::string arg = what.back() == 's' ? range : one;
        const test::CliResult r = test::run_cli({"query", bad, what, arg});
        EXPECT_EQ(r.exit_code, 8) << what << " " << arg << ": " << r.err;
        EXPECT_NE(r.err.find("bad.dice.h5"), std::string::npos) << r.err;
      }
    }
    // A range from 0 walks the rows and never consults the index past its
    // start: it is answered correctly (nothing silent: the answer is right).
    const test::CliResult whole = test::run_cli(
        {"query", bad, nodes ? "--nodes" : "--elements", "0:" + std::to_string(nodes ? s.nodes : s.elements)});
    const test::CliResult good = test::run_cli(
        {"query", s.path, nodes ? "--nodes" : "--elements", "0:" + std::to_string(nodes ? s.nodes : s.elements)});
    EXPECT_EQ(whole.exit_code, 0) << whole.err;
    EXPECT_EQ(whole.out, good.out);
    // The sweep reads the index only to balance its threads' chunks (a
    // store's split comes from it); what it sweeps, and so its checksum,
    // is the good store's.
    auto checksum = [](const test::CliResult& r) {
      const size_t at = r.out.find("\"checksum\":\"");
      return at == std::string::npos ? std::string("(none)") : r.out.substr(at, 30);
    };
    const test::CliResult swept = test::run_cli({"sweep", bad, "--threads", "2", "--json"});
    const test::CliResult good_swept = test::run_cli({"sweep", s.path, "--threads", "2", "--json"});
    EXPECT_EQ(swept.exit_code, 0) << swept.err;
    EXPECT_EQ(checksum(swept), checksum(good_swept));
    EXPECT_NE(checksum(good_swept), "(none)") << good_swept.out;
  }
}

// The same lie in one process, where a kept element table's node-id guide
// (tables.hpp LazyIdGuide) fills page by page as queries land: each moved
// id is Corrupt every time it is asked, before and after the pages around
// it were filled, and every other id is the good store's node, bit for bit.
// (The CLI test above asks each id once, in a process of its own, so it
// never reaches a filled guide.)
TEST(CraftedRows, ALyingPageIndexIsCorruptAtEveryAskingInOneProcess) {
  const Store& s = store(true);
  test::TempDir tmp;
  const std::string bad = tmp.path("bad.dice.h5");
  fs::copy_file(s.path, bad);
  hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  std::int64_t first = -1;
  test::forge_page(f, "numbering/element_page_node", 0, [&](std::vector<std::uint8_t>& page) {
    std::memcpy(&first, page.data() + 8, 8);
    const std::int64_t v = first + 40;
    std::memcpy(page.data() + 8, &v, 8);
  }, true);
  H5Fclose(f);
  ASSERT_GT(first, 0);
  const FineMesh good = read_store(s.path);
  for (const bool keep : {true, false}) {
    SCOPED_TRACE(keep ? "kept tables" : "nothing kept");
    const FineMesh m = read_store(bad, StoreOptions{64ull << 20, 4, keep});
    const LazyIdGuide* guide = m.tables().node_row_guide.get();
    ASSERT_EQ(guide != nullptr, keep) << "the guide is what this test is about";
    std::vector<Id> ids(static_cast<size_t>(s.nodes));
    for (Id i = 0; i < s.nodes; ++i) ids[static_cast<size_t>(i)] = i;
    std::mt19937_64 rng(7);
    size_t corrupt = 0;
    for (int round = 0; round < 3; ++round) {
      std::shuffle(ids.begin(), ids.end(), rng);
      MeshCursor cur;
      for (const Id id : ids) {
        const bool moved = id >= first && id < first + 40;
        try {
          const Vec3 p = m.node(id, cur), q = good.node(id);
          EXPECT_FALSE(moved) << "node " << id << " answered through a lying index";
          EXPECT_EQ(std::memcmp(&p, &q, sizeof p), 0) << "node " << id;
        } catch (const Error& e) {
          EXPECT_TRUE(moved) << "node " << id << ": " << e.what();
          EXPECT_EQ(e.kind(), ErrorKind::Corrupt) << e.what();
          EXPECT_NE(std::string(e.what()).find("bad.dice.h5"), std::string::npos) << e.what();
          ++corrupt;
        }
      }
      if (keep) {  // after the first round every page has been landed on
        const Id pages = static_cast<Id>(m.tables().node_index.size());
        for (Id p = 0; p < pages; ++p) EXPECT_TRUE(guide->page_done[static_cast<size_t>(p)].load()) << "page " << p;
      }
    }
    EXPECT_EQ(corrupt, 3u * 40u);
  }
}

// A graded sheet whose direction is crafted inconsistent: one edge of a
// geometric sheet flipped (kind 1 <-> 5 in column 9), checksums valid.
// verify names the edges table and a row; so does a query of the flipped
// edge's face nodes.
TEST(CraftedRows, AnInconsistentGradingDirectionIsCorrupt) {
  test::TempDir tmp;
  const std::string good = tmp.path("g.dice.h5"), bad = tmp.path("bad.dice.h5");
  auto r = test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "3", "--sheet-bias", "0=1.4",
                          "--sheet-bias", "1=0.7", "--sheet-bias", "2=1.3", "-o", good});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(test::run_cli({"verify", good}).exit_code, 0);
  fs::copy_file(good, bad);
  hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  const hsize_t w = width_of(f, "topology/edges");
  ASSERT_EQ(w, 11u);
  std::int64_t flipped = -1;
  test::forge_page(f, "topology/edges", 0, [&](std::vector<std::uint8_t>& page) {
    for (std::size_t row = 0; row * w * 8 < page.size() && flipped < 0; ++row) {
      std::int64_t g;
      std::memcpy(&g, page.data() + (row * w + 9) * 8, 8);
      if ((g & 3) != 1) continue;  // geometric
      g ^= 4;
      std::memcpy(page.data() + (row * w + 9) * 8, &g, 8);
      flipped = static_cast<std::int64_t>(row);
    }
  }, true);
  H5Fclose(f);
  ASSERT_GE(flipped, 0) << "no geometric edge on the first page";
  r = test::run_cli({"verify", bad});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  EXPECT_NE(r.err.find("topology/edges row "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("grad"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

// The per-block tables, forged with valid checksums: two blocks given one
// id (the Exodus export then failed as an I/O error blaming its output) is
// Corrupt on opening; two blocks trading fine elements (the sum kept, so
// info printed wrong counts and verify passed) is a defect verify names.
TEST(CraftedRows, PerBlockTablesThatDisagreeWithTheElementsAreCaught) {
  test::TempDir tmp;
  const std::string good = tmp.path("g.dice.h5");
  auto r = test::run_cli({"dice", test::data_path("cardinal_pincell.e"), "--interval", "1", "-o", good});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto forged = [&](const std::string& name, const std::string& ds, auto&& edit) {
    const std::string bad = tmp.path(name);
    fs::copy_file(good, bad);
    hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    test::forge_page(f, ds, 0, [&](std::vector<std::uint8_t>& page) {
      std::int64_t v[2];
      ASSERT_GE(page.size(), sizeof v);
      std::memcpy(v, page.data(), sizeof v);
      edit(v);
      std::memcpy(page.data(), v, sizeof v);
    }, true);
    H5Fclose(f);
    return bad;
  };
  const std::string dup = forged("dup.dice.h5", "coarse/block_id", [](std::int64_t* v) { v[1] = v[0]; });
  for (const std::string cmd : {"info", "verify", "sweep"}) {
    r = test::run_cli({cmd, dup});
    EXPECT_EQ(r.exit_code, 8) << cmd << ": " << r.err;
    EXPECT_NE(r.err.find("coarse/block_id: block id 1 appears twice"), std::string::npos) << cmd << ": " << r.err;
  }
  const std::string traded =
      forged("traded.dice.h5", "coarse/block_fine_elements", [](std::int64_t* v) { ++v[0], --v[1]; });
  ASSERT_EQ(test::run_cli({"info", traded}).exit_code, 0) << "the sum still holds: only verify can tell";
  r = test::run_cli({"verify", traded});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE((r.out + r.err).find("block 1: coarse/block_coarse_elements and block_fine_elements say"), std::string::npos)
      << r.out << r.err;
}

// Tables no element reads, forged with valid checksums: the sheets (info
// printed a forged interval or grading, and verify passed) and the sets
// (verify passed; only an export then failed). verify checks each against
// the edges or the mesh: Corrupt (exit 8), one line naming the table.
TEST(CraftedRows, SheetAndSetTablesThatTheMeshDoesNotBearOutAreCorruptForVerify) {
  test::TempDir tmp;
  const std::string good = tmp.path("g.dice.h5");
  // PROVENANCE.md: 7 side sets (ids 1..7), 3 node sets; interval 2 everywhere.
  auto r = test::run_cli({"dice", test::data_path("vtkdata_disk_out_ref.ex2"), "--interval", "2", "-o", good});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(test::run_cli({"verify", good}).exit_code, 0);
  struct Case {
    const char* name;
    std::string dataset;
    std::size_t byte;   // of the first page
    std::int64_t value;
    std::vector<std::string> said;
  };
  std::int64_t edge_sheet = -1;  // edge row 1's sheet, for a valid other one
  {
    const FineMesh m = read_store(good);
    MeshCursor cur;
    edge_sheet = RowReader(m.tables(), cur).edge(1).sheet;
    ASSERT_GT(m.info().sheets, 1);
  }
  const std::int64_t dual = 2;  // FORMAT.md: sheet_grading kind 2, a ratio, start -1
  const std::vector<Case> cases = {
      // Sheet 0 at interval 3, its edges at 2: every column in range.
      {"interval", "sheets/sheet_interval", 0, 3, {"topology/edges row ", "sheets/sheet_interval"}},
      {"grading", "sheets/sheet_grading", 0, dual, {"topology/edges row ", "sheets/sheet_grading"}},
      // Edge 1 moved to another sheet of the same interval: only the
      // element's parallel edges tell.
      {"edge sheet", "topology/edges", 1 * 11 * 8 + 4 * 8, edge_sheet == 0 ? 1 : 0, {"topology/edges row ", "parallel"}},
      {"side set member", "sets/side_set_member", 0, 1 << 30, {"side set ", "entry out of range"}},
      {"node set vertex", "sets/node_set_vertex", 0, -1, {"node set ", "vertex out of range"}},
      {"side set id", "sets/side_set_id", 8, 0, {"sets/side_set_id: set id ", " appears twice"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string bad = tmp.path(std::string(c.name) + ".dice.h5");
    fs::copy_file(good, bad);
    hid_t f = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    test::forge_page(f, c.dataset, 0, [&](std::vector<std::uint8_t>& page) {
      ASSERT_GE(page.size(), c.byte + 8);
      if (c.dataset == "sheets/sheet_grading") {  // a dual grading of ratio 1.5: a valid row
        const std::int64_t row[3] = {dual, std::bit_cast<std::int64_t>(1.5), -1};
        std::memcpy(page.data(), row, sizeof row);
        return;
      }
      if (c.dataset == "sets/side_set_id") {  // the second set given the first one's id
        std::memcpy(page.data() + 8, page.data(), 8);
        return;
      }
      std::memcpy(page.data() + c.byte, &c.value, 8);
    }, true);
    H5Fclose(f);
    r = test::run_cli({"verify", bad});
    EXPECT_EQ(r.exit_code, 8) << r.out << r.err;
    for (const auto& s : c.said) EXPECT_NE(r.err.find(s), std::string::npos) << s << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}
