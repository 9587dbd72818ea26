// The command line itself: file arguments that are not files (a directory,
// a FIFO), an output that is one of the inputs, file and block names that
// are not UTF-8, the JSON number policy, and the parser's contract (what
// --help lists is what is accepted). Every case runs the real binaries;
// JSON is read back by Python's json module, a parser independent of ours.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/stat.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <set>
#include <sstream>

#include "../../cli/json_out.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;
using test::run_cli;

namespace {

const std::string kPython = "/usr/bin/python3";

// Runs Python on `script` with `file` as sys.argv[1]; its stdout.
test::CliResult python(const std::string& script, const std::string& file) {
  return test::run_process({kPython, "-c", script, file}, {}, test::kForeignPythonEnv);
}

// Python reads the file as strict UTF-8 JSON (one document per line) and
// prints every number in it, in order, as the hex of its IEEE-754 bits
// ("null" for null): an independent check of what our printer wrote.
const char* kNumbersAsBits = R"(
import json, struct, sys
def walk(v):
    if v is None: print("null")
    elif isinstance(v, bool): pass
    elif isinstance(v, (int, float)): print(struct.pack(">d", float(v)).hex())
    elif isinstance(v, list):
        for x in v: walk(x)
    elif isinstance(v, dict):
        for x in v.values(): walk(x)
text = open(sys.argv[1], "rb").read().decode("utf-8")  # strict: invalid UTF-8 raises
for line in text.splitlines():
    if line: walk(json.loads(line))
)";

std::string bits_hex(double d) {
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(std::bit_cast<std::uint64_t>(d)));
  return buf;
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

// Doubles that stress a printer: subnormals, the extremes, exponents far
// from 0, values next to powers of ten, and random bit patterns.
std::vector<double> awkward_doubles(size_t random_count) {
  std::vector<double> v = {0.0,
                           -0.0,
                           std::numeric_limits<double>::denorm_min(),
                           -std::numeric_limits<double>::denorm_min(),
                           std::numeric_limits<double>::min(),
                           std::nextafter(std::numeric_limits<double>::min(), 0.0),  // largest subnormal
                           std::numeric_limits<double>::max(),
                           -std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::epsilon(),
                           0.1,
                           1.0 / 3.0,
                           std::nextafter(1e23, 0.0),
                           1e23,
                           5e-324,
                           9007199254740993.0,
                           123456789012345678.0,
                           std::ldexp(1.0, -1074 + 52),
                           std::ldexp(0.7, 1023)};
  std::mt19937_64 rng(20240611);
  while (v.size() < random_count + 18) {
    const double d = std::bit_cast<double>(rng());
    if (std::isfinite(d)) v.push_back(d);
  }
  // Random subnormals too: the exponent field all zero.
  for (int i = 0; i < 32; ++i) v.push_back(std::bit_cast<double>(rng() & 0x800FFFFFFFFFFFFFull));
  return v;
}

bool is_fifo(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
}

// A store to read, made once per test process.
const std::string& sphere_store() {
  static test::TempDir dir;
  static const std::string path = [] {
    const std::string p = dir.path("sphere.dice.h5");
    const auto r = run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", p});
    if (r.exit_code != 0) throw std::runtime_error("cannot make the store: " + r.err);
    return p;
  }();
  return path;
}

// Each command that reads a file, with IN for that file and OUT for an output.
const std::vector<std::vector<std::string>> kReadersOfStore = {
    {"info", "IN"},      {"query", "IN", "--node", "0"}, {"verify", "IN"}, {"footprint", "IN"},
    {"export", "IN", "--format", "msh", "-o", "OUT"},    {"sweep", "IN"}};
const std::vector<std::vector<std::string>> kReadersOfMesh = {
    {"sheets", "IN"}, {"dice", "IN", "-o", "OUT"}, {"mesh-coarse", "IN", "--size", "1", "-o", "OUT"}};

