// Our in-process LZ4 (32004) + Fletcher32 pages against HDF5 itself and
// against independent readers: the HDF5 pipeline, H5Dread_chunk/H5Dwrite_chunk
// with our page codec, h5dump with the HDF Group's libh5lz4.so plugin, and
// h5py + hdf5plugin (tests/roundtrip/interop_check.py).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>

#include "dicer/error.hpp"
#include "hdf5_file.hpp"
#include "lz4_filter.hpp"
#include "test_support.hpp"

using 
namespace dicer;
using namespace dicer::store;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr const char* kPluginDir = "/usr/lib/x86_64-linux-gnu/hdf5/serial/plugins";
constexpr hsize_t kN = 2500, kChunk = 1000;         // /x: float64, chunks 1000 + 1000 + 500
constexpr hsize_t kRows = 1234, kRowChunk = 256;    // /ids: int64 [1234 x 3], 5 chunks, last holds 210 rows

std::vector<double> x_values() {
  std::vector<double> v(kN);
  for (hsize_t i = 0; i < kN; ++i) v[i] = 0.125 * static_cast<double>(i % 1700) - 100.0 + (i % 5 == 0 ? 0.5 : 0.0);
  return v;
}
std::vector<std::int64_t> id_values() {
  std::vector<std::int64_t> v(kRows * 3);
  for (hsize_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::int64_t>(i * 1000003) - 500000000 + (i % 3);
  return v;
}

h5::Handle check(hid_t id, herr_t (*close)(hid_t), const char* what) {
  if (id < 0) throw std::runtime_error(std::string("HDF5 call failed: ") + what);
  return h5::Handle(id, close);
}

h5::Handle make_dataset(hid_t file, const char* name, hid_t type, int rank, const hsize_t* dims, const hsize_t* chunk) {
  auto space = check(H5Screate_simple(rank, dims, nullptr), H5Sclose, "space");
  auto dcpl = check(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "dcpl");
  if (H5Pset_chunk(dcpl.get(), rank, chunk) < 0) throw std::runtime_error("H5Pset_chunk");
  add_page_filters(dcpl.get());
  return check(H5Dcreate2(file, name, type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose, name);
}

// /x (float64) and /ids (int64 [kRows x 3]) written through the pipeline with H5Dwrite.
void write_fixture(const std::string& path) {
  h5::quiet();
  auto file = check(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, "create");
  const hsize_t xd[1] = {kN}, xc[1] = {kChunk};
  auto x = make_dataset(file.get(), "/x", H5T_IEEE_F64LE, 1, xd, xc);
  const auto xv = x_values();
  ASSERT_GE(H5Dwrite(x.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, xv.data()), 0);
  const hsize_t id[2] = {kRows, 3}, ic[2] = {kRowChunk, 3};
  auto ids = make_dataset(file.get(), "/ids", H5T_STD_I64LE, 2, id, ic);
  const auto iv = id_values();
  ASSERT_GE(H5Dwrite(ids.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, iv.data()), 0);
}

struct Chunk {
  hsize_t offset[2] = {0, 0};
  haddr_t addr = 0;
  hsize_t size = 0;
  Bytes stored;
};

std::vector<Chunk> read_chunks(hid_t ds) {
  auto space = check(H5Dget_space(ds), H5Sclose, "space");
  hsize_t n = 0;
  if (H5Dget_num_chunks(ds, space.get(), &n) < 0) throw std::runtime_error("H5Dget_num_chunks");
  std::vector<Chunk> out(n);
  for (hsize_t i = 0; i < n; ++i) {
    unsigned mask = 0;
    if (H5Dget_chunk_info(ds, space.get(), i, out[i].offset, &mask, &out[i].addr, &out[i].size) < 0 || mask != 0)
      throw std::runtime_error("H5Dget_chunk_info");
    out[i].stored.resize(out[i].size);
    std::uint32_t filters = 99;
    if (H5Dread_chunk(ds, H5P_DEFAULT, out[i].offset, &filters, out[i].stored.data()) < 0 || filters != 0)
      throw std::runtime_error("H5Dread_chunk");
  }
  return out;
}

template <class T>
std::vector<T> read_all(hid_t ds, hid_t mem_type, std::size_t n) {
  std::vector<T> v(n);
  if (H5Dread(ds, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) throw std::runtime_error("H5Dread");
  return v;
}

// The full-chunk bytes of the chunk starting at element first_elem (past the end: the fill value 0).
template <class T>
Bytes chunk_bytes(const std::vector<T>& all, std::size_t first_elem, std::size_t chunk_elems) {
  std::vector<T> c(chunk_elems, T{});
  for (std::size_t i = 0; i < chunk_elems && first_elem + i < all.size(); ++i) c[i] = all[first_elem + i];
  Bytes b(chunk_elems * sizeof(T));
  std::memcpy(b.data(), c.data(), b.size());
  return b;
}

using Proc = test::CliResult;
Proc run(const std::vector<std::string>& argv, const std::map<std::string, std::string>& set = {},
         const std::vector<std::string>& unset = {}) {
  return test::run_process(argv, set, unset);
}

// The numbers in h5dump's DATA { ... } block, without the "(i,j):" indices.
std::vector<std::string> h5dump_values(const std::string& dump) {
  const auto start = dump.find("DATA {");
  if (start == std::string::npos) return {};
  const auto end = dump.find('}', start + 6);
  std::string body = dump.substr(start + 6, end - start - 6), clean;
  int depth = 0;
  for (char c : body) {
    if (c == '(') ++depth;
    else if (c == ')') --depth;
    else if (depth == 0 && c != ':') clean += (c == ',' || c == '\n') ? ' ' : c;
  }
  std::istringstream in(clean);
  std::vector<std::string> out;
  for (std::string tok; in >> tok;) out.push_back(tok);
  return out;
}

// The line of interop_check.py's output for dataset `name`.
std::string json_line(const std::string& json, const std::string& name) {
  const std::string key = "\"" + name + "\": {";
  std::istringstream in(json);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key, 0) == 0) return line;
  return {};
}
// The text of field `field` in a one-line JSON object (up to the next ',' or '}' outside brackets).
std::string json_field(const std::string& line, const std::string& field) {
  const std::string key = "\"" + field + "\": ";
  const auto at = line.find(key);
  if (at == std::string::npos) return {};
  std::string v;
  int depth = 0;
  for (std::size_t i = at + key.size(); i < line.size(); ++i) {
    const char c = line[i];
    if (c == '[') ++depth;
    if (c == ']') --depth;
    if (depth == 0 && (c == ',' || c == '}')) break;
    v += c;
  }
  return v;
}

template <class T>
std::uint64_t digest(const std::vector<T>& v) {
  static_assert(sizeof(T) == 8);
  std::uint64_t d = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v[i], 8);
    d += (i + 1) * bits;
  }
  return d;
}

}  // namespace

