// Bad Exodus inputs: each must give a dicer::Error of the right kind whose
// message starts with the path and names what is wrong. Fixtures are written
// with the Exodus library itself, or made by corrupting real files.
#include <exodusII.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <netcdf.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "exodus_fixture.hpp"
#include "test_support.hpp"

namespace {

using dicer::ErrorKind;
using dicer::test::data_path;
using dicer::test::TempDir;
using namespace dicer::test;  // Exodus fixtures

// Reads the file, expecting an Error of `kind` whose message starts with the
// path and contains every one of `parts`. Returns the message.
std::string expect_error(const std::string& path, ErrorKind kind, std::initializer_list<std::string> parts) {
  try {
    dicer::read_exodus(path);
  } catch (const dicer::Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(static_cast<int>(e.kind()), static_cast<int>(kind)) << msg;
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    for (const std::string& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "missing '" << p << "' in: " << msg;
    return msg;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected dicer::Error, got std::exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected an error reading " << path;
  return {};
}

TEST(BadExodus, MissingFileIsIo) {
  TempDir tmp;
  const std::string path = tmp.path("does_not_exist.e");
  expect_error(path, ErrorKind::Io, {"No such file"});
}

TEST(BadExodus, DirectoryIsIo) {
  TempDir tmp;
  expect_error(tmp.dir().string(), ErrorKind::Io, {"directory"});
}

TEST(BadExodus, TextGarbageIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("garbage.e");
  dicer::test::write_file(path, "this is not a mesh\n$MeshFormat? no.\n" + std::string(500, 'x'));
  expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file"});
}

TEST(BadExodus, EmptyFileIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("empty.e");
  dicer::test::write_file(path, "");
  expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file", "empty"});
}

TEST(BadExodus, NetcdfButNotExodusIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("plain.nc");
  int ncid = -1, dim = -1, var = -1;
  ASSERT_EQ(nc_create(path.c_str(), NC_CLOBBER, &ncid), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "n", 4, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_var(ncid, "values", NC_DOUBLE, 1, &dim, &var), NC_NOERR);
  ASSERT_EQ(nc_enddef(ncid), NC_NOERR);
  const double values[4] = {1, 2, 3, 4};
  ASSERT_EQ(nc_put_var_double(ncid, var, values), NC_NOERR);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
  expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file"});
}

TEST(BadExodus, TruncatedRealFileIsBadInput) {
  TempDir tmp;
  for (const char* name : {"cardinal_pincell.e", "vtkdata_disk_out_ref.ex2", "vtkdata_mug.e"}) {
    const std::string bytes = dicer::test::read_file(data_path(name));
    ASSERT_GT(bytes.size(), 1000u) << name;
    const std::string path = tmp.path(std::string("half_") + name);
    dicer::test::write_file(path, bytes.substr(0, bytes.size() / 2));
    expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file", "truncated"});
  }
}

TEST(BadExodus, HeaderOnlyCutIsBadInput) {
  TempDir tmp;
  const std::string bytes = dicer::test::read_file(data_path("cardinal_sphere.e"));
  const std::string path = tmp.path("cut.e");
  dicer::test::write_file(path, bytes.substr(0, 100));
  expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file"});
}

// Patches the length of a netCDF-3 dimension in the header of `bytes`.
void patch_dimension(std::string& bytes, const std::string& name, std::uint32_t value) {
  // Header entry: 4-byte name length, name padded to 4 bytes, 4-byte length.
  std::string key(4, '\0');
  key[3] = static_cast<char>(name.size());
  key += name;
  const std::size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos) << name;
  const std::size_t len_at = at + 4 + (name.size() + 3) / 4 * 4;
  for (int i = 0; i < 4; ++i) bytes[len_at + i] = static_cast<char>((value >> (8 * (3 - i))) & 0xff);
}

// A netCDF header with the Exodus attributes and dimensions but no data: a
// hostile file claiming 10^12 nodes in about 1 kB. CDF5 allows 64-bit
// dimensions; with no variables using them, netCDF itself sees nothing wrong.
void write_hostile_header(const std::string& path, long long num_nodes, long long num_elem) {
  int ncid = -1, dim = -1;
  ASSERT_EQ(nc_create(path.c_str(), NC_CLOBBER | NC_64BIT_DATA, &ncid), NC_NOERR);
  const float version = 6.02f;
  const int word_size = 8, one = 1;
  const std::string title = "hostile";
  ASSERT_EQ(nc_put_att_text(ncid, NC_GLOBAL, "title", title.size(), title.c_str()), NC_NOERR);
  ASSERT_EQ(nc_put_att_float(ncid, NC_GLOBAL, "api_version", NC_FLOAT, 1, &version), NC_NOERR);
  ASSERT_EQ(nc_put_att_float(ncid, NC_GLOBAL, "version", NC_FLOAT, 1, &version), NC_NOERR);
  ASSERT_EQ(nc_put_att_int(ncid, NC_GLOBAL, "floating_point_word_size", NC_INT, 1, &word_size), NC_NOERR);
  ASSERT_EQ(nc_put_att_int(ncid, NC_GLOBAL, "file_size", NC_INT, 1, &one), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "len_string", 33, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "len_name", 33, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "len_line", 81, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "four", 4, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "time_step", NC_UNLIMITED, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "num_dim", 3, &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "num_nodes", static_cast<size_t>(num_nodes), &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "num_elem", static_cast<size_t>(num_elem), &dim), NC_NOERR);
  ASSERT_EQ(nc_def_dim(ncid, "num_el_blk", 1, &dim), NC_NOERR);
  ASSERT_EQ(nc_close(ncid), NC_NOERR);
}

TEST(BadExodus, HostileNodeCountIsBadInputNotBadAlloc) {
  TempDir tmp;
  const std::string path = tmp.path("hostile_nodes.e");
  write_hostile_header(path, 1000000000000LL, 1);
  ASSERT_LT(dicer::test::read_file(path).size(), 4096u);
  expect_error(path, ErrorKind::BadInput, {"header claims 1000000000000 nodes", "bytes"});
}

TEST(BadExodus, HostileElementCountIsBadInputNotBadAlloc) {
  TempDir tmp;
  const std::string path = tmp.path("hostile_elems.e");
  write_hostile_header(path, 8, 1000000000000LL);
  expect_error(path, ErrorKind::BadInput, {"header claims 1000000000000 elements"});
}

// A real header whose node dimension was patched: netCDF's own consistency
// checks or ours must refuse it, as BadInput.
TEST(BadExodus, PatchedDimensionsAreBadInput) {
  TempDir tmp;
  const std::string good = tmp.path("good.e");
  Fixture f = two_hexes();
  f.side_sets.push_back({1, {1, 2}, {1, 2}});
  write_exodus(good, f);
  const std::string bytes = dicer::test::read_file(good);
  for (const char* dim : {"num_nodes", "num_elem", "num_el_in_blk1", "num_side_ss1"}) {
    std::string patched = bytes;
    patch_dimension(patched, dim, 0x08000000u);
    const std::string path = tmp.path(std::string("patched_") + dim + ".e");
    dicer::test::write_file(path, patched);
    expect_error(path, ErrorKind::BadInput, {});
  }
}

TEST(BadExodus, TruncatedNetcdf4FileIsBadInput) {
  TempDir tmp;
  const std::string good = tmp.path("hdf5.e");
  Fixture f = two_hexes();
  f.create_mode = EX_CLOBBER | EX_NETCDF4;
  write_exodus(good, f);
  const std::string bytes = dicer::test::read_file(good);
  const std::string path = tmp.path("half_hdf5.e");
  dicer::test::write_file(path, bytes.substr(0, bytes.size() / 2));
  expect_error(path, ErrorKind::BadInput, {"not a readable Exodus II file"});
}

// A crash inside the netCDF-4/HDF5 libraries is the isolated reader's, not
// dicer's: squeezing the reader's address space (DICER_READER_MEMORY_MB)
// makes HDF5 fail an allocation it does not check and die of SIGSEGV; the
// command still ends with exit 3 and one line naming the file.
TEST(BadExodus, ALibraryCrashOnANetcdf4FileIsExit3) {
#if defined(DICER_SANITIZER_BUILD)
  GTEST_SKIP() << "no address-space limit under a sanitizer's shadow memory";
#endif
  TempDir tmp;
  const std::string path = tmp.path("hdf5.e");
  Fixture f = two_hexes();
  f.create_mode = EX_CLOBBER | EX_NETCDF4;
  write_exodus(path, f);
  const auto ok = dicer::test::run_process({DICER_CLI, "sheets", path});
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  const auto r = dicer::test::run_process({DICER_CLI, "sheets", path}, {{"DICER_READER_MEMORY_MB", "1"}});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find(path + ": not a readable Exodus II file"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("isolated reader"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
}

TEST(BadExodus, TetraBlockIsUnsupported) {
  TempDir tmp;
  const std::string path = tmp.path("tets.e");
  Fixture f = two_hexes();
  FixtureBlock tets;
  tets.id = 2;
  tets.type = "TETRA4";
  tets.nodes_per_element = 4;
  tets.conn = {1, 2, 4, 7, 2, 5, 4, 8, 2, 3, 5, 9};
  f.blocks.push_back(tets);
  write_exodus(path, f);
  expect_error(path, ErrorKind::Unsupported, {"unsupported elements", "3 TETRA4 (block 2)", "HEX8"});
}

TEST(BadExodus, ThirdOrderHexBlockIsUnsupported) {
  // HEX20 and HEX27 are read (tests/geometry/test_second_order.cpp); a
  // 64-node hex is not.
  TempDir tmp;
  const std::string path = tmp.path("hex64.e");
  Fixture f = two_hexes();
  f.blocks[0].id = 5;
  f.blocks[0].type = "HEX";
  f.blocks[0].nodes_per_element = 64;
  std::vector<std::int64_t> conn;
  for (int i = 0; i < 64; ++i) conn.push_back(1 + i % 12);
  f.blocks[0].conn = conn;  // one element with 64 nodes
  write_exodus(path, f);
  expect_error(path, ErrorKind::Unsupported, {"1 HEX with 64 nodes per element (block 5)"});
}

TEST(BadExodus, NodeCountThatContradictsTheTypeIsUnsupported) {
  TempDir tmp;
  const std::string path = tmp.path("hex20_of_8.e");
  Fixture f = two_hexes();
  f.blocks[0].id = 6;
  f.blocks[0].type = "HEX20";  // but 8 nodes per element
  write_exodus(path, f);
  expect_error(path, ErrorKind::Unsupported, {"2 HEX20 with 8 nodes per element (block 6)"});
}

TEST(BadExodus, ConnectivityOutOfRangeIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("conn.e");
  Fixture f = two_hexes();
  f.blocks[0].id = 76;
  f.blocks[0].conn[13] = 99999;  // element 2, corner 6
  f.elem_map = {1233, 1234};
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput,
               {"element block 76: element 1234 references node 99999 (file has 12 nodes)"});
}

TEST(BadExodus, ConnectivityZeroIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("conn0.e");
  Fixture f = two_hexes();
  f.blocks[0].conn[0] = 0;
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"element block 1: element 1 references node 0"});
}

