// The command line's JSON: file and block names that are not UTF-8, and the
// number policy (exact doubles, null for non-finite). JSON is read back by
// Python's json module, a parser independent of ours.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
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

}  // namespace

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
    test::forge_page(f, "coarse/vertices", 0, [&](std::vector<std::uint8_t>& page) {
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