TEST(Hdf5Interop, PipelineAndDirectChunkPathsAgree) {
  test::TempDir tmp;
  const std::string path = tmp.path("pages.h5");
  ASSERT_NO_FATAL_FAILURE(write_fixture(path));
  const auto xv = x_values();
  const auto iv = id_values();
  auto file = check(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, "open");

  // Through the pipeline.
  auto x = check(H5Dopen2(file.get(), "/x", H5P_DEFAULT), H5Dclose, "/x");
  auto ids = check(H5Dopen2(file.get(), "/ids", H5P_DEFAULT), H5Dclose, "/ids");
  EXPECT_EQ(read_all<double>(x.get(), H5T_NATIVE_DOUBLE, kN), xv);
  EXPECT_EQ(read_all<std::int64_t>(ids.get(), H5T_NATIVE_INT64, kRows * 3), iv);

  // Raw chunks + decode_page; re-encoding gives back the very bytes HDF5 stored.
  const auto xc = read_chunks(x.get());
  ASSERT_EQ(xc.size(), 3u);
  for (std::size_t i = 0; i < xc.size(); ++i) {
    const Bytes want = chunk_bytes(xv, xc[i].offset[0], kChunk);
    Bytes got;
    decode_page(xc[i].stored, got, kChunk * 8, path + ": dataset /x page " + std::to_string(i));
    EXPECT_EQ(got, want) << "page " << i;
    EXPECT_EQ(encode_page(want), xc[i].stored) << "page " << i;
    // The trailer is HDF5's own Fletcher32, least significant byte first.
    const Bytes& s = xc[i].stored;
    const std::uint32_t f = fletcher32(s.data(), s.size() - 4);
    const std::uint8_t* t = s.data() + s.size() - 4;
    EXPECT_EQ(t[0] | (t[1] << 8) | (t[2] << 16) | (std::uint32_t{t[3]} << 24), f);
  }
  std::printf("[ info ] /x pages (8000 bytes each): stored %llu, %llu, %llu bytes\n",
              static_cast<unsigned long long>(xc[0].size), static_cast<unsigned long long>(xc[1].size),
              static_cast<unsigned long long>(xc[2].size));
  const auto ic = read_chunks(ids.get());
  ASSERT_EQ(ic.size(), 5u);
  for (std::size_t i = 0; i < ic.size(); ++i) {
    const Bytes want = chunk_bytes(iv, ic[i].offset[0] * 3, kRowChunk * 3);
    Bytes got;
    decode_page(ic[i].stored, got, kRowChunk * 3 * 8, path + ": dataset /ids page " + std::to_string(i));
    EXPECT_EQ(got, want) << "page " << i;
    EXPECT_EQ(encode_page(want), ic[i].stored) << "page " << i;
  }

  // Pages written directly with H5Dwrite_chunk(encode_page(...)) read back through the pipeline.
  const hsize_t dd[1] = {kN}, dc[1] = {kChunk};
  {
    auto direct = make_dataset(file.get(), "/direct", H5T_IEEE_F64LE, 1, dd, dc);
    for (hsize_t first = 0; first < kN; first += kChunk) {
      const Bytes page = encode_page(chunk_bytes(xv, first, kChunk));
      const hsize_t offset[1] = {first};
      ASSERT_GE(H5Dwrite_chunk(direct.get(), H5P_DEFAULT, 0, offset, page.size(), page.data()), 0);
    }
  }
  file.reset();
  auto again = check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "reopen");
  auto direct = check(H5Dopen2(again.get(), "/direct", H5P_DEFAULT), H5Dclose, "/direct");
  EXPECT_EQ(read_all<double>(direct.get(), H5T_NATIVE_DOUBLE, kN), xv);
}