TEST(BadExodus, TwoDimensionalHexMeshIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("hex2d.e");
  Fixture f = two_hexes();
  f.num_dim = 2;
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"3 coordinate dimensions", "has 2"});
}

TEST(BadExodus, SideNumberNineIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("side9.e");
  Fixture f = two_hexes();
  f.elem_map = {41, 42};
  f.side_sets.push_back({5, {1, 2}, {3, 9}});
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"side set 5: element 42 has side 9"});
}

TEST(BadExodus, SideSetElementOutOfRangeIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("sideelem.e");
  Fixture f = two_hexes();
  f.side_sets.push_back({3, {1, 7}, {1, 2}});
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"side set 3", "element 7", "file has 2 elements"});
}

TEST(BadExodus, NodeSetOutOfRangeIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("nodeset.e");
  Fixture f = two_hexes();
  f.node_sets.push_back({4, {1, 2, 13}});
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"node set 4", "node 13", "file has 12 nodes"});
}

TEST(BadExodus, NanCoordinateIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("nan.e");
  Fixture f = two_hexes();
  for (std::int64_t i = 0; i < 12; ++i) f.node_map.push_back(1000 + i);
  f.y[6] = std::numeric_limits<double>::quiet_NaN();
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"node 1006", "not finite"});
}

TEST(BadExodus, InfiniteCoordinateIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("inf.e");
  Fixture f = two_hexes();
  f.z[11] = -std::numeric_limits<double>::infinity();
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"node 12", "not finite"});
}

