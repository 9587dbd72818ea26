// Hostile stores: metadata that lies (attributes of the wrong shape or
// class, companions of another type, sizes the file does not hold), links
// and storage that point outside the file, and store identity (uuid). Each
// fixture is a real store edited with the HDF5 API; each is read by the
// real binary (under `timeout` where the old code blocked, under an
// address-space limit where it allocated gigabytes).
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/store.hpp"
#include "lz4_filter.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;

namespace {

// A copy of the sphere's store edited through the HDF5 API.
std::string edited(const test::TempDir& d, const std::function<void(hid_t)>& edit) {
  return test::edited_copy(test::diced_store("cardinal_sphere.e", 2), d.path("bad.dice.h5"), edit);
}

void replace_attr(hid_t f, const char* name, hid_t type, hid_t space, const void* data) {
  H5Adelete(f, name);
  const hid_t a = H5Acreate2(f, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(a, 0);
  ASSERT_GE(H5Awrite(a, type, data), 0);
  H5Aclose(a);
}

std::vector<std::uint32_t> read_u32(hid_t f, const std::string& name) {
  const hid_t ds = H5Dopen2(f, name.c_str(), H5P_DEFAULT), sp = H5Dget_space(ds);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(sp, &n, nullptr);
  std::vector<std::uint32_t> v(n);
  if (n) H5Dread(ds, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Sclose(sp), H5Dclose(ds);
  return v;
}

// Replaces dataset `name` by one made by `make(file, name)`.
void replace_dataset(hid_t f, const std::string& name, const std::function<void(hid_t, const char*)>& make) {
  ASSERT_GE(H5Ldelete(f, name.c_str(), H5P_DEFAULT), 0) << name;
  make(f, name.c_str());
}

// Runs `dicer args...` with a wall-clock limit (the old code blocked on a
// FIFO for ever: killed, 128 + 9) and, when given, an address-space limit
// (not in sanitizer builds, whose shadow memory no such limit admits; the
// Release suite applies it).
test::CliResult run_limited(const std::vector<std::string>& args, std::uint64_t address_space = 0) {
#ifdef DICER_SANITIZER_BUILD
  address_space = 0;
#endif
  std::vector<std::string> argv{"/usr/bin/timeout", "-s", "KILL", "60"};
  if (address_space) argv.insert(argv.end(), {"/usr/bin/prlimit", "--as=" + std::to_string(address_space), "--"});
  argv.push_back(DICER_CLI);
  argv.insert(argv.end(), args.begin(), args.end());
  return test::run_process(argv);
}

// One line on stderr, containing every `says`.
void expect_one_line(const test::CliResult& r, const std::vector<std::string>& says) {
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  for (const auto& s : says) EXPECT_NE(r.err.find(s), std::string::npos) << "expected \"" << s << "\" in: " << r.err;
}

}  // namespace

// H5Aread writes every value of the attribute into the buffer: one int64
// for format_version (an array of 1000 smashed the stack), one string for
// format (1000 strings overflowed the heap).
TEST(HostileStore, AttributeHoldingManyValuesIsCorrupt) {
  test::TempDir d;
  {
    const std::string p = edited(d, [](hid_t f) {
      const hsize_t n = 1000;
      std::vector<std::int64_t> v(n, 6);
      const hid_t sp = H5Screate_simple(1, &n, nullptr);
      replace_attr(f, "format_version", H5T_NATIVE_INT64, sp, v.data());
      H5Sclose(sp);
    });
    const auto r = run_limited({"info", p});
    EXPECT_EQ(r.exit_code, 8) << r.err;
    expect_one_line(r, {p, "attribute format_version", "exactly one value"});
  }
  {
    const std::string p = edited(d, [](hid_t f) {
      const hsize_t n = 1000;
      std::vector<char> v(n * 16, 'x');
      const hid_t sp = H5Screate_simple(1, &n, nullptr), t = H5Tcopy(H5T_C_S1);
      H5Tset_size(t, 16);
      replace_attr(f, "format", t, sp, v.data());
      H5Tclose(t), H5Sclose(sp);
    });
    const auto r = run_limited({"info", p});
    EXPECT_EQ(r.exit_code, 8) << r.err;
    expect_one_line(r, {p, "attribute format", "exactly one value"});
  }
}

TEST(HostileStore, AttributeOfAnotherClassIsCorrupt) {
  test::TempDir d;
  const std::string p = edited(d, [](hid_t f) {
    const double v = 256.0;
    const hid_t sp = H5Screate(H5S_SCALAR);
    replace_attr(f, "coarse_elements", H5T_NATIVE_DOUBLE, sp, &v);
    H5Sclose(sp);
  });
  const auto r = run_limited({"info", p});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  expect_one_line(r, {p, "attribute coarse_elements", "not an integer"});
}

// HDF5 converts while it reads, into a buffer dicer sized for uint32.
TEST(HostileStore, CompanionOfAnotherTypeIsCorrupt) {
  test::TempDir d;
  const std::string p = edited(d, [](hid_t f) {
    const auto crc = read_u32(f, "topology/elements_crc");
    replace_dataset(f, "topology/elements_crc", [&](hid_t file, const char* name) {
      const hsize_t n = crc.size(), chunk = crc.size();
      const hid_t sp = H5Screate_simple(1, &n, nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 1, &chunk);
      store::add_page_filters(dcpl);
      const hid_t ds = H5Dcreate2(file, name, H5T_STD_U64LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
      ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, crc.data()), 0);
      H5Dclose(ds), H5Pclose(dcpl), H5Sclose(sp);
    });
  });
  const auto r = run_limited({"info", p});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  expect_one_line(r, {p, "topology/elements_crc", "element type"});
}

// A few kilobytes declaring a billion sheets: the extent is grown without
// writing a page (HDF5 allocates nothing), the attribute agrees. The old
// reader sized an 8 GB vector from it (under a 3 GiB address-space limit:
// bad_alloc, exit 70); now the missing pages are seen first.
TEST(HostileStore, DeclaredSizeTheFileDoesNotHoldIsCorrupt) {
  test::TempDir d;
  const hsize_t rows = 1000000000;
  const std::string p = edited(d, [&](hid_t f) {
    hsize_t chunk[2] = {0, 0};
    {
      const hid_t ds = H5Dopen2(f, "sheets/sheet_interval", H5P_DEFAULT), dcpl = H5Dget_create_plist(ds);
      H5Pget_chunk(dcpl, 2, chunk);
      hsize_t dims[2] = {rows, 1};
      EXPECT_GE(H5Dset_extent(ds, dims), 0);
      H5Pclose(dcpl), H5Dclose(ds);
    }
    // A companion with one (unwritten) entry per page, as the shape says.
    replace_dataset(f, "sheets/sheet_interval_crc", [&](hid_t file, const char* name) {
      const hsize_t pages = (rows + chunk[0] - 1) / chunk[0], cchunk = 16384;
      const hid_t sp = H5Screate_simple(1, &pages, nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 1, &cchunk);
      store::add_page_filters(dcpl);
      const hid_t ds = H5Dcreate2(file, name, H5T_STD_U32LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
      EXPECT_GE(ds, 0);
      H5Dclose(ds), H5Pclose(dcpl), H5Sclose(sp);
    });
    const std::int64_t v = static_cast<std::int64_t>(rows);
    const hid_t sp = H5Screate(H5S_SCALAR);
    replace_attr(f, "sheets", H5T_NATIVE_INT64, sp, &v);
    H5Sclose(sp);
  });
  EXPECT_LT(fs::file_size(p), 1u << 20);
  const auto r = run_limited({"info", p}, 3ull << 30);
  EXPECT_EQ(r.exit_code, 8) << r.err;
  expect_one_line(r, {p, "sheets/sheet_interval", "the file holds"});
}

// Rank 32 (HDF5's maximum): the old reader asked for the extent of
// coarse/block_id into a 2-value array.
TEST(HostileStore, DatasetOfHighRankIsCorrupt) {
  test::TempDir d;
  const std::string p = edited(d, [](hid_t f) {
    replace_dataset(f, "coarse/block_id", [](hid_t file, const char* name) {
      std::vector<hsize_t> dims(32, 1);
      const hid_t sp = H5Screate_simple(32, dims.data(), nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 32, dims.data());
      const hid_t ds = H5Dcreate2(file, name, H5T_STD_I64LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
      ASSERT_GE(ds, 0);
      H5Dclose(ds), H5Pclose(dcpl), H5Sclose(sp);
    });
  });
  const auto r = run_limited({"info", p});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  expect_one_line(r, {p, "coarse/block_id", "rank"});
}

namespace {

std::string make_fifo(const test::TempDir& d) {
  const std::string fifo = d.path("fifo");
  if (::mkfifo(fifo.c_str(), 0600) != 0) throw std::runtime_error("mkfifo failed");
  return fifo;
}

}  // namespace

// HDF5 follows soft and external links when a path is opened; an external
// link to a FIFO blocked every command in open(2). A store holds hard
// links only, checked before any path is opened.
TEST(HostileStore, LinksOutOfTheStoreAreRefused) {
  test::TempDir d;
  const std::string fifo = make_fifo(d);
  struct Link {
    const char* name;
    std::function<void(hid_t)> make;
    const char* says;
  };
  const std::vector<Link> cases = {
      {"external link replacing a dataset",
       [&](hid_t f) {
         H5Ldelete(f, "sheets/sheet_interval", H5P_DEFAULT);
         ASSERT_GE(H5Lcreate_external(fifo.c_str(), "/x", f, "sheets/sheet_interval", H5P_DEFAULT, H5P_DEFAULT), 0);
       },
       "external link"},
      {"external link beside the datasets",
       [&](hid_t f) { ASSERT_GE(H5Lcreate_external(fifo.c_str(), "/x", f, "sets/extra", H5P_DEFAULT, H5P_DEFAULT), 0); },
       "external link"},
      {"soft link aliasing another dataset",
       [&](hid_t f) {
         for (const char* n : {"coarse/block_id", "coarse/block_id_crc"}) H5Ldelete(f, n, H5P_DEFAULT);
         ASSERT_GE(H5Lcreate_soft("/coarse/block_coarse_elements", f, "coarse/block_id", H5P_DEFAULT, H5P_DEFAULT), 0);
         ASSERT_GE(H5Lcreate_soft("/coarse/block_coarse_elements_crc", f, "coarse/block_id_crc", H5P_DEFAULT, H5P_DEFAULT), 0);
       },
       "soft link"},
  };
  for (const Link& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string p = edited(d, c.make);
    for (const char* cmd : {"info", "verify"}) {
      const auto r = run_limited({cmd, p});
      EXPECT_EQ(r.exit_code, 8) << cmd << ": " << r.err;
      expect_one_line(r, {p, c.says});
    }
  }
}

// Data of a dataset kept in another file: external storage and virtual
// datasets. HDF5 opens those files when the data is read (the companions
// are read with H5Dread): a FIFO blocked.
TEST(HostileStore, DatasetsStoredOutsideTheFileAreRefused) {
  test::TempDir d;
  const std::string fifo = make_fifo(d);
  const std::vector<std::pair<const char*, std::function<void(hid_t, const char*, hsize_t)>>> cases = {
      {"external storage",
       [&](hid_t f, const char* name, hsize_t n) {
         const hid_t sp = H5Screate_simple(1, &n, nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
         ASSERT_GE(H5Pset_external(dcpl, fifo.c_str(), 0, H5F_UNLIMITED), 0);
         const hid_t ds = H5Dcreate2(f, name, H5T_STD_U32LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
         ASSERT_GE(ds, 0);
         H5Dclose(ds), H5Pclose(dcpl), H5Sclose(sp);
       }},
      {"virtual dataset",
       [&](hid_t f, const char* name, hsize_t n) {
         const hid_t sp = H5Screate_simple(1, &n, nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
         ASSERT_GE(H5Pset_virtual(dcpl, sp, fifo.c_str(), "/x", sp), 0);
         const hid_t ds = H5Dcreate2(f, name, H5T_STD_U32LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
         ASSERT_GE(ds, 0);
         H5Dclose(ds), H5Pclose(dcpl), H5Sclose(sp);
       }},
  };
  for (const auto& [what, make_case] : cases) {
    SCOPED_TRACE(what);
    const auto& make = make_case;  // Clang before 16 cannot capture a structured binding
    const std::string p = edited(d, [&](hid_t f) {
      const hsize_t n = read_u32(f, "sheets/sheet_interval_crc").size();
      replace_dataset(f, "sheets/sheet_interval_crc", [&](hid_t file, const char* name) { make(file, name, n); });
    });
    const auto r = run_limited({"info", p});
    EXPECT_EQ(r.exit_code, 8) << r.err;
    expect_one_line(r, {p, "sheets/sheet_interval_crc", "one file"});
  }
}

// HDF5 metadata without checksums (superblock 0, what HDF5 writes by
// default) is refused before HDF5 parses it.
TEST(HostileStore, MetadataWithoutChecksumsIsRefused) {
  test::TempDir d;
  const std::string p = d.path("old_layout.dice.h5");
  {
    const hid_t f = H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t sp = H5Screate(H5S_SCALAR), t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, 11);
    const hid_t a = H5Acreate2(f, "format", t, sp, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, t, "dicer-store");
    H5Aclose(a), H5Tclose(t), H5Sclose(sp), H5Fclose(f);
  }
  const auto r = run_limited({"info", p});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  expect_one_line(r, {p, "superblock version 0"});
}

// ---- identity ----------------------------------------------------------------

TEST(StoreIdentity, EveryStoreGetsItsOwnUuid) {
  test::TempDir d;
  std::vector<std::string> uuids;
  for (const char* name : {"a.dice.h5", "b.dice.h5"}) {
    const auto r = test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", d.path(name)});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    uuids.push_back(read_store(d.path(name)).info().uuid);
  }
  for (const auto& u : uuids) {
    EXPECT_EQ(u.size(), 32u);
    EXPECT_EQ(u.find_first_not_of("0123456789abcdef"), std::string::npos) << u;
  }
  EXPECT_NE(uuids[0], uuids[1]);  // same mesh, same intervals: two stores all the same
}

// export reads the mesh and then the sets, opening the file twice: a store
// renamed over the path in between must not lend the mesh its sets.
TEST(StoreIdentity, SetsOfAReplacedStoreAreRefused) {
  test::TempDir d;
  const std::string path = d.path("mesh.dice.h5"), other = d.path("other.dice.h5");
  for (const auto& [out, interval] : {std::pair{path, "2"}, std::pair{other, "3"}}) {
    const auto r = test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", interval, "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const FineMesh mesh = read_store(path);
  EXPECT_NO_THROW(read_store_sets(mesh, path));
  fs::rename(other, path);
  try {
    read_store_sets(mesh, path);
    ADD_FAILURE() << "the sets of another store were read for this mesh";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io);
    EXPECT_NE(std::string(e.what()).find("replaced"), std::string::npos) << e.what();
  }
  const std::string pristine = d.path("pristine.dice.h5");
  const auto r = test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "2", "-o", pristine});
  ASSERT_EQ(r.exit_code, 0);
  EXPECT_THROW(read_store_sets(read_store(pristine), path), Error);  // same mesh, another store
}

TEST(StoreIdentity, StoreWithoutUuidIsCorrupt) {
  test::TempDir d;
  const std::string p = edited(d, [](hid_t f) { H5Adelete(f, "uuid"); });
  const auto r = run_limited({"info", p});
  EXPECT_EQ(r.exit_code, 8) << r.err;
  expect_one_line(r, {p, "attribute uuid", "missing"});
  const std::string q = edited(d, [](hid_t f) {
    const hid_t sp = H5Screate(H5S_SCALAR), t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, 5);
    replace_attr(f, "uuid", t, sp, "hello");
    H5Tclose(t), H5Sclose(sp);
  });
  const auto s = run_limited({"info", q});
  EXPECT_EQ(s.exit_code, 8) << s.err;
  expect_one_line(s, {q, "attribute uuid", "hex digits"});
}

// Every count attribute is determined by a table: off by one, or huge, it
// is Corrupt at open (exit 8, one line), before it sizes anything; info and
// export never report or write a mesh of the wrong size. (A flipped
// fine_elements once gave a wrong mesh with exit 0, a huge one exit 70;
// checked since store format 6: this test guards that, it passes on the
// base of this branch.)
TEST(HostileStore, CountAttributesAreCheckedAgainstTheTables) {
  test::TempDir d;
  for (const char* name : {"coarse_vertices", "coarse_edges", "coarse_faces", "coarse_elements", "sheets", "fine_nodes",
                           "fine_elements", "bounding_nodes"}) {
    for (const std::int64_t delta : {std::int64_t{1}, std::int64_t{1} << 50}) {
      SCOPED_TRACE(std::string(name) + " + " + std::to_string(delta));
      const std::string p = edited(d, [&](hid_t f) {
        std::int64_t v = 0;
        const hid_t a = H5Aopen(f, name, H5P_DEFAULT);
        H5Aread(a, H5T_NATIVE_INT64, &v);
        H5Aclose(a);
        v += delta;
        const hid_t sp = H5Screate(H5S_SCALAR);
        replace_attr(f, name, H5T_STD_I64LE, sp, &v);
        H5Sclose(sp);
      });
      for (const std::vector<std::string>& cmd :
           {std::vector<std::string>{"info", p}, std::vector<std::string>{"export", p, "--format", "msh", "-o", d.path("out.msh"), "--quiet"}}) {
        const auto r = run_limited(cmd, 4ull << 30);
        EXPECT_EQ(r.exit_code, 8) << cmd[0] << ": " << r.err;
        expect_one_line(r, {p});
      }
      EXPECT_FALSE(fs::exists(d.path("out.msh")));
    }
  }
}