TEST(Hdf5Interop, PageWithLyingLayoutFailsThePipelineCleanly) {
  // Valid checksums, lying LZ4 layouts: H5Dread must fail (the filter returns 0), never crash or over-allocate.
  h5::quiet();
  test::TempDir tmp;
  const std::string path = tmp.path("lies.h5");
  auto file = check(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, "create");
  const hsize_t dims[1] = {kChunk}, chunk[1] = {kChunk};
  const auto seal = [](Bytes b) {
    const std::uint32_t f = fletcher32(b.data(), b.size());
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(f >> (8 * i)));
    return b;
  };
  Bytes good = encode_page(chunk_bytes(x_values(), 0, kChunk));
  good.resize(good.size() - 4);
  std::vector<Bytes> lies;
  Bytes huge = good;  // original size 2^40
  huge[2] = 1;
  lies.push_back(huge);
  Bytes zero_block = good;  // block size 0
  std::fill(zero_block.begin() + 8, zero_block.begin() + 12, 0);
  lies.push_back(zero_block);
  Bytes past_end = good;  // first block's stored size 2^32 - 1
  std::fill(past_end.begin() + 12, past_end.begin() + 16, 0xff);
  lies.push_back(past_end);
  Bytes garbage = good;  // LZ4 block body overwritten
  std::fill(garbage.begin() + 16, garbage.end(), 0xee);
  lies.push_back(garbage);
  lies.push_back(Bytes(good.begin(), good.begin() + 7));  // truncated header
  for (std::size_t k = 0; k < lies.size(); ++k) {
    const std::string name = "/lie" + std::to_string(k);
    auto ds = make_dataset(file.get(), name.c_str(), H5T_IEEE_F64LE, 1, dims, chunk);
    const Bytes page = seal(lies[k]);
    const hsize_t offset[1] = {0};
    ASSERT_GE(H5Dwrite_chunk(ds.get(), H5P_DEFAULT, 0, offset, page.size(), page.data()), 0);
    std::vector<double> out(kChunk);
    EXPECT_LT(H5Dread(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0) << name;
    Bytes decoded;
    EXPECT_THROW(decode_page(page, decoded, kChunk * 8, name), Error) << name;
  }
}