// Exodus creates files in netCDF no-fill mode: coordinates never written
// read back as zeros.
TEST(BadExodus, NoCoordinatesWrittenIsBadInput) {
  TempDir tmp;
  const std::string path = tmp.path("nocoords.e");
  Fixture f = two_hexes();
  f.write_coords = false;
  write_exodus(path, f);
  expect_error(path, ErrorKind::BadInput, {"all 12 nodes are at the origin"});
}

}  // namespace

// Same dimension as the mesh but not diceable: refused, whatever else is there.
TEST(BadExodus, TrianglesInAQuadMeshAreUnsupported) {
  TempDir tmp;
  const std::string path = tmp.path("quad_tri.e");
  Fixture f = two_quads();
  f.blocks[0].conn.resize(4);  // the first quad; triangles fill the second
  f.blocks.push_back(block_of(2, "TRI3", 3, {2, 3, 6, 2, 6, 5}));
  f.blocks.push_back(block_of(4, "BAR2", 2, {1, 2}));
  write_exodus(path, f);
  const std::string msg = expect_error(path, ErrorKind::Unsupported, {"2 TRI3 (block 2)", "QUAD4"});
  EXPECT_EQ(msg.find("BAR2"), std::string::npos) << "beams are skipped, not refused: " << msg;
}