std::vector<std::string> substitute(const std::vector<std::string>& args, const std::string& in, const std::string& out) {
  std::vector<std::string> v;
  for (std::string a : args) {
    for (const auto& [key, value] : {std::pair{std::string("IN"), in}, std::pair{std::string("OUT"), out}})
      if (const auto p = a.find(key); p != std::string::npos && (p == 0 || a[p - 1] == '=')) a.replace(p, key.size(), value);
    v.push_back(a);
  }
  return v;
}

// Runs the CLI under timeout(1): a command that blocks (opening a FIFO)
// fails the test with 124 instead of hanging it.
test::CliResult run_cli_bounded(const std::vector<std::string>& args) {
  std::vector<std::string> argv{"/usr/bin/timeout", "20", DICER_CLI};
  argv.insert(argv.end(), args.begin(), args.end());
  return test::run_process(argv);
}

}  // namespace

// ---- file arguments

TEST(BadCli, OutputThatIsADirectoryIsAUsageErrorNamingIt) {
  test::TempDir tmp;
  const std::string dir = tmp.path("folder");
  fs::create_directory(dir);
  const std::vector<std::vector<std::string>> cases = {
      {"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", dir},
      {"export", sphere_store(), "--format", "exodus", "-o", dir},
      {"export", sphere_store(), "--format", "vtkhdf", "--output=" + dir},
      {"mesh-coarse", std::string(DICER_SOURCE_DIR) + "/examples/cylinder.brep", "--size", "1", "-o", dir}};
  for (const auto& args : cases) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args[0] << ": " << r.err;
    EXPECT_NE(r.err.find(dir), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("is a directory"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(fs::is_empty(dir)) << args[0];
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.dir()), fs::directory_iterator()), 1);
}

// "-o -" is not standard output (HDF5 and netCDF files need seeking, and an
// output appears whole under its name): refused, and no file named "-" made.
TEST(BadCli, OutputDashIsRefusedNotWrittenAsAFileNamedDash) {
  ASSERT_FALSE(fs::exists("-")) << "a file named - in " << fs::current_path();
  const std::string sphere = test::data_path("cardinal_sphere.e");
  const std::vector<std::vector<std::string>> cases = {
      {"dice", sphere, "--interval", "2", "-o", "-"},
      {"export", sphere_store(), "--format", "msh", "-o", "-"},
      {"export", sphere_store(), "--format", "vtkhdf", "--output=-"},
      {"transfer", sphere, sphere_store(), "-o", "-"},
      {"mesh-coarse", std::string(DICER_SOURCE_DIR) + "/examples/cylinder.brep", "--size", "1", "-o", "-"}};
  for (const auto& args : cases) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args[0] << ": " << r.err;
    EXPECT_NE(r.err.find("standard output"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists("-")) << args[0];
  }
}