TEST(Hdf5Interop, H5dumpWithTheHdfGroupPluginReadsOurFile) {
  if (!std::filesystem::exists("/usr/bin/h5dump") || !std::filesystem::exists(std::string(kPluginDir) + "/libh5lz4.so"))
    DICER_SKIP_OR_FAIL_IN_CI("h5dump or the HDF Group LZ4 plugin (hdf5-tools, hdf5-filter-plugin) is not installed");
  test::TempDir tmp;
  const std::string path = tmp.path("dump.h5");
  ASSERT_NO_FATAL_FAILURE(write_fixture(path));
  const Proc x = run({"/usr/bin/h5dump", "-d", "/x", path}, {{"HDF5_PLUGIN_PATH", kPluginDir}});
  ASSERT_EQ(x.exit_code, 0) << x.err;
  const auto xs = h5dump_values(x.out);
  const auto xv = x_values();
  ASSERT_EQ(xs.size(), kN) << x.out.substr(0, 2000);
  for (hsize_t i = 0; i < kN; ++i) ASSERT_EQ(std::strtod(xs[i].c_str(), nullptr), xv[i]) << i << ": " << xs[i];

  const Proc ids = run({"/usr/bin/h5dump", "-d", "/ids", path}, {{"HDF5_PLUGIN_PATH", kPluginDir}});
  ASSERT_EQ(ids.exit_code, 0) << ids.err;
  const auto is = h5dump_values(ids.out);
  const auto iv = id_values();
  ASSERT_EQ(is.size(), iv.size());
  for (std::size_t i = 0; i < iv.size(); ++i) ASSERT_EQ(std::strtoll(is[i].c_str(), nullptr, 10), iv[i]) << i;
}