TEST(BadExodus, UnknownElementTypeIsUnsupported) {
  TempDir tmp;
  const std::string path = tmp.path("unknown.e");
  Fixture f = two_hexes();
  f.blocks.push_back(block_of(4, "SUPERELEMENT", 2, {1, 2}));
  write_exodus(path, f);
  expect_error(path, ErrorKind::Unsupported, {"1 SUPERELEMENT (block 4)"});
}

TEST(BadExodus, OnlyBeamsIsUnsupported) {
  TempDir tmp;
  const std::string path = tmp.path("beams.e");
  Fixture f = two_hexes();
  f.blocks[0].type = "BEAM2", f.blocks[0].nodes_per_element = 2;
  f.blocks[0].conn = {1, 2, 2, 3};
  write_exodus(path, f);
  expect_error(path, ErrorKind::Unsupported, {"no hexahedra or quadrilaterals", "dimension 1"});
}

// ---------------------------------------------------------------------------
// Files whose variables and attributes lie about their size. The Exodus
// 6.02 getters read whole variables into buffers sized from the header's
// dimensions (and into their own, in ex_id_lkup), so each of these wrote far
// past a buffer before the reader checked shapes: the reads run in a child
// process, where a crash fails the test instead of ending the suite.

// What reading `path` with read_exodus did in a child process.
struct ChildRead {
  bool normal_exit = false;  // the child returned, with or without an Error
  std::string outcome;       // "error <kind>: <message>", "no error", "other exception", or the signal
};

ChildRead read_in_child(const std::string& path) {
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    ::close(fds[0]);
    ::alarm(60);  // a read that hangs fails the test too
    std::string out = "no error";
    try {
      dicer::read_exodus(path);
    } catch (const dicer::Error& e) {
      out = "error " + std::to_string(static_cast<int>(e.kind())) + ": " + e.what();
    } catch (...) {
      out = "other exception";
    }
    const ssize_t ignored = ::write(fds[1], out.data(), out.size());
    (void)ignored;
    ::_exit(0);
  }
  ::close(fds[1]);
  ChildRead r;
  char buf[4096];
  ssize_t n;
  while ((n = ::read(fds[0], buf, sizeof buf)) > 0) r.outcome.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  r.normal_exit = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (WIFSIGNALED(status)) r.outcome = "killed by signal " + std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) + ")";
  return r;
}

// The child refused the file with BadInput, naming the file and every part.
void expect_refused_in_child(const std::string& path, std::initializer_list<std::string> parts) {
  const ChildRead r = read_in_child(path);
  ASSERT_TRUE(r.normal_exit) << r.outcome;
  const std::string prefix = "error " + std::to_string(static_cast<int>(ErrorKind::BadInput)) + ": " + path + ": ";
  EXPECT_EQ(r.outcome.rfind(prefix, 0), 0u) << r.outcome;
  for (const std::string& p : parts) EXPECT_NE(r.outcome.find(p), std::string::npos) << "missing '" << p << "' in: " << r.outcome;
  EXPECT_EQ(r.outcome.find('\n'), std::string::npos) << "one line: " << r.outcome;
}

void nc_check(int rc, const char* what) {
  if (rc != NC_NOERR) throw std::runtime_error(std::string("fixture: ") + what + ": " + nc_strerror(rc));
}