// mesh-coarse writes MSH only: a name that says Exodus or HDF5 is refused,
// not filled with MSH text that extension-based readers would misread.
TEST(BadCli, MeshCoarseRefusesAnOutputNamedForAnotherFormat) {
  test::TempDir tmp;
  for (const std::string name : {"c.e", "c.EXO", "c.h5"}) {
    const auto r = run_cli({"mesh-coarse", std::string(DICER_SOURCE_DIR) + "/examples/cylinder.brep", "--size", "1", "-o",
                            tmp.path(name)});
    EXPECT_EQ(r.exit_code, 2) << name << ": " << r.err;
    EXPECT_NE(r.err.find("give a .msh name"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(tmp.path(name)));
  }
}

// An empty file name is a usage error naming the option, not "cannot open"
// (exit 5) or another option's complaint (--points "" once read as --point).
TEST(BadCli, EmptyFileNamesAndADirectoryOfPointsAreUsageErrors) {
  test::TempDir tmp;
  const std::string sphere = test::data_path("cardinal_sphere.e"), store = sphere_store();
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"info", ""}, "STORE: the file name is empty"},
      {{"dice", "", "--interval", "2", "-o", tmp.path("x.dice.h5")}, "MESH: the file name is empty"},
      {{"dice", sphere, "--interval", "2", "-o", ""}, "-o: the file name is empty"},
      {{"export", store, "--format", "msh", "-o", ""}, "-o: the file name is empty"},
      {{"query", store, "--points", ""}, "--points: the file name is empty"},
      {{"query", store, "--points", tmp.dir()}, "--points is a directory"}};
  for (const auto& c : cases) {
    const auto r = run_cli(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args[0] << ": " << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_TRUE(fs::is_empty(tmp.dir()));
}

TEST(BadCli, InputThatIsADirectoryOrAFifoIsRefusedBeforeAnyLibraryOpensIt) {
  test::TempDir tmp;
  const std::string dir = tmp.path("folder.dice.h5"), fifo = tmp.path("pipe.dice.h5");
  fs::create_directory(dir);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string out = tmp.path("out.file");
  auto check = [&](const std::vector<std::string>& form, const std::string& in, const char* what) {
    const auto args = substitute(form, in, out);
    const auto r = run_cli_bounded(args);
    EXPECT_EQ(r.exit_code, 2) << form[0] << " on " << what << ": " << r.err;  // 124: it blocked on the FIFO
    EXPECT_NE(r.err.find(in), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("no such file"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out));
  };
  for (const auto& form : kReadersOfStore) {
    check(form, dir, "directory");
    check(form, fifo, "FIFO");
  }
  for (const auto& form : kReadersOfMesh) {
    check(form, dir, "directory");
    check(form, fifo, "FIFO");
  }
  // The other files a command reads: the intervals file and the CAD model.
  const std::string sphere = test::data_path("cardinal_sphere.e");
  check({"dice", sphere, "--intervals-file", "IN", "-o", "OUT"}, fifo, "FIFO");
  check({"sheets", sphere, "--intervals-file=IN"}, dir, "directory");
  check({"dice", sphere, "--geometry", "IN", "-o", "OUT"}, fifo, "FIFO");
  check({"verify", sphere_store(), "--geometry", "IN"}, dir, "directory");
  EXPECT_TRUE(is_fifo(fifo));
}

TEST(BadCli, MissingInputIsAnIoErrorNamingIt) {
  test::TempDir tmp;
  for (const auto& form : kReadersOfStore) {
    const std::string in = tmp.path("absent.dice.h5");
    const auto r = run_cli(substitute(form, in, tmp.path("out")));
    EXPECT_EQ(r.exit_code, 5) << form[0] << ": " << r.err;
    EXPECT_NE(r.err.find(in), std::string::npos) << r.err;
  }
}

TEST(BadCli, OutputThatIsTheSameFileAsAnInputIsRefusedAndTheInputKept) {
  test::TempDir tmp;
  const std::string store = tmp.path("s.dice.h5"), mesh = tmp.path("m.e"), plan = tmp.path("plan.json");
  fs::copy_file(sphere_store(), store);
  fs::copy_file(test::data_path("cardinal_sphere.e"), mesh);
  test::write_file(plan, R"({"global": 2})");
  fs::create_symlink("s.dice.h5", tmp.path("store-link"));
  fs::create_symlink("m.e", tmp.path("mesh-link"));
  fs::create_hard_link(mesh, tmp.path("mesh-hard"));
  const std::string store_bytes = test::read_file(store), mesh_bytes = test::read_file(mesh);
  // Different strings, one file: compared by device and inode.
  const std::string dotted = (tmp.dir() / "." / "s.dice.h5").string();
  const std::string dotdot = (tmp.dir() / ".." / tmp.dir().filename() / "m.e").string();
  const std::vector<std::vector<std::string>> cases = {
      {"export", store, "--format", "msh", "-o", store},
      {"export", store, "--format", "vtkhdf", "-o", dotted},
      {"export", dotted, "--format", "exodus", "-o", tmp.path("store-link")},
      {"dice", mesh, "--interval", "2", "-o", mesh},
      {"dice", mesh, "--interval", "2", "-o", dotdot},
      {"dice", mesh, "--interval", "2", "-o", tmp.path("mesh-link")},
      {"dice", tmp.path("mesh-link"), "--interval", "2", "-o", mesh},
      {"dice", mesh, "--interval", "2", "-o", tmp.path("mesh-hard")},
      {"dice", mesh, "--intervals-file", plan, "-o", plan},
      {"mesh-coarse", plan, "--size", "1", "-o", plan},
  };
  for (const auto& args : cases) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args[0] << " -o " << args.back() << ": " << r.err;
    EXPECT_NE(r.err.find("same file"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(args.back()), std::string::npos) << "names the output: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_EQ(test::read_file(store), store_bytes);
  EXPECT_EQ(test::read_file(mesh), mesh_bytes);
  EXPECT_EQ(test::read_file(plan), R"({"global": 2})");
  for (const auto& e : fs::directory_iterator(tmp.dir()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << "left behind: " << e.path();
  // A different file of the same name elsewhere is fine.
  test::TempDir other;
  EXPECT_EQ(run_cli({"dice", mesh, "--interval", "2", "-o", other.path("m.e"), "--quiet"}).exit_code, 0);
}

// ---- JSON: UTF-8 and numbers

TEST(BadCli, FileAndBlockNamesThatAreNotUtf8GiveValidJson) {
  if (!fs::exists(kPython)) DICER_SKIP_OR_FAIL_IN_CI("no " << kPython);
  test::TempDir tmp;
  // A file name with bytes that are not UTF-8 (Linux names are bytes), and
  // a block (physical group) name with a lone continuation byte and a
  // truncated 3-byte sequence.
  const std::string mesh = tmp.path("m\xff\xfe-mesh.msh");
  test::write_file(mesh,
                   "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 7 \"bl\x80" "ck\xe2\x82\"\n$EndPhysicalNames\n"
                   "$Nodes\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$EndNodes\n"
                   "$Elements\n1\n1 5 2 7 1 1 2 3 4 5 6 7 8\n$EndElements\n");
  const std::string store = tmp.path("s.dice.h5");
  auto r = run_cli({"dice", mesh, "--interval", "2", "-o", store});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"info", store, "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  test::write_file(tmp.path("info.json"), r.out);
  const auto py = python(R"(
import json, sys
j = json.loads(open(sys.argv[1], "rb").read().decode("utf-8"))
print(j["source"].encode("unicode_escape").decode("ascii"))
print(j["blocks"][0]["name"].encode("unicode_escape").decode("ascii"))
)",
                         tmp.path("info.json"));
  ASSERT_EQ(py.exit_code, 0) << "not valid UTF-8 JSON: " << py.err;
  const auto names = lines_of(py.out);
  ASSERT_EQ(names.size(), 2u) << py.out;
  // Each invalid sequence becomes U+FFFD; the valid text around it stays.
  EXPECT_NE(names[0].find("/m\\ufffd\\ufffd-mesh.msh"), std::string::npos) << names[0];
  EXPECT_EQ(names[1].substr(0, 2), "bl") << names[1];
  EXPECT_NE(names[1].find("\\ufffdck"), std::string::npos) << names[1];
  EXPECT_EQ(names[1].find("\\x"), std::string::npos) << names[1];
}

// The printer the command uses (cli/json_out.hpp), read back by strtod and
// by Python: the same 64 bits for every finite double, null for the rest.
TEST(BadCli, JsonNumbersReadBackToTheSameBitsAndNonFiniteIsNull) {
  if (!fs::exists(kPython)) DICER_SKIP_OR_FAIL_IN_CI("no " << kPython);
  const std::vector<double> values = awkward_doubles(2000);
  std::string text;
  for (double d : values) {
    const std::string s = cli::json_text(cli::Json::array({d}));
    text += s + "\n";
    const std::string number = s.substr(1, s.size() - 2);
    EXPECT_LE(number.size(), 24u) << number;  // at most 17 digits, sign, point, exponent
    EXPECT_EQ(bits_hex(std::strtod(number.c_str(), nullptr)), bits_hex(d)) << number;
  }
  const double nonfinite[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity()};
  for (double d : nonfinite) {
    const std::string s = cli::json_text(cli::Json{{"x", d}});
    EXPECT_EQ(s, R"({"x":null})");
    text += s + "\n";
  }
  test::TempDir tmp;
  test::write_file(tmp.path("numbers.json"), text);
  const auto py = python(kNumbersAsBits, tmp.path("numbers.json"));
  ASSERT_EQ(py.exit_code, 0) << py.err;
  const auto got = lines_of(py.out);
  ASSERT_EQ(got.size(), values.size() + 3);
  for (size_t i = 0; i < values.size(); ++i) EXPECT_EQ(got[i], bits_hex(values[i])) << "value " << i;
  for (size_t i = values.size(); i < got.size(); ++i) EXPECT_EQ(got[i], "null");
}

// The same through the command: a store whose coarse vertices were forged
// (valid checksums) to hold awkward doubles; at interval 1 every fine node
// is a vertex, and `query --json` must print each coordinate so that an
// independent parser gets the library's bits back.
TEST(BadCli, QueryJsonCoordinatesAreExactForAwkwardDoubles) {
  if (!fs::exists(kPython)) DICER_SKIP_OR_FAIL_IN_CI("no " << kPython);
  test::TempDir tmp;
  const std::string store = tmp.path("s.dice.h5");
  ASSERT_EQ(run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "1", "-o", store}).exit_code, 0);
  const std::vector<double> values = awkward_doubles(321 * 3);
  {
    hid_t f = H5Fopen(store.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    // The corners table holds the coarse coordinates (a vertex's are its
    // owner's corner); at interval 1 every fine node is a coarse vertex.
    test::forge_page(f, "topology/element_corners", 0, [&](std::vector<std::uint8_t>& page) {
      const size_t n = std::min(page.size() / 8, size_t{321 * 3});
      std::memcpy(page.data(), values.data(), n * 8);
    }, true);
    H5Fclose(f);
  }
  const FineMesh m = read_store(store);
  ASSERT_EQ(m.num_nodes(), 321);
  const auto r = run_cli({"query", store, "--nodes", "0:321", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  test::write_file(tmp.path("nodes.json"), r.out);
  const auto py = python(kNumbersAsBits, tmp.path("nodes.json"));
  ASSERT_EQ(py.exit_code, 0) << py.err;
  const auto got = lines_of(py.out);  // per line: id, x, y, z
  ASSERT_EQ(got.size(), 321u * 4);
  std::set<std::string> printed;
  for (Id id = 0; id < 321; ++id) {
    const Vec3 p = m.node(id);
    EXPECT_EQ(got[4 * id], bits_hex(static_cast<double>(id)));
    EXPECT_EQ(got[4 * id + 1], bits_hex(p.x)) << "node " << id;
    EXPECT_EQ(got[4 * id + 2], bits_hex(p.y)) << "node " << id;
    EXPECT_EQ(got[4 * id + 3], bits_hex(p.z)) << "node " << id;
    for (int k = 1; k <= 3; ++k) printed.insert(got[4 * id + k]);
  }
  // The forged values did reach the output (the vertices are the nodes).
  for (double d : {std::numeric_limits<double>::denorm_min(), std::numeric_limits<double>::max(), 1e23})
    EXPECT_TRUE(printed.count(bits_hex(d))) << d;
}

// ---- the parser's contract

TEST(BadCli, OptionSpellingsRepeatsAndHelp) {
  test::TempDir tmp;
  const std::string mesh = test::data_path("cardinal_sphere.e");
  auto fine_elements = [&](const std::vector<std::string>& args) -> long long {
    const std::string store = tmp.path("x.dice.h5");
    std::vector<std::string> a = {"dice", mesh, "--quiet"};
    a.insert(a.end(), args.begin(), args.end());
    const auto r = run_cli(a);
    if (r.exit_code != 0) return -r.exit_code;
    const auto info = run_cli({"info", store, "--json"});
    return nlohmann::json::parse(info.out)["fine_elements"].get<long long>();
  };
  const std::string out = tmp.path("x.dice.h5");
  EXPECT_EQ(fine_elements({"--interval", "3", "-o", out}), 256 * 27);
  EXPECT_EQ(fine_elements({"--interval=3", "--output=" + out}), 256 * 27);
  EXPECT_EQ(fine_elements({"-o=" + out, "--interval", "3"}), 256 * 27);
  EXPECT_EQ(fine_elements({"--interval", "5", "--interval", "2", "-o", out}), 256 * 8);  // the last one counts
  // Repeatable: every value is kept (the sphere has one block, id 1).
  EXPECT_EQ(fine_elements({"--block-interval", "1=2", "--sheet-interval=0=3", "--sheet-interval", "1=3", "-o", out}),
            fine_elements({"--interval", "2", "--sheet-interval", "0=3", "--sheet-interval", "1=3", "-o", out}));
  // A repeatable option takes one value: the positional after it stays one.
  EXPECT_EQ(run_cli({"dice", "--block-interval", "1=2", mesh, "-o", out, "--quiet"}).exit_code, 0);

  // No command: the usage on stderr, exit 2; --help: on stdout, exit 0.
  auto r = run_cli({});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_TRUE(r.out.empty());
  EXPECT_NE(r.err.find("Usage: dicer"), std::string::npos);
  r = run_cli({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("Usage: dicer"), std::string::npos);
  // The exit codes, the JSON policy and every command are in the main help.
  for (const char* s : {"130", "143", "129", "70", "null", "U+FFFD"}) EXPECT_NE(r.out.find(s), std::string::npos) << s;
  r = run_cli({"frobnicate"});
  EXPECT_EQ(r.exit_code, 2);
  for (const char* c : {"mesh-coarse", "sheets", "dice", "info", "query", "verify", "footprint", "export", "sweep"})
    EXPECT_NE(r.err.find(c), std::string::npos) << c;
  // Errors name the flag.
  r = run_cli({"info", sphere_store(), "--cache-mb"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--cache-mb needs a value"), std::string::npos) << r.err;
  r = run_cli({"info", sphere_store(), "--read-ahead=2000"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--read-ahead"), std::string::npos) << r.err;
  r = run_cli({"info", sphere_store(), "stray"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unexpected argument \"stray\""), std::string::npos) << r.err;
  // The largest id: a range of one would overflow (UBSan: signed overflow).
  r = run_cli({"query", sphere_store(), "--node", "9223372036854775807"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--node"), std::string::npos) << r.err;
  // No --format and an extension that names none (.msh, .vtkhdf, .exo ...
  // would: test_export_cli.cpp).
  r = run_cli({"export", sphere_store(), "-o", tmp.path("y.txt")});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("missing --format FMT (vtkhdf, msh, msh-ascii or exodus): OUT's extension .txt names none"),
            std::string::npos) << r.err;
  r = run_cli({"export", sphere_store(), "-o", tmp.path("y")});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("OUT has no extension"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp.path("y.txt")) || fs::exists(tmp.path("y")));
}

// What `dicer COMMAND --help` lists is what the parser accepts, both ways:
// every --flag the help names (options and prose) is accepted (never
// "unknown option"), and every flag this test expects each command to take
// (from the README) is both accepted and listed with its description.
TEST(BadCli, HelpListsWhatTheParserAccepts) {
  const std::vector<std::string> store = {"--cache-mb", "--read-ahead", "--stats"};
  const std::vector<std::string> intervals = {"--interval",      "--size",         "--block-interval",
                                              "--sheet-interval", "--entity-interval", "--sheet-bias",
                                              "--sheet-dual-bias", "--block-bias",    "--entity-bias",
                                              "--intervals-file"};
  auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  const std::map<std::string, std::vector<std::string>> expected = {
      {"sheets", with({"--json", "--edges"}, intervals)},
      {"dice", with({"-o", "--output", "--geometry", "--geometry-tol", "--quiet"}, intervals)},
      {"info", with({"--json"}, store)},
      {"query", with({"--node", "--nodes", "--element", "--elements", "--box", "--count", "--json"}, store)},
      {"verify", with({"--geometry", "--json", "--quiet"}, store)},
      {"footprint", with({"--json", "--exact"}, store)},
      {"export", with({"--format", "-o", "--output", "--chunk", "--chunks", "--box", "--quiet"}, store)},
      {"sweep", with({"--threads", "--json", "--quiet"}, store)},
      {"mesh-coarse", {"--size", "-o", "--output", "--surface", "--subdivide", "--quiet"}},
  };
  const std::regex flag_re("(^|[\\s\\[(,|`])(--?[a-z][a-z-]*)");
  for (const auto& [cmd, flags] : expected) {
    SCOPED_TRACE(cmd);
    const auto help = run_cli({cmd, "--help"});
    ASSERT_EQ(help.exit_code, 0) << help.err;
    EXPECT_TRUE(help.err.empty()) << help.err;
    // Teaching: a usage line, an explanation, the options, an example.
    EXPECT_EQ(help.out.rfind("Usage: dicer " + cmd + " ", 0), 0u) << help.out;
    EXPECT_NE(help.out.find("\nExamples:\n  dicer " + cmd + " "), std::string::npos) << help.out;
    EXPECT_GT(help.out.size(), 600u);
    // Examples of other commands ("dicer dice ... --geometry" in mesh-coarse's) are theirs.
    std::string own;
    for (const auto& l : lines_of(help.out))
      if (l.rfind("  dicer ", 0) != 0 || l.rfind("  dicer " + cmd + " ", 0) == 0) own += l + "\n";
    std::set<std::string> named;
    for (std::sregex_iterator it(own.begin(), own.end(), flag_re), end; it != end; ++it) named.insert((*it)[2]);
    for (const auto& f : flags) {
      EXPECT_TRUE(named.count(f)) << f << " is not in the help";
      // Listed as an option line (indented, at the start of the line).
      EXPECT_TRUE(help.out.find("\n  " + f) != std::string::npos || help.out.find(", " + f) != std::string::npos) << f;
    }
    for (const auto& f : named) {
      if (f == "-h" || f == "--help") continue;
      const auto r = run_cli({cmd, f});
      EXPECT_EQ(r.err.find("unknown option"), std::string::npos) << f << ": " << r.err;
    }
    // An option the help does not name is refused, naming it.
    const auto r = run_cli({cmd, "--no-such-option"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("unknown option --no-such-option"), std::string::npos) << r.err;
  }
  // Defaults are shown, and they are the library's.
  const auto info = run_cli({"info", "--help"}).out;
  EXPECT_NE(info.find("(default: " + std::to_string(StoreOptions{}.cache_bytes >> 20) + ")"), std::string::npos) << info;
  EXPECT_NE(info.find("(default: " + std::to_string(StoreOptions{}.read_ahead_pages) + ")"), std::string::npos) << info;
  const auto dice = run_cli({"dice", "--help"}).out;
  EXPECT_NE(dice.find("(default: 1)"), std::string::npos) << dice;
  EXPECT_NE(dice.find("(default: 0.0001)"), std::string::npos) << dice;
  EXPECT_NE(dice.find("(repeatable)"), std::string::npos) << dice;
}

// Every command that opens a store takes the store options, export too,
// and --stats prints the page cache counters.
TEST(BadCli, EveryStoreCommandTakesTheStoreOptions) {
  test::TempDir tmp;
  for (const auto& form : kReadersOfStore) {
    auto args = substitute(form, sphere_store(), tmp.path("out.msh"));
    for (const char* a : {"--cache-mb", "8", "--read-ahead=2", "--stats"}) args.push_back(a);
    if (form[0] == "export" || form[0] == "verify" || form[0] == "sweep") args.push_back("--quiet");
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 0) << form[0] << ": " << r.err;
    EXPECT_NE(r.err.find("dicer " + form[0] + ": cache: "), std::string::npos) << form[0] << ": " << r.err;
    EXPECT_NE(r.err.find("of 8.0 MiB budget"), std::string::npos) << form[0] << ": " << r.err;
  }
}