TEST(Hdf5Interop, H5pyWithHdf5pluginReadsOurFile) {
  if (!std::filesystem::exists("/usr/bin/python3")) DICER_SKIP_OR_FAIL_IN_CI("no /usr/bin/python3");
  test::TempDir tmp;
  const std::string path = tmp.path("py.h5");
  ASSERT_NO_FATAL_FAILURE(write_fixture(path));
  const Proc p = run({"/usr/bin/python3", std::string(DICER_SOURCE_DIR) + "/tests/roundtrip/interop_check.py", path},
                     {}, {"PYTHONPATH", "PYTHONHOME", "HDF5_PLUGIN_PATH"});
  if (p.exit_code == 77) DICER_SKIP_OR_FAIL_IN_CI(p.err);
  ASSERT_EQ(p.exit_code, 0) << p.err << p.out;

  const auto xv = x_values();
  const std::string x = json_line(p.out, "/x");
  ASSERT_FALSE(x.empty()) << p.out;
  EXPECT_EQ(json_field(x, "dtype"), "\"float64\"");
  EXPECT_EQ(json_field(x, "shape"), "[2500]");
  EXPECT_EQ(json_field(x, "filters"), "[\"32004\", \"fletcher32\"]");
  EXPECT_EQ(json_field(x, "count"), "2500");
  double xsum = 0;  // exact: every value is a multiple of 1/8 well below 2^40
  for (double v : xv) xsum += v;
  EXPECT_EQ(std::strtod(json_field(x, "sum").c_str(), nullptr), xsum);
  EXPECT_EQ(std::strtod(json_field(x, "last").c_str(), nullptr), xv.back());
  EXPECT_EQ(std::strtoull(json_field(x, "digest").c_str(), nullptr, 10), digest(xv));
  const std::string first = json_field(x, "first");
  ASSERT_GE(first.size(), 2u);
  std::istringstream fs(first.substr(1, first.size() - 2));
  for (int i = 0; i < 3; ++i) {
    std::string tok;
    std::getline(fs, tok, ',');
    EXPECT_EQ(std::strtod(tok.c_str(), nullptr), xv[i]) << tok;
  }

  const auto iv = id_values();
  const std::string ids = json_line(p.out, "/ids");
  ASSERT_FALSE(ids.empty()) << p.out;
  EXPECT_EQ(json_field(ids, "dtype"), "\"int64\"");
  EXPECT_EQ(json_field(ids, "shape"), "[1234, 3]");
  std::int64_t isum = 0;
  for (auto v : iv) isum += v;
  EXPECT_EQ(std::strtoll(json_field(ids, "sum").c_str(), nullptr, 10), isum);
  EXPECT_EQ(std::strtoll(json_field(ids, "last").c_str(), nullptr, 10), iv.back());
  EXPECT_EQ(std::strtoull(json_field(ids, "digest").c_str(), nullptr, 10), digest(iv));
}

TEST(Hdf5Interop, WeReadMultiBlockPagesWrittenByThePlugin) {
  // h5py + hdf5plugin (the HDF Group's H5Zlz4) write LZ4 pages with small block sizes;
  // our in-process filter (H5Dread) and decode_page (H5Dread_chunk) must both read them.
  if (!std::filesystem::exists("/usr/bin/python3")) DICER_SKIP_OR_FAIL_IN_CI("no /usr/bin/python3");
  h5::quiet();
  register_lz4_filter();
  test::TempDir tmp;
  const std::string path = tmp.path("plugin.h5");
  const std::string script = std::string(DICER_SOURCE_DIR) + "/tests/roundtrip/interop_check.py";
  const std::vector<std::string> clean_env = {"PYTHONPATH", "PYTHONHOME"};
  const Proc w = run({"/usr/bin/python3", script, "--write", path}, {}, clean_env);
  if (w.exit_code == 77) DICER_SKIP_OR_FAIL_IN_CI(w.err);
  ASSERT_EQ(w.exit_code, 0) << w.err;
  const Proc summary = run({"/usr/bin/python3", script, path}, {}, clean_env);
  ASSERT_EQ(summary.exit_code, 0) << summary.err;

  auto file = check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open");
  const struct {
    const char* name;
    std::size_t count;
    std::uint32_t block;
  } sets[] = {{"/x", 5000, 3000}, {"/noise", 2600, 3000}, {"/mixed", 2700, 4000}};
  for (const auto& set : sets) {
    SCOPED_TRACE(set.name);
    auto ds = check(H5Dopen2(file.get(), set.name, H5P_DEFAULT), H5Dclose, set.name);
    // Both element types are 8-byte little-endian: read the bit patterns unconverted.
    auto type = check(H5Dget_type(ds.get()), H5Tclose, "type");
    const auto through_filter = read_all<std::int64_t>(ds.get(), type.get(), set.count);
    std::vector<std::int64_t> through_codec(set.count);
    std::size_t blocks = 0, raw_blocks = 0, compressed_blocks = 0;
    for (const Chunk& c : read_chunks(ds.get())) {
      const Bytes& s = c.stored;
      ASSERT_GE(s.size(), 16u);
      EXPECT_EQ((std::uint32_t{s[8]} << 24) | (s[9] << 16) | (s[10] << 8) | s[11], set.block);
      for (std::size_t pos = 12, left = 8000; left > 0;) {  // count the plugin's blocks
        const std::size_t len = std::min<std::size_t>(set.block, left);
        const std::size_t stored = (std::size_t{s[pos]} << 24) | (s[pos + 1] << 16) | (s[pos + 2] << 8) | s[pos + 3];
        raw_blocks += stored == len;
        compressed_blocks += stored < len;
        ++blocks;
        pos += 4 + stored;
        left -= len;
      }
      Bytes page;
      decode_page(s, page, 8000, path + ": dataset " + set.name + " page " + std::to_string(c.offset[0] / 1000));
      const std::size_t n = std::min<std::size_t>(1000, set.count - c.offset[0]);
      std::memcpy(through_codec.data() + c.offset[0], page.data(), n * 8);
    }
    EXPECT_EQ(through_codec, through_filter);
    // Several blocks per page, raw (noise) and LZ4 (smooth data, zeros, the fill value past the end) ones.
    EXPECT_EQ(raw_blocks + compressed_blocks, blocks);
    EXPECT_GE(blocks, 6u);
    EXPECT_GT(compressed_blocks, 0u);
    if (std::string(set.name) != "/x") {
      EXPECT_GE(raw_blocks, 2u);
    }
    const std::string line = json_line(summary.out, set.name);
    EXPECT_EQ(std::strtoull(json_field(line, "digest").c_str(), nullptr, 10), digest(through_filter)) << line;
  }
}