// Replaces variable `name` by one whose first dimension is a new one of
// `length`; other dimensions and attributes as they were; NC_BYTE values 1.
// The header's own dimensions (num_nodes, num_el_in_blk1, ...) still say
// the old size.
void lengthen_variable(const std::string& path, const std::string& name, std::size_t length) {
  int ncid = -1, old = -1, rank = 0, natts = 0;
  nc_check(nc_open(path.c_str(), NC_WRITE, &ncid), "nc_open");
  nc_check(nc_redef(ncid), "nc_redef");
  nc_check(nc_inq_varid(ncid, name.c_str(), &old), name.c_str());
  nc_check(nc_inq_varndims(ncid, old, &rank), "nc_inq_varndims");
  std::vector<int> dims(static_cast<std::size_t>(rank));
  nc_check(nc_inq_vardimid(ncid, old, dims.data()), "nc_inq_vardimid");
  nc_check(nc_rename_var(ncid, old, (name + "_as_written").c_str()), "nc_rename_var");
  nc_check(nc_def_dim(ncid, ("lie_" + name).c_str(), length, &dims[0]), "nc_def_dim");
  int var = -1;
  nc_check(nc_def_var(ncid, name.c_str(), NC_BYTE, rank, dims.data(), &var), "nc_def_var");
  nc_check(nc_inq_varnatts(ncid, old, &natts), "nc_inq_varnatts");
  for (int a = 0; a < natts; ++a) {
    char att[NC_MAX_NAME + 1] = {};
    nc_check(nc_inq_attname(ncid, old, a, att), "nc_inq_attname");
    nc_check(nc_copy_att(ncid, old, att, ncid, var), "nc_copy_att");
  }
  nc_check(nc_enddef(ncid), "nc_enddef");
  std::size_t total = 1;
  for (int d : dims) {
    std::size_t len = 0;
    nc_check(nc_inq_dimlen(ncid, d, &len), "nc_inq_dimlen");
    total *= len;
  }
  const std::vector<signed char> ones(total, 1);
  nc_check(nc_put_var_schar(ncid, var, ones.data()), "nc_put_var_schar");
  nc_check(nc_close(ncid), "nc_close");
}

Fixture two_hexes_with_sets() {
  Fixture f = two_hexes();
  f.side_sets.push_back({4, {1, 2}, {5, 5}});
  f.node_sets.push_back({6, {1, 2, 3}});
  return f;
}

TEST(BadExodus, VariablesLongerThanTheirDimensionsAreRefusedBeforeAnyRead) {
  TempDir tmp;
  struct Lie {
    const char* var;
    std::size_t length;
    const char* says;
  };
  // Lengths large enough that writing them into the buffers the header sizes
  // runs off the heap.
  const Lie lies[] = {
      {"connect1", 200000, "has shape 200000 x 8 but the dimensions the reader sizes it from give 2 x 8"},
      {"coordx", 1000000, "has shape 1000000 but the dimensions the reader sizes it from give 12"},
      {"node_num_map", 1000000, "give 12"},
      {"elem_num_map", 1000000, "give 2"},
      {"eb_prop1", 1000000, "give 1"},
      {"eb_status", 1000000, "give 1"},
      {"ss_prop1", 1000000, "give 1"},
      {"ss_status", 1000000, "give 1"},
      {"elem_ss1", 1000000, "give 2"},
      {"side_ss1", 1000000, "give 2"},
      {"ns_prop1", 1000000, "give 1"},
      {"node_ns1", 1000000, "give 3"},
  };
  Fixture f = two_hexes_with_sets();
  f.node_map = {11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22};
  f.elem_map = {7, 8};
  for (const Lie& lie : lies) {
    SCOPED_TRACE(lie.var);
    const std::string path = tmp.path(std::string("long_") + lie.var + ".e");
    write_exodus(path, f);
    lengthen_variable(path, lie.var, lie.length);
    expect_refused_in_child(path, {std::string("variable '") + lie.var + "'", lie.says});
  }
}

