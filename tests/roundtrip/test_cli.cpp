// The dicer command end to end: JSON contracts, exactness of printed
// coordinates, exit codes of refusals. JSON is parsed with nlohmann::json.
#include <gtest/gtest.h>

#include <fstream>
#include <iomanip>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dicer/store.hpp"
#include "test_support.hpp"

using namespace dicer;
using test::run_cli;
using Json = nlohmann::json;

namespace {
std::vector<Json> json_lines(const std::string& out) {
  std::vector<Json> v;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) v.push_back(Json::parse(line));
  return v;
}
}  // namespace

TEST(Cli, DiceInfoQueryVerifyOnARealMesh) {
  test::TempDir tmp;
  const std::string store = tmp.path("sphere.dice.h5");
  auto r = run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "3", "-o", store});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"info", store, "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json info = Json::parse(r.out);
  EXPECT_EQ(info["mode"], "volume");
  EXPECT_EQ(info["coarse_vertices"], 321);  // PROVENANCE.md
  EXPECT_EQ(info["coarse_elements"], 256);
  EXPECT_EQ(info["fine_elements"], 256 * 27);
  for (const char* k : {"coarse_edges", "coarse_faces", "sheets", "fine_nodes", "format_version", "store_bytes"})
    EXPECT_TRUE(info.contains(k)) << k;
  ASSERT_EQ(info["blocks"].size(), 1u);
  EXPECT_EQ(info["blocks"][0]["fine_elements"], 256 * 27);
  // One interval per sheet, as asked (every sheet at 3).
  ASSERT_EQ(info["sheet_intervals"].size(), info["sheets"].get<size_t>());
  for (const auto& n : info["sheet_intervals"]) EXPECT_EQ(n, 3);
  // V - E + F - H = 1 for a solid ball, on the coarse mesh.
  const long long euler = info["coarse_vertices"].get<long long>() - info["coarse_edges"].get<long long>() +
                          info["coarse_faces"].get<long long>() - info["coarse_elements"].get<long long>();
  EXPECT_EQ(euler, 1);

  // Printed coordinates round-trip exactly to the library's values.
  const FineMesh m = read_store(store);
  r = run_cli({"query", store, "--nodes", "100:140", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto nodes = json_lines(r.out);
  ASSERT_EQ(nodes.size(), 40u);
  for (const auto& n : nodes) {
    const Vec3 p = m.node(n["id"].get<Id>());
    EXPECT_EQ(n["xyz"][0].get<double>(), p.x);
    EXPECT_EQ(n["xyz"][1].get<double>(), p.y);
    EXPECT_EQ(n["xyz"][2].get<double>(), p.z);
  }
  const Id last = m.num_elements() - 1;
  r = run_cli({"query", store, "--element", std::to_string(last), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json el = Json::parse(r.out);
  EXPECT_EQ(el["nodes"].size(), 8u);
  EXPECT_EQ(el["coarse_element"], 255);
  EXPECT_EQ(el["ijk"], Json::array({2, 2, 2}));
  EXPECT_EQ(el["block"], m.info().blocks[0].id);
  // --point: the element's centroid (inside it only) comes back in it at
  // xi = (1/2, 1/2, 1/2); --points streams a file, a bad line is named.
  {
    double c[3] = {0, 0, 0};
    for (int q = 0; q < 8; ++q) {
      const Vec3 p = m.node(el["nodes"][q].get<Id>());
      c[0] += p.x / 8, c[1] += p.y / 8, c[2] += p.z / 8;
    }
    char pt[200];
    std::snprintf(pt, sizeof pt, "%.17g,%.17g,%.17g", c[0], c[1], c[2]);
    r = run_cli({"query", store, "--point", pt, "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Json at = Json::parse(r.out);
    EXPECT_EQ(at["element"], last);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(at["xi"][d].get<double>(), 0.5, 0.1);  // a curved part's centroid is near
    const std::string pts = tmp.path("points.txt");
    {
      std::ofstream f(pts);
      f << std::setprecision(17) << "# probes\n" << c[0] << " " << c[1] << " " << c[2] << "\n\n1e9 1e9 1e9\n";
    }
    r = run_cli({"query", store, "--points", pts, "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out.substr(0, std::to_string(last).size() + 1), std::to_string(last) + " ");
    EXPECT_NE(r.out.find("\n-1 "), std::string::npos) << r.out;
    {
      std::ofstream f(pts, std::ios::app);
      f << "1 2\n";
    }
    r = run_cli({"query", store, "--points", pts});
    EXPECT_EQ(r.exit_code, 3) << "a bad input file";
    EXPECT_NE(r.err.find("points.txt:5: \"1 2\" is not three finite numbers"), std::string::npos) << r.err;
    r = run_cli({"query", store, "--point", "1,2"});
    EXPECT_EQ(r.exit_code, 2) << "a bad value on the command line";
    // A NUL ended the line for strtod (the rest was dropped, exit 0); what
    // follows the third number is named, not counted as a fourth.
    const std::vector<std::pair<std::string, std::string>> lines = {
        {std::string("0.5 0.5 0.5\0 0.5\n", 17), "0.5 0.5 0.5\\x00 0.5\" holds a NUL byte"},
        {"1,2,3,\n", "is not three finite numbers x y z (\",\" after the third)"},
        {"0.5 0.5 -0.5e\n", "(\"e\" after the third)"},
        {"1 2 3 4\n", "has more than three numbers"},
        {"1,2,3,4\n", "has more than three numbers"}};
    for (const auto& [line, says] : lines) {
      test::write_file(pts, line);
      r = run_cli({"query", store, "--points", pts});
      EXPECT_EQ(r.exit_code, 3) << r.err;
      EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
    }
    // Options that would be ignored are refused: --threads is for --points,
    // --max-distance for surface stores.
    r = run_cli({"query", store, "--point", "0,0,0", "--threads", "2"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("--threads goes with --points"), std::string::npos) << r.err;
    r = run_cli({"query", store, "--point", "0,0,0", "--max-distance", "1"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("is a volume store"), std::string::npos) << r.err;
  }
  // A range partly out: the message names the first id that is not there.
  {
    const Id n = read_store(store).num_nodes();
    r = run_cli({"query", store, "--nodes", std::to_string(n - 2) + ":" + std::to_string(n + 3)});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("node id " + std::to_string(n) + " is out of range (the mesh has " + std::to_string(n) + " nodes"),
              std::string::npos) << r.err;
  }
  // --element-neighbors: 6 sides, the boundary -1, each neighbour names it back.
  r = run_cli({"query", store, "--element-neighbors", std::to_string(last), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json nb = Json::parse(r.out);
  ASSERT_EQ(nb["neighbors"].size(), 6u);
  int inside = 0;
  for (const auto& n : nb["neighbors"]) {
    if (n.get<Id>() < 0) continue;
    ++inside;
    const auto back = run_cli({"query", store, "--element-neighbors", std::to_string(n.get<Id>()), "--json"});
    ASSERT_EQ(back.exit_code, 0) << back.err;
    const Json b = Json::parse(back.out)["neighbors"];
    EXPECT_NE(std::find(b.begin(), b.end(), Json(last)), b.end()) << n;
  }
  EXPECT_GE(inside, 3);
  // --node-elements: the last element's first node is used by it.
  r = run_cli({"query", store, "--node-elements", std::to_string(el["nodes"][0].get<Id>()), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json ne = Json::parse(r.out)["elements"];
  EXPECT_NE(std::find(ne.begin(), ne.end(), Json(last)), ne.end()) << r.out;
  r = run_cli({"verify", store});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos);
}

TEST(Cli, SheetsListEdgesInFileNumbering) {
  auto r = run_cli({"sheets", test::data_path("cardinal_brick.e"), "--json", "--edges", "--interval", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json j = Json::parse(r.out);
  long long max_id = 0, edges = 0;
  for (const auto& s : j["sheets"]) {
    EXPECT_EQ(s["interval"], 2);
    EXPECT_EQ(s["edges"].size(), s["edge_count"].get<size_t>());
    for (const auto& e : s["edges"]) max_id = std::max({max_id, e[0].get<long long>(), e[1].get<long long>()}), ++edges;
    EXPECT_EQ(s["blocks"], Json::array({3}));  // the brick is block 3 only
  }
  // The brick's node_num_map has gaps up to 5925 (PROVENANCE.md): ids are the file's, not 1..4665.
  EXPECT_EQ(max_id, 5925);
  // Sheet ids do not depend on the command that lists them.
  auto again = run_cli({"sheets", test::data_path("cardinal_brick.e"), "--json", "--edges"});
  EXPECT_EQ(Json::parse(again.out)["sheets"][5]["edges"], j["sheets"][5]["edges"]);
}

TEST(Cli, IntervalsFileAndFlagsCombine) {
  test::TempDir tmp;
  const std::string plan = tmp.path("plan.json"), store = tmp.path("m.dice.h5");
  test::write_file(plan, R"({"global": 2, "blocks": {"76": 3}})");
  auto r = run_cli({"dice", test::data_path("vtkdata_mug.e"), "--intervals-file", plan, "--sheet-interval", "0=4", "-o", store});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"info", store, "--json"});
  const Json info = Json::parse(r.out);
  ASSERT_EQ(info["blocks"].size(), 2u);
  EXPECT_EQ(info["blocks"][1]["id"], 76);
  EXPECT_EQ(info["blocks"][1]["coarse_elements"], 760);
  EXPECT_GT(info["blocks"][1]["fine_elements"].get<long long>(), 760LL * 8);  // block 76 asks 3 > 2
}

// The README's boundary layer, command by command: sheet 70 of the pin cell
// graded from wall node 3392; the interior nodes of the radial coarse edge
// at the wall (ids 22081..22087) step away from the wall (x = 0.64) by
// cells growing 1.3 times each, the first 0.155 (1.3 - 1) / (1.3^8 - 1).
TEST(Cli, ReadmeBoundaryLayerExample) {
  test::TempDir tmp;
  const std::string mesh = test::data_path("cardinal_pincell.e"), store = tmp.path("pin.dice.h5");
  const std::vector<std::string> flags = {"--interval", "2", "--sheet-interval", "70=8", "--sheet-bias", "70=1.3@3392"};
  auto with = [&](std::vector<std::string> a) {
    a.insert(a.end(), flags.begin(), flags.end());
    return a;
  };
  auto r = run_cli(with({"sheets", mesh, "--json", "--edges"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<Id> through;
  const Json sheets = Json::parse(r.out);
  for (const auto& sh : sheets["sheets"])
    for (const auto& e : sh["edges"])
      if (e[0] == 3392 || e[1] == 3392) {
        through.push_back(sh["id"]);
        break;
      }
  EXPECT_EQ(through, (std::vector<Id>{0, 3, 38, 39, 70}));
  r = run_cli(with({"sheets", mesh}));
  EXPECT_NE(r.out.find("      70     1440        8         1.3@3392  2\n"), std::string::npos) << r.out;
  r = run_cli(with({"dice", mesh, "-o", store, "--quiet"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"query", store, "--nodes", "22081:22088"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream in(r.out);
  std::vector<double> x{0.64};
  std::string word;
  Id id;
  double px, py, pz;
  while (in >> word >> id >> px >> py >> pz) {
    EXPECT_EQ(py, 0.0);
    EXPECT_NEAR(pz, 4.9152542372881349, 1e-15);
    x.insert(x.begin() + 1, px);  // ids run inwards to outwards: the wall first after reversing
  }
  std::sort(x.begin(), x.end(), std::greater<>());
  x.push_back(0.485);
  ASSERT_EQ(x.size(), 9u);
  const double h0 = 0.155 * 0.3 / (std::pow(1.3, 8) - 1);
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(x[k] - x[k + 1], h0 * std::pow(1.3, k), 1e-13) << "cell " << k;
  EXPECT_EQ(run_cli({"verify", store, "--quiet"}).exit_code, 0);
}

TEST(Cli, RefusalsHaveDocumentedExitCodesAndLeaveNoOutput) {
  test::TempDir tmp;
  const std::string out = tmp.path("never.dice.h5");
  const std::string mesh = test::data_path("cardinal_sphere.e");
  struct Case {
    std::vector<std::string> args;
    int code;
    const char* text;
  };
  const std::vector<Case> cases = {
      {{"dice", mesh, "--bogus", "-o", out}, 2, "unknown option --bogus"},
      {{"dice", mesh, "--interval", "0", "-o", out}, 2, "interval must be a whole number >= 1 (got 0)"},
      {{"dice", mesh, "--interval", "-4", "-o", out}, 2, "interval must be a whole number >= 1 (got -4)"},
      {{"dice", mesh, "--interval", "abc", "-o", out}, 2, "not a whole number"},
      {{"dice", mesh, "--interval", "99999999999999999999", "-o", out}, 2, "does not fit in 64 bits"},
      {{"dice", mesh, "--interval", "1000000000", "-o", out}, 6, "more than 2^40 grid points"},
      {{"dice", mesh, "--block-interval", "9=2", "-o", out}, 2, "no block with id or name \"9\""},
      {{"dice", mesh, "--sheet-interval", "500=2", "-o", out}, 2, "no sheet 500"},
      {{"dice", mesh, "--interval", "2"}, 2, "missing -o"},
      {{"dice", tmp.path("nope.exo"), "-o", out}, 5, "cannot open"},
      {{"frobnicate"}, 2, "unknown command"},
  };
  for (const auto& c : cases) {
    const auto r = run_cli(c.args);
    EXPECT_EQ(r.exit_code, c.code) << c.args[0] << " " << c.args[2] << ": " << r.err;
    EXPECT_NE(r.err.find(c.text), std::string::npos) << r.err;
    // One line of message.
    EXPECT_LE(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
  }
  size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.dir())) ++files;
  EXPECT_EQ(files, 0u);
}

// A message quotes file names and file content: control bytes (a line
// break, an ESC that starts a terminal escape sequence) and bytes that are
// not UTF-8 reach the terminal as escapes, so the message stays one line
// and a hostile file cannot drive the terminal; UTF-8 names stay readable.
TEST(Cli, MessagesShowControlAndNonUtf8BytesAsEscapes) {
  test::TempDir tmp;
  const std::string store = test::diced_store("cardinal_brick.e", 1);
  // Every byte the terminal sees is printable ASCII, the line's end aside.
  auto plain = [](const std::string& err) {
    for (size_t i = 0; i + 1 < err.size(); ++i)
      if (static_cast<unsigned char>(err[i]) < 0x20 || static_cast<unsigned char>(err[i]) >= 0x7f) return false;
    return !err.empty() && err.back() == '\n';
  };
  const std::string pts = tmp.path("points.txt");
  test::write_file(pts, "1 2 3\n\x1b[31mRED 1 2\n");
  auto r = run_cli({"query", store, "--points", pts});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("points.txt:2: \"\\x1b[31mRED 1 2\" is not three finite numbers"), std::string::npos) << r.err;
  EXPECT_TRUE(plain(r.err)) << r.err;
  // A binary "line": bytes 0x80..0xff in order form no UTF-8 sequence
  // (each lead byte meets another lead byte); the quote stops at 60 bytes.
  std::string binary;
  for (int c = 0x80; c <= 0xff; ++c) binary.push_back(static_cast<char>(c));
  test::write_file(pts, binary + "\n");
  r = run_cli({"query", store, "--points", pts});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("points.txt:1: \"\\x80\\x81\\x82"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("\\xba\\xbb...\" is not three"), std::string::npos) << r.err;
  EXPECT_TRUE(plain(r.err)) << r.err;
  // A file name with a line break and an escape sequence, and a command.
  const std::string odd = tmp.path("bad\nname\x1b[2J.e");
  test::write_file(odd, "not an exodus file");
  r = run_cli({"dice", odd, "-o", tmp.path("x.dice.h5")});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("bad\\nname\\x1b[2J.e: "), std::string::npos) << r.err;
  EXPECT_TRUE(plain(r.err)) << r.err;
  r = run_cli({"\x1b]0;owned\x07"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown command \"\\x1b]0;owned\\x07\""), std::string::npos) << r.err;
  // C1 controls (U+0080..U+009F; U+009B is a one-byte CSI to some
  // terminals) are escaped; other UTF-8 is kept.
  r = run_cli({"info", tmp.path("maillage-\xc3\xa9t\xc3\xa9\xc2\x9b.dice.h5")});
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find("maillage-\xc3\xa9t\xc3\xa9\\u009b.dice.h5"), std::string::npos) << r.err;
  // Success lines echo the paths they were given the same way.
  auto all_plain = [](const std::string& out) {
    for (char c : out)
      if (c != '\n' && (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f)) return false;
    return !out.empty();
  };
  const std::string odd_store = tmp.path("out\n\x1b[2J\xff.dice.h5");
  const std::string shown = tmp.path("out\\n\\x1b[2J\\xff.dice.h5");
  r = run_cli({"dice", test::data_path("cardinal_brick.e"), "--interval", "1", "-o", odd_store});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("wrote " + shown + "\n"), std::string::npos) << r.out;
  EXPECT_TRUE(all_plain(r.out)) << r.out;
  const std::string odd_vtk = tmp.path("x\x1b[2J.vtkhdf");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"info", odd_store}, {"footprint", odd_store}, {"verify", odd_store},
        {"export", odd_store, "-o", odd_vtk}, {"export", odd_store, "-o", tmp.path("x\x1b[2J.e"), "--chunks", "2", "--format", "exodus", "--nemesis"}}) {
    r = run_cli(args);
    EXPECT_EQ(r.exit_code, 0) << args[0] << ": " << r.err;
    EXPECT_NE(r.out.find(shown), std::string::npos) << args[0] << ": " << r.out;
    EXPECT_TRUE(all_plain(r.out)) << args[0] << ": " << r.out;
  }
}

TEST(Cli, BadStoresAreRefusedClearly) {
  test::TempDir tmp;
  const std::string good = tmp.path("good.dice.h5");
  ASSERT_EQ(run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", good}).exit_code, 0);
  // Not HDF5 at all.
  test::write_file(tmp.path("text.dice.h5"), "hello, I am not a store\n");
  auto r = run_cli({"info", tmp.path("text.dice.h5")});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("not an HDF5 file"), std::string::npos) << r.err;
  // Truncated.
  const std::string bytes = test::read_file(good);
  test::write_file(tmp.path("cut.dice.h5"), bytes.substr(0, bytes.size() / 2));
  r = run_cli({"info", tmp.path("cut.dice.h5")});
  EXPECT_TRUE(r.exit_code == 3 || r.exit_code == 8) << r.err;
  EXPECT_NE(r.err.find("cut.dice.h5"), std::string::npos) << r.err;
  // Unknown version and a missing dataset, edited with HDF5 itself.
  const std::string ver = tmp.path("ver.dice.h5"), miss = tmp.path("miss.dice.h5");
  std::filesystem::copy_file(good, ver);
  std::filesystem::copy_file(good, miss);
  {
    hid_t f = H5Fopen(ver.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t a = H5Aopen(f, "format_version", H5P_DEFAULT);
    const long long v = 99;
    H5Awrite(a, H5T_NATIVE_LLONG, &v);
    H5Aclose(a);
    H5Fclose(f);
    f = H5Fopen(miss.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    H5Ldelete(f, "topology/faces", H5P_DEFAULT);
    H5Fclose(f);
  }
  r = run_cli({"info", ver});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_NE(r.err.find("version 99"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("reads version " + std::to_string(kStoreFormatVersion)), std::string::npos) << r.err;
  // A store of a previous format (5: numbered by kind; 6: without the spatial
  // index of format 7; 7: without gradings) is refused the same way.
  {
    hid_t f = H5Fopen(ver.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t a = H5Aopen(f, "format_version", H5P_DEFAULT);
    const long long v = 7;
    H5Awrite(a, H5T_NATIVE_LLONG, &v);
    H5Aclose(a);
    H5Fclose(f);
  }
  r = run_cli({"query", ver, "--node", "0"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_NE(r.err.find("store format version 7 is not known to this dicer (it reads version 8)"), std::string::npos) << r.err;
  // --version names the project's version (CMake's project()) and the format.
  r = run_cli({"--version"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, std::string("dicer ") + DICER_PROJECT_VERSION + " (store format 8)\n");
  r = run_cli({"query", miss, "--node", "0"});
  EXPECT_EQ(r.exit_code, 8);
  EXPECT_NE(r.err.find("topology/faces is missing"), std::string::npos) << r.err;
  // Query out of range.
  r = run_cli({"query", good, "--node", "999999999"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("out of range"), std::string::npos) << r.err;
}

// A script can pass --quiet to every command (those that draw no progress
// accept it and do nothing).
TEST(Cli, EveryCommandAcceptsQuiet) {
  test::TempDir tmp;
  const std::string mesh = test::data_path("cardinal_sphere.e"), store = tmp.path("s.dice.h5");
  ASSERT_EQ(run_cli({"dice", mesh, "--interval", "1", "-o", store, "--quiet"}).exit_code, 0);
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"sheets", mesh},
           {"info", store},
           {"query", store, "--node", "0"},
           {"verify", store},
           {"footprint", store},
           {"export", store, "-o", tmp.path("q.msh")},
           {"sweep", store},
           {"transfer", store, store, "--check"}}) {
    std::vector<std::string> quiet = args;
    quiet.push_back("--quiet");
    const auto r = run_cli(quiet);
    EXPECT_EQ(r.exit_code, 0) << args[0] << ": " << r.err;
  }
}

TEST(Cli, HelpTeaches) {
  auto r = run_cli({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("Exit codes"), std::string::npos);
  for (const char* cmd : {"sheets", "dice", "info", "query", "verify"}) {
    r = run_cli({cmd, "--help"});
    EXPECT_EQ(r.exit_code, 0) << cmd;
    EXPECT_NE(r.out.find("Usage: dicer"), std::string::npos) << cmd;
  }
  r = run_cli({"dice", "--help"});
  EXPECT_NE(r.out.find("precedence"), std::string::npos);
}

// `dicer` does not link Gmsh/OpenCASCADE; the commands that need a CAD
// model run in `dicer-cad` (found beside it, or through DICER_CAD), and a
// missing dicer-cad is a clear I/O error that names it, not a crash.
TEST(Cli, GmshIsLoadedOnlyByTheCadCommands) {
  const test::CliResult ldd = test::run_process({"/usr/bin/ldd", DICER_CLI});
  ASSERT_EQ(ldd.exit_code, 0) << ldd.err;
  EXPECT_NE(ldd.out.find("libhdf5"), std::string::npos) << ldd.out;  // ldd did list the libraries
  EXPECT_EQ(ldd.out.find("libgmsh"), std::string::npos) << ldd.out;
  EXPECT_EQ(ldd.out.find("libTK"), std::string::npos) << ldd.out;

  test::TempDir tmp;
  const std::string missing = tmp.path("no-such-dicer-cad");
  const std::map<std::string, std::string> env = {{"DICER_CAD", missing}};
  test::CliResult r = test::run_process({DICER_CLI, "mesh-coarse", tmp.path("part.step"), "--size", "1", "-o", tmp.path("c.msh")}, env);
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("dicer-cad"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  const std::string store = tmp.path("s.dice.h5");
  r = test::run_process({DICER_CLI, "dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "--geometry=x.step",
                         "-o", store}, env);
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_FALSE(std::filesystem::exists(store));
  // Commands without a CAD model never need it.
  r = test::run_process({DICER_CLI, "dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", store}, env);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = test::run_process({DICER_CLI, "verify", store, "--quiet"}, env);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // The hand-over keeps the arguments: dicer-cad refuses a missing CAD by name.
  r = run_cli({"verify", store, "--geometry", tmp.path("absent.step")});
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find("absent.step"), std::string::npos) << r.err;
}

// One HDF5 and one netCDF in the process: dicer links the Open MPI
// flavours that Debian's Exodus library already loads, never the serial ones.
TEST(Cli, TheBinaryLoadsOneHdf5AndOneNetcdf) {
  for (const std::string& bin : {std::string(DICER_CLI), std::string(DICER_CLI) + "-cad"}) {
    const test::CliResult r = test::run_process({"/usr/bin/ldd", bin});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out.find("libhdf5_serial"), std::string::npos) << bin << "\n" << r.out;
    EXPECT_EQ(r.out.find("libnetcdf.so"), std::string::npos) << bin << "\n" << r.out;
    EXPECT_NE(r.out.find("libhdf5_openmpi"), std::string::npos) << bin;
    EXPECT_NE(r.out.find("libnetcdf_mpi"), std::string::npos) << bin;
  }
}

// A flag given a value (--json=0 read as false, --json=1 as true), options
// that would change nothing (transfer --check --format petsc), and
// `dicer help CMD` (which printed the global help).
TEST(Cli, FlagsTakeNoValueAndIdleOptionsAreRefused) {
  test::TempDir tmp;
  const std::string store = test::diced_store("cardinal_brick.e", 1);
  for (const char* v : {"--json=1", "--json=0", "--json="}) {
    const auto r = run_cli({"info", store, v});
    EXPECT_EQ(r.exit_code, 2) << v << ": " << r.err;
    EXPECT_NE(r.err.find("--json takes no value"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  EXPECT_EQ(run_cli({"sweep", store, "--threads=1", "--quiet"}).exit_code, 0);  // a value option keeps its '='
  const std::vector<std::pair<std::vector<std::string>, const char*>> idle = {
      {{"transfer", store, store, "--check", "--format", "petsc"}, "--format is for -o FILE"},
      {{"transfer", store, store, "--check", "--petsc-int", "64"}, "--petsc-int is for -o FILE"},
      {{"transfer", store, store, "-o", tmp.path("P.h5"), "--petsc-int", "64"}, "--petsc-int is for --format petsc"}};
  for (const auto& [args, text] : idle) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(text), std::string::npos) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(tmp.path("P.h5")));
  const auto help = run_cli({"help", "export"}), direct = run_cli({"export", "--help"});
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_EQ(help.out, direct.out);
  EXPECT_EQ(help.out.rfind("Usage: dicer export STORE", 0), 0u) << help.out;
  EXPECT_EQ(run_cli({"help", "frobnicate"}).exit_code, 2);
}

// "--" ends the options (it was an unknown option): a file whose name
// starts with '-' is read after it, options after it are file names, and
// an argument too many after it is refused as one.
TEST(Cli, DoubleDashEndsTheOptions) {
  test::TempDir tmp;
  const std::string dashed = tmp.path("-b.e");
  std::filesystem::copy_file(test::data_path("cardinal_brick.e"), dashed);
  const auto plain = run_cli({"sheets", test::data_path("cardinal_brick.e"), "--json"});
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  // Run from the directory, so that the name itself starts with '-'.
  auto in_tmp = [&](std::vector<std::string> args) {
    args.insert(args.begin(), DICER_CLI);
    args.insert(args.begin(), {"/usr/bin/env", "-C", tmp.path("")});
    return test::run_process(args);
  };
  const auto dashed_run = in_tmp({"sheets", "--json", "--", "-b.e"});
  ASSERT_EQ(dashed_run.exit_code, 0) << dashed_run.err;
  // The same sheets; only the file name in the document differs.
  const auto sheets_of = [](const std::string& json) { return json.substr(json.find("\"sheets\"")); };
  EXPECT_EQ(sheets_of(dashed_run.out), sheets_of(plain.out));
  EXPECT_EQ(in_tmp({"sheets", "-b.e"}).exit_code, 2);  // without "--" it is an option
  auto r = in_tmp({"sheets", "--", "-b.e", "--json"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("unexpected argument \"--json\""), std::string::npos) << r.err;
  r = in_tmp({"sheets", "--", "--json"});  // a file named --json, which does not exist
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find("--json"), std::string::npos) << r.err;
  r = run_cli({"sheets", test::data_path("cardinal_brick.e"), "--bogus", "--", "x"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("unknown option --bogus"), std::string::npos) << r.err;
}

// DICER_CAD naming dicer itself (or a copy of it) made `dice --geometry`
// exec itself for ever: it is refused, exit 5, naming the variable.
TEST(Cli, DicerCadNamingDicerIsRefusedNotLooped) {
  test::TempDir tmp;
  const std::string copy = tmp.path("dicer-copy");
  std::filesystem::copy_file(DICER_CLI, copy);
  std::filesystem::permissions(copy, std::filesystem::perms::owner_all);
  const char* old = std::getenv("DICER_CAD");
  const std::string kept = old ? old : "";
  for (const std::string& cad : {std::string(DICER_CLI), copy}) {
    ::setenv("DICER_CAD", cad.c_str(), 1);
    // Under timeout: a broken guard loops for ever.
    auto r = test::run_process({"/usr/bin/timeout", "60", DICER_CLI, "dice", test::data_path("cardinal_brick.e"), "-o",
                                tmp.path("g.dice.h5"), "--geometry", test::data_path("cardinal_brick.e")});
    EXPECT_EQ(r.exit_code, 5) << cad << ": " << r.err;
    EXPECT_NE(r.err.find("is not dicer-cad"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("set DICER_CAD"), std::string::npos) << r.err;
    // Help is dicer's own: no dicer-cad needed.
    r = test::run_process({"/usr/bin/timeout", "60", DICER_CLI, "help", "mesh-coarse"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out.rfind("Usage: dicer mesh-coarse", 0), 0u) << r.out;
  }
  old ? ::setenv("DICER_CAD", kept.c_str(), 1) : ::unsetenv("DICER_CAD");
  EXPECT_FALSE(std::filesystem::exists(tmp.path("g.dice.h5")));
}

// A named physical group 0 (MSH 4.1: a group, as Gmsh reads it) is
// written back as group 0 without its name (Gmsh 4.8 would put a name of
// tag 0 on group 1): the export says so, naming it.
TEST(Cli, MshExportSaysGroupZerosNameIsLeftOut) {
  test::TempDir tmp;
  std::string text = test::read_file(test::data_path("dealii_step-49_example.msh"));
  const std::string end = "$EndMeshFormat\n";
  const size_t at = text.find(end);
  ASSERT_NE(at, std::string::npos);
  text.insert(at + end.size(), "$PhysicalNames\n2\n1 0 \"wall\"\n1 1 \"inlet\"\n$EndPhysicalNames\n");
  test::write_file(tmp.path("named.msh"), text);
  ASSERT_EQ(run_cli({"dice", tmp.path("named.msh"), "-o", tmp.path("n.dice.h5"), "--quiet"}).exit_code, 0);
  auto r = run_cli({"export", tmp.path("n.dice.h5"), "-o", tmp.path("n.msh"), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("note: the name of side set 0 (\"wall\") is not written to MSH"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("inlet"), std::string::npos) << r.err;
  const std::string msh = test::read_file(tmp.path("n.msh"));
  EXPECT_NE(msh.find("1 1 \"inlet\""), std::string::npos);
  EXPECT_EQ(msh.find("wall"), std::string::npos);
  r = run_cli({"export", tmp.path("n.dice.h5"), "-o", tmp.path("n.e"), "--quiet"});  // Exodus keeps it
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("wall"), std::string::npos) << r.err;
}