TEST(Hdf5Interop, FlippedByteInAStoredPageIsCaught) {
  test::TempDir tmp;
  const std::string path = tmp.path("good.h5"), bad_path = tmp.path("bad.h5");
  ASSERT_NO_FATAL_FAILURE(write_fixture(path));
  Chunk target;
  {
    auto file = check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open");
    auto x = check(H5Dopen2(file.get(), "/x", H5P_DEFAULT), H5Dclose, "/x");
    target = read_chunks(x.get()).at(1);
  }
  std::string bytes = test::read_file(path);
  ASSERT_LT(target.addr + target.size, bytes.size());
  ASSERT_EQ(0, std::memcmp(bytes.data() + target.addr, target.stored.data(), target.size));  // the page is really there
  bytes[target.addr + target.size / 2] ^= 0x10;
  test::write_file(bad_path, bytes);

  auto file = check(H5Fopen(bad_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open bad");
  auto x = check(H5Dopen2(file.get(), "/x", H5P_DEFAULT), H5Dclose, "/x");
  std::vector<double> all(kN);
  EXPECT_LT(H5Dread(x.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, all.data()), 0);
  // Page 0 alone still reads.
  {
    auto fspace = check(H5Dget_space(x.get()), H5Sclose, "space");
    const hsize_t start[1] = {0}, count[1] = {kChunk};
    ASSERT_GE(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
    auto mspace = check(H5Screate_simple(1, count, nullptr), H5Sclose, "mspace");
    std::vector<double> page0(kChunk);
    ASSERT_GE(H5Dread(x.get(), H5T_NATIVE_DOUBLE, mspace.get(), fspace.get(), H5P_DEFAULT, page0.data()), 0);
    const auto xv = x_values();
    EXPECT_TRUE(std::equal(page0.begin(), page0.end(), xv.begin()));
  }
  const auto chunks = read_chunks(x.get());
  const std::string what = bad_path + ": dataset /x page 1";
  Bytes out;
  try {
    decode_page(chunks.at(1).stored, out, kChunk * 8, what);
    FAIL() << "decode_page accepted a damaged page";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Corrupt);
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
}

// unshuffle_bytes undoes HDF5's own shuffle filter (H5Pset_shuffle, no other
// filter, the chunk read raw with H5Dread_chunk): 8-byte elements at counts
// around the 16-element vector steps (the SSE2 path and its scalar tail),
// 4- and 1-byte elements (the scalar path), and shuffle_bytes gives HDF5's
// bytes too.
TEST(Hdf5Interop, OurShuffleIsHdf5sShuffleFilter) {
  test::TempDir tmp;
  const std::string path = tmp.path("shuffle.h5");
  h5::quiet();
  auto file = check(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, "file");
  std::uint64_t seed = 0x1234567;
  auto byte = [&seed] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint8_t>(seed >> 56);
  };
  int sets = 0;
  for (const hid_t type : {H5T_NATIVE_INT64, H5T_NATIVE_INT32, H5T_NATIVE_UINT8}) {
    const size_t elem = H5Tget_size(type);
    for (const hsize_t count : {1, 15, 16, 17, 31, 32, 47, 100, 1000, 4099}) {
      const std::string name = "d" + std::to_string(sets++);
      auto space = check(H5Screate_simple(1, &count, nullptr), H5Sclose, "space");
      auto dcpl = check(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "dcpl");
      ASSERT_GE(H5Pset_chunk(dcpl.get(), 1, &count), 0);
      ASSERT_GE(H5Pset_shuffle(dcpl.get()), 0);
      auto ds = check(H5Dcreate2(file.get(), name.c_str(), type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                      H5Dclose, "dataset");
      Bytes plain(count * elem);
      for (auto& b : plain) b = byte();
      ASSERT_GE(H5Dwrite(ds.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, plain.data()), 0);
      ASSERT_GE(H5Fflush(file.get(), H5F_SCOPE_LOCAL), 0);
      Bytes hdf5_shuffled(plain.size());
      const hsize_t offset = 0;
      std::uint32_t mask = 0;
      ASSERT_GE(H5Dread_chunk(ds.get(), H5P_DEFAULT, &offset, &mask, hdf5_shuffled.data()), 0);
      ASSERT_EQ(mask, 0u);
      if (elem > 1 && count > 1) {
        ASSERT_NE(hdf5_shuffled, plain) << name;  // the filter ran
      }
      Bytes ours;
      unshuffle_bytes(hdf5_shuffled, elem, ours);
      EXPECT_EQ(ours, plain) << elem << "-byte elements, " << count;
      shuffle_bytes(plain, elem, ours);
      EXPECT_EQ(ours, hdf5_shuffled) << elem << "-byte elements, " << count;
    }
  }
}

// page_crc (libdeflate) is the CRC-32 of zlib and gzip: the standard check
// value of "123456789", and zlib's crc32 on pages of every length up to a
// few vector widths past 64 KiB, at every alignment of the first byte.
TEST(Hdf5Interop, PageCrcIsZlibsCrc32) {
  const std::string check = "123456789";
  EXPECT_EQ(page_crc({reinterpret_cast<const std::uint8_t*>(check.data()), check.size()}), 0xCBF43926u);
  EXPECT_EQ(page_crc({}), 0u);
  std::vector<std::uint8_t> bytes(65536 + 300);
  std::uint64_t seed = 99;
  for (auto& b : bytes) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    b = static_cast<std::uint8_t>(seed >> 56);
  }
  auto zlib = [](const std::uint8_t* p, size_t n) {
    return static_cast<std::uint32_t>(crc32(crc32(0L, Z_NULL, 0), p, static_cast<uInt>(n)));
  };
  for (size_t at = 0; at < 16; ++at)
    for (size_t n : {size_t{1}, size_t{7}, size_t{15}, size_t{16}, size_t{63}, size_t{64}, size_t{65}, size_t{255},
                     size_t{4096}, size_t{65536}, size_t{65536 + 200}})
      ASSERT_EQ(page_crc({bytes.data() + at, n}), zlib(bytes.data() + at, n)) << "length " << n << " at " << at;
}