// The Exodus library copies elem_type into a 33-byte buffer on its stack.
TEST(BadExodus, ElementTypeLongerThanExodusAllowsIsRefused) {
  TempDir tmp;
  for (const std::size_t length : {std::size_t{500}, std::size_t{33}}) {
    SCOPED_TRACE(length);
    const std::string path = tmp.path("long_type_" + std::to_string(length) + ".e");
    write_exodus(path, two_hexes());
    int ncid = -1, var = -1;
    nc_check(nc_open(path.c_str(), NC_WRITE, &ncid), "nc_open");
    nc_check(nc_redef(ncid), "nc_redef");
    nc_check(nc_inq_varid(ncid, "connect1", &var), "connect1");
    const std::string type = "HEX8" + std::string(length - 4, 'X');  // no terminating NUL
    nc_check(nc_put_att_text(ncid, var, "elem_type", type.size(), type.data()), "elem_type");
    nc_check(nc_close(ncid), "nc_close");
    expect_refused_in_child(path, {"variable 'connect1'", "elem_type attribute is " + std::to_string(length) + " characters"});
  }
}

// ex_open reads version and word size into one float / int of its caller's.
TEST(BadExodus, GlobalAttributeWithManyValuesIsRefused) {
  TempDir tmp;
  for (const char* att : {"version", "floating_point_word_size", "maximum_name_length"}) {
    SCOPED_TRACE(att);
    const std::string path = tmp.path(std::string("many_") + att + ".e");
    write_exodus(path, two_hexes());
    int ncid = -1;
    nc_check(nc_open(path.c_str(), NC_WRITE, &ncid), "nc_open");
    nc_check(nc_redef(ncid), "nc_redef");
    const std::vector<int> values(100000, 8);
    nc_check(nc_put_att_int(ncid, NC_GLOBAL, att, NC_INT, values.size(), values.data()), att);
    nc_check(nc_close(ncid), "nc_close");
    expect_refused_in_child(path, {std::string("attribute '") + att + "' has 100000 values"});
  }
}

// Byte-level lies in the netCDF header itself, which netCDF trusts: a name
// length or an attribute length of 2^31 made nc_open allocate gigabytes
// (out of memory, or tens of seconds).
std::uint32_t be32(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v = v << 8 | static_cast<unsigned char>(b[at + k]);
  return v;
}
void put_be32(std::string& b, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) b[at + k] = static_cast<char>(v >> (8 * (3 - k)));
}

TEST(BadExodus, LyingNetcdfHeaderBytesAreRefusedBeforeNetcdfOpensThem) {
  TempDir tmp;
  const std::string good = tmp.path("good.e");
  write_exodus(good, two_hexes_with_sets());
  const std::string bytes = dicer::test::read_file(good);
  ASSERT_EQ(bytes.compare(0, 3, "CDF"), 0);
  ASSERT_NE(bytes[3], 5) << "the offsets below are those of CDF-1 and CDF-2";
  // magic, numrecs, then the dimension list: tag, count, first name's length.
  ASSERT_EQ(be32(bytes, 8), 10u) << "dimension list tag";
  struct Patch {
    const char* name;
    std::size_t at;
    std::uint32_t value;
    const char* says;
  };
  // An attribute's length sits after its name and type: find "api_version".
  const std::string key = std::string("\0\0\0\x0b", 4) + "api_version";
  const std::size_t api = bytes.find(key);
  ASSERT_NE(api, std::string::npos);
  const std::size_t api_length = api + 4 + 12 + 4;  // name length, padded name, type
  ASSERT_EQ(be32(bytes, api_length), 1u);
  const Patch patches[] = {
      {"name_length", 16, 0x7ffffff0u, "the name of dimension 0 is 2147483632 characters long"},
      {"dimension_count", 12, 0x7fffffffu, "claims 2147483647 dimensions"},
      {"attribute_length", api_length, 0x7fffffffu, "global attribute 'api_version' claims 2147483647 values"},
      {"negative_count", 12, 0x80000001u, "the number of dimensions is 2147483649 (negative)"},
  };
  for (const Patch& p : patches) {
    SCOPED_TRACE(p.name);
    std::string b = bytes;
    put_be32(b, p.at, p.value);
    const std::string path = tmp.path(std::string("patched_") + p.name + ".e");
    dicer::test::write_file(path, b);
    expect_refused_in_child(path, {"not a readable Exodus II file (netCDF header: ", p.says});
  }
}

// A count of sets that only a dimension states (no set of them exists): the
// audit would otherwise look for thousands of variables.
TEST(BadExodus, MoreSetsThanTheFileHasDimensionsIsRefused) {
  TempDir tmp;
  const std::string path = tmp.path("phantom_sets.e");
  write_exodus(path, two_hexes());
  int ncid = -1, dim = -1, filler_dim = -1, filler = -1;
  nc_check(nc_open(path.c_str(), NC_WRITE, &ncid), "nc_open");
  nc_check(nc_redef(ncid), "nc_redef");
  nc_check(nc_def_dim(ncid, "num_side_sets", 5000, &dim), "num_side_sets");
  nc_check(nc_def_dim(ncid, "filler", 200000, &filler_dim), "filler dim");  // room for the count check
  nc_check(nc_def_var(ncid, "filler", NC_BYTE, 1, &filler_dim, &filler), "filler");
  nc_check(nc_enddef(ncid), "nc_enddef");
  const std::vector<signed char> zeros(200000, 0);
  nc_check(nc_put_var_schar(ncid, filler, zeros.data()), "filler data");
  nc_check(nc_close(ncid), "nc_close");
  expect_refused_in_child(path, {"claims 1 element blocks, 5000 side sets and 0 node sets but defines only"});
}

// A 2 x 1 x 1 box of hexes written with netCDF alone, its coordinates as
// `coord` (one array, the library's layout when the global attribute
// file_size is 0) and/or coordx/y/z (file_size 1), `coord` first when
// `coord_first` (netCDF variable id 0, the one the Exodus library skips).
// `coord` holds `coord_scale` x the true coordinates.
void write_box_with_coords(const std::string& path, int file_size, bool with_coord, bool with_axes,
                           double coord_scale) {
  const double x[12] = {0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}, y[12] = {0, 0, 0, 1, 1, 1, 0, 0, 0, 1, 1, 1},
               z[12] = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1};
  const int connect[16] = {1, 2, 5, 4, 7, 8, 11, 10, 2, 3, 6, 5, 8, 9, 12, 11};
  int ncid = -1, d_dim = -1, d_nodes = -1, d_blk = -1, d_el = -1, d_per = -1, d = -1, v_coord = -1, v_ax[3] = {};
  int v_status = -1, v_prop = -1, v_conn = -1;
  nc_check(nc_create(path.c_str(), NC_CLOBBER | NC_64BIT_OFFSET, &ncid), "nc_create");
  if (with_coord) {  // first: variable id 0
    nc_check(nc_def_dim(ncid, "num_dim", 3, &d_dim), "dim");
    nc_check(nc_def_dim(ncid, "num_nodes", 12, &d_nodes), "dim");
    const int dims[2] = {d_dim, d_nodes};
    nc_check(nc_def_var(ncid, "coord", NC_DOUBLE, 2, dims, &v_coord), "coord");
  } else {
    nc_check(nc_def_dim(ncid, "num_dim", 3, &d_dim), "dim");
    nc_check(nc_def_dim(ncid, "num_nodes", 12, &d_nodes), "dim");
  }
  const float version = 8.0f;
  const int word = 8;
  nc_check(nc_put_att_float(ncid, NC_GLOBAL, "api_version", NC_FLOAT, 1, &version), "att");
  nc_check(nc_put_att_float(ncid, NC_GLOBAL, "version", NC_FLOAT, 1, &version), "att");
  nc_check(nc_put_att_int(ncid, NC_GLOBAL, "floating_point_word_size", NC_INT, 1, &word), "att");
  nc_check(nc_put_att_int(ncid, NC_GLOBAL, "file_size", NC_INT, 1, &file_size), "att");
  nc_check(nc_put_att_text(ncid, NC_GLOBAL, "title", 3, "box"), "att");
  for (const auto& [name, len] : {std::pair{"len_string", 33}, {"len_name", 33}, {"len_line", 81}, {"four", 4}})
    nc_check(nc_def_dim(ncid, name, static_cast<size_t>(len), &d), name);
  nc_check(nc_def_dim(ncid, "time_step", NC_UNLIMITED, &d), "time_step");
  nc_check(nc_def_dim(ncid, "num_elem", 2, &d), "num_elem");
  nc_check(nc_def_dim(ncid, "num_el_blk", 1, &d_blk), "num_el_blk");
  nc_check(nc_def_dim(ncid, "num_el_in_blk1", 2, &d_el), "num_el_in_blk1");
  nc_check(nc_def_dim(ncid, "num_nod_per_el1", 8, &d_per), "num_nod_per_el1");
  if (with_axes)
    for (int a = 0; a < 3; ++a)
      nc_check(nc_def_var(ncid, (std::string("coord") + "xyz"[a]).c_str(), NC_DOUBLE, 1, &d_nodes, &v_ax[a]), "axis");
  nc_check(nc_def_var(ncid, "eb_status", NC_INT, 1, &d_blk, &v_status), "eb_status");
  nc_check(nc_def_var(ncid, "eb_prop1", NC_INT, 1, &d_blk, &v_prop), "eb_prop1");
  nc_check(nc_put_att_text(ncid, v_prop, "name", 2, "ID"), "ID");
  const int cdims[2] = {d_el, d_per};
  nc_check(nc_def_var(ncid, "connect1", NC_INT, 2, cdims, &v_conn), "connect1");
  nc_check(nc_put_att_text(ncid, v_conn, "elem_type", 4, "HEX8"), "elem_type");
  nc_check(nc_enddef(ncid), "enddef");
  if (with_coord) {
    double all[36];
    for (int i = 0; i < 12; ++i) all[i] = coord_scale * x[i], all[12 + i] = coord_scale * y[i], all[24 + i] = coord_scale * z[i];
    nc_check(nc_put_var_double(ncid, v_coord, all), "coord data");
  }
  if (with_axes)
    for (int a = 0; a < 3; ++a) nc_check(nc_put_var_double(ncid, v_ax[a], a == 0 ? x : a == 1 ? y : z), "axis data");
  const int one = 1;
  nc_check(nc_put_var_int(ncid, v_status, &one), "eb_status data");
  nc_check(nc_put_var_int(ncid, v_prop, &one), "eb_prop1 data");
  nc_check(nc_put_var_int(ncid, v_conn, connect), "connect1 data");
  nc_check(nc_close(ncid), "nc_close");
}

// The coordinates are those of the layout the Exodus library reads: a
// stray `coord` (variable id 0) beside coordx/y/z in a file_size 1 file was
// put over the true coordinates (exit 0, a mesh 10 times too big), while a
// `coord` of id 0 that is the file's one layout must still be read.
TEST(BadExodus, CoordinatesComeFromTheLayoutTheFileDeclares) {
  TempDir tmp;
  struct Case {
    const char* name;
    int file_size;
    bool coord, axes;
  };
  for (const Case c : {Case{"both_large.e", 1, true, true}, Case{"coord_only.e", 0, true, false},
                       Case{"axes_only.e", 1, false, true}}) {
    const std::string path = tmp.path(c.name);
    ASSERT_NO_THROW(write_box_with_coords(path, c.file_size, c.coord, c.axes, c.axes ? 10.0 : 1.0)) << c.name;
    const dicer::CoarseMesh m = dicer::read_exodus(path);
    ASSERT_EQ(m.x.size(), 12u) << c.name;
    EXPECT_EQ(*std::max_element(m.x.begin(), m.x.end()), 2.0) << c.name;
    EXPECT_EQ(*std::max_element(m.y.begin(), m.y.end()), 1.0) << c.name;
    EXPECT_EQ(*std::max_element(m.z.begin(), m.z.end()), 1.0) << c.name;
  }
}

// Two element blocks of one id: the library finds blocks by id, so the
// first was read twice and the error spoke of duplicated elements.
TEST(BadExodus, TwoElementBlocksOfOneIdAreNamed) {
  TempDir tmp;
  const std::string path = tmp.path("dup_block.e");
  Fixture f = two_hexes();
  FixtureBlock second = f.blocks[0];
  f.blocks[0].conn.resize(8), second.conn.erase(second.conn.begin(), second.conn.begin() + 8);
  f.blocks[0].id = 5, second.id = 6;
  f.blocks.push_back(second);
  write_exodus(path, f);
  int ncid = -1, var = -1;
  nc_check(nc_open(path.c_str(), NC_WRITE, &ncid), "nc_open");
  nc_check(nc_inq_varid(ncid, "eb_prop1", &var), "eb_prop1");
  const int ids[2] = {5, 5};
  nc_check(nc_put_var_int(ncid, var, ids), "eb_prop1 data");
  nc_check(nc_close(ncid), "nc_close");
  expect_error(path, ErrorKind::BadInput, {"two element blocks have id 5"});
}
