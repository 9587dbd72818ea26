// Shared bodies of the fuzz targets and of the FuzzRegressions tests; see
// fuzz_entries.hpp for what each one checks.
#include "fuzz_entries.hpp"

#include <hdf5.h>
#include <stdlib.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <span>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/store.hpp"
#include "dicer/verify.hpp"
#include "lz4_filter.hpp"

#ifndef DICER_FUZZ_DATA_DIR
#ifdef DICER_TEST_DATA
#define DICER_FUZZ_DATA_DIR DICER_TEST_DATA
#else
#error "define DICER_FUZZ_DATA_DIR (the tests/data folder)"
#endif
#endif

namespace dicer::fuzz {
namespace {

// One temporary folder per process, removed at exit.
class ProcessTempDir {
 public:
  ProcessTempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string templ = std::string(base && *base ? base : "/tmp") + "/dicer-fuzz-XXXXXX";
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) throw std::runtime_error("fuzz: cannot create a temporary folder under " + templ);
    dir_ = buf.data();
  }
  ~ProcessTempDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

 private:
  std::filesystem::path dir_;
};

ProcessTempDir& temp_dir() {
  static ProcessTempDir dir;
  return dir;
}

void write_bytes(const std::string& path, const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::runtime_error("fuzz: cannot write " + path);
  const bool ok = size == 0 || std::fwrite(data, 1, size, f) == size;
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error("fuzz: cannot write " + path);
}

[[noreturn]] void bug(const std::string& what) { throw FuzzBug("fuzz oracle failed: " + what); }

// ---- MSH ---------------------------------------------------------------------

void dice_and_verify(CoarseMesh mesh) {
  const Id ne = mesh.num_elements();
  const FineMesh fine = FineMesh::dice(std::move(mesh), IntervalRequest{});
  if (fine.num_coarse_elements() != ne) bug("dice changed the number of coarse elements");
  const VerifyReport r = verify(fine);
  // Properties of the numbering and of the recipe, true for every accepted
  // mesh whatever its geometry (coincident nodes or poor Jacobians are the
  // input's business, not a bug).
  if (!r.counts_ok() || r.id_errors != 0 || r.bit_identity_errors != 0) {
    std::string msg = "verify: counts " + std::to_string(r.nodes) + "/" + std::to_string(r.nodes_formula) + " nodes, " +
                      std::to_string(r.elements) + "/" + std::to_string(r.elements_formula) + " elements, " +
                      std::to_string(r.id_errors) + " id errors, " + std::to_string(r.bit_identity_errors) +
                      " bit-identity errors";
    for (const auto& p : r.problems) msg += "; " + p;
    bug(msg);
  }
}

// ---- store -------------------------------------------------------------------

struct ChunkRange {
  std::uint64_t addr = 0, size = 0;
};

herr_t collect_chunks(hid_t obj, const char* name, const H5O_info_t* info, void* op_data) {
  if (info->type != H5O_TYPE_DATASET) return 0;
  auto* out = static_cast<std::vector<ChunkRange>*>(op_data);
  const hid_t ds = H5Dopen2(obj, name, H5P_DEFAULT);
  if (ds < 0) return -1;
  // HDF5 1.10.8 refuses H5S_ALL here: pass the dataset's own space.
  const hid_t space = H5Dget_space(ds);
  hsize_t n = 0;
  herr_t status = 0;
  if (space < 0 || H5Dget_num_chunks(ds, space, &n) < 0) status = -1;
  for (hsize_t i = 0; status == 0 && i < n; ++i) {
    hsize_t offset[2] = {0, 0};
    unsigned mask = 0;
    haddr_t addr = 0;
    hsize_t size = 0;
    if (H5Dget_chunk_info(ds, space, i, offset, &mask, &addr, &size) < 0) status = -1;
    else if (size > 0) out->push_back({static_cast<std::uint64_t>(addr), static_cast<std::uint64_t>(size)});
  }
  if (space >= 0) H5Sclose(space);
  H5Dclose(ds);
  return status;
}

// What a store gives back, flattened: info, every block, a few queries, the
// sets. Two reads are bit-identical iff their traces are equal.
using Trace = std::vector<std::uint64_t>;

void put(Trace& t, double v) { t.push_back(std::bit_cast<std::uint64_t>(v)); }
void put(Trace& t, Id v) { t.push_back(static_cast<std::uint64_t>(v)); }
void put(Trace& t, const std::string& s) {
  put(t, static_cast<Id>(s.size()));
  for (unsigned char c : s) t.push_back(c);
}

// Appends to t as it goes, so a read that fails half way leaves the part it
// returned before failing (which must match too).
void trace_store(const std::string& path, Trace& t) {
  const FineMesh m = read_store(path, StoreOptions{1u << 20, 0});
  const MeshInfo& i = m.info();
  put(t, static_cast<Id>(i.mode));
  put(t, i.source);
  for (Id v : {i.coarse_vertices, i.coarse_edges, i.coarse_faces, i.coarse_elements, i.sheets, i.nodes, i.elements})
    put(t, v);
  for (Id v : m.sheet_intervals()) put(t, v);
  put(t, static_cast<Id>(i.blocks.size()));
  for (const Block& b : i.blocks) put(t, b.id), put(t, b.name);
  for (Id v : i.block_coarse_elements) put(t, v);
  for (Id v : i.block_fine_elements) put(t, v);
  FineBlock b;
  for (Id h = 0; h < m.num_coarse_elements(); ++h) {
    m.fill_block(h, b);
    put(t, b.coarse_element);
    for (Id v : b.n) put(t, v);
    put(t, b.first_element), put(t, static_cast<Id>(b.block));
    put(t, static_cast<Id>(b.node_id.size()));
    for (std::size_t g = 0; g < b.node_id.size(); ++g) put(t, b.node_id[g]), put(t, b.x[g]), put(t, b.y[g]), put(t, b.z[g]);
    put(t, static_cast<Id>(b.conn.size()));
    for (Id c : b.conn) put(t, c);
  }
  const Id nn = m.num_nodes(), ne = m.num_elements();
  for (Id id : {Id{0}, nn / 3, nn / 2, nn - 1}) {
    if (id < 0 || id >= nn) continue;
    const Vec3 p = m.node(id);
    put(t, p.x), put(t, p.y), put(t, p.z);
  }
  for (Id id : {Id{0}, ne / 3, ne / 2, ne - 1}) {
    if (id < 0 || id >= ne) continue;
    const FineElement e = m.element(id);
    put(t, e.id), put(t, static_cast<Id>(e.num_nodes)), put(t, e.coarse_element), put(t, static_cast<Id>(e.block));
    for (Id v : e.nodes) put(t, v);
    for (Id v : e.ijk) put(t, v);
  }
  const StoreSets sets = read_store_sets(path);
  put(t, static_cast<Id>(sets.side_sets.size()));
  for (const SideSet& s : sets.side_sets) {
    put(t, s.id), put(t, s.name), put(t, static_cast<Id>(s.element.size()));
    for (std::size_t k = 0; k < s.element.size(); ++k) put(t, s.element[k]), put(t, static_cast<Id>(s.side[k]));
  }
  put(t, static_cast<Id>(sets.node_sets.size()));
  for (const NodeSet& s : sets.node_sets) {
    put(t, s.id), put(t, s.name), put(t, static_cast<Id>(s.vertex.size()));
    for (Id v : s.vertex) put(t, v);
  }
}

struct Pristine {
  std::string path;                  // the pristine store (kept on disk)
  std::string mutated_path;          // where edited copies are written
  std::vector<std::uint8_t> bytes;   // the pristine file
  std::vector<ChunkRange> chunks;    // sorted by address
  std::vector<std::uint64_t> start;  // prefix sums of chunk sizes
  std::uint64_t total = 0;
  Trace trace;
};

Pristine build_pristine() {
  Pristine p;
  p.path = temp_dir().path("pristine.dice.h5");
  p.mutated_path = temp_dir().path("mutated.dice.h5");
  IntervalRequest r;
  r.global = 2;
  write_store(FineMesh::dice(read_coarse_mesh(std::string(DICER_FUZZ_DATA_DIR) + "/cardinal_sphere.e"), r), p.path);
  {
    std::ifstream in(p.path, std::ios::binary);
    p.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  {
    const hid_t f = H5Fopen(p.path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) throw std::runtime_error("fuzz: cannot open " + p.path);
    const herr_t st = H5Ovisit2(f, H5_INDEX_NAME, H5_ITER_INC, collect_chunks, &p.chunks, H5O_INFO_BASIC);
    H5Fclose(f);
    if (st < 0) throw std::runtime_error("fuzz: cannot list the chunks of " + p.path);
  }
  std::sort(p.chunks.begin(), p.chunks.end(), [](const ChunkRange& a, const ChunkRange& b) { return a.addr < b.addr; });
  for (const ChunkRange& c : p.chunks) {
    if (c.addr + c.size > p.bytes.size()) throw std::runtime_error("fuzz: chunk past the end of " + p.path);
    p.start.push_back(p.total);
    p.total += c.size;
  }
  if (p.total == 0) throw std::runtime_error("fuzz: " + p.path + " has no chunks");
  trace_store(p.path, p.trace);
  return p;
}

const Pristine& pristine() {
  static const Pristine p = build_pristine();
  return p;
}

bool checksum_valid(const std::uint8_t* chunk, std::size_t n) {
  if (n < 4) return false;
  const std::uint32_t want = std::uint32_t{chunk[n - 4]} | (std::uint32_t{chunk[n - 3]} << 8) |
                             (std::uint32_t{chunk[n - 2]} << 16) | (std::uint32_t{chunk[n - 1]} << 24);
  return store::fletcher32(chunk, n - 4) == want;
}

std::uint32_t le32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) | (std::uint32_t{p[3]} << 24);
}

}  // namespace

// Bytes -> a file -> read_coarse_mesh; small meshes are diced and verified.
void read_dice_verify(const std::string& path, const std::uint8_t* data, std::size_t size) {
  write_bytes(path, data, size);
  try {
    CoarseMesh mesh = read_coarse_mesh(path);
    if (mesh.num_elements() <= kMaxDiceElements) dice_and_verify(std::move(mesh));
  } catch (const Error&) {
  }
}

void run_msh(const std::uint8_t* data, std::size_t size) {
  // netCDF classic / HDF5 magic goes to the Exodus reader: not this target.
  if (size >= 3 && std::memcmp(data, "CDF", 3) == 0) return;
  if (size >= 4 && std::memcmp(data, "\x89HDF", 4) == 0) return;
  static const std::string path = temp_dir().path("input.msh");
  read_dice_verify(path, data, size);
}

void run_exodus(const std::uint8_t* data, std::size_t size) {
  // Only netCDF classic, 64-bit offset and 64-bit data files ("CDF" 1, 2, 5).
  if (size < 4 || std::memcmp(data, "CDF", 3) != 0 || (data[3] != 1 && data[3] != 2 && data[3] != 5)) return;
  static const std::string path = temp_dir().path("input.e");
  read_dice_verify(path, data, size);
}

void run_page(const std::uint8_t* data, std::size_t size) {
  std::uint32_t head = 0;
  for (std::size_t i = 0; i < 4 && i < size; ++i) head |= std::uint32_t{data[i]} << (8 * i);
  const std::size_t expected = head % (1u << 20);
  const std::span<const std::uint8_t> rest(data + std::min<std::size_t>(size, 4), size - std::min<std::size_t>(size, 4));
  std::vector<std::uint8_t> out;

  // 1. As stored.
  try {
    store::decode_page(rest, out, expected, "fuzz");
    if (out.size() != expected) bug("decode_page returned " + std::to_string(out.size()) + " bytes, expected " +
                                    std::to_string(expected));
  } catch (const Error&) {
  }

  // 2. Header size set to expected_size and checksum recomputed, so the
  //    LZ4 layout and the LZ4 data are what is fuzzed.
  if (rest.size() >= 16) {
    std::vector<std::uint8_t> page(rest.begin(), rest.end());
    for (int i = 7, k = 0; i >= 0; --i, ++k) page[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(expected >> (8 * k));
    const std::size_t n = page.size() - 4;
    const std::uint32_t sum = store::fletcher32(page.data(), n);
    for (int i = 0; i < 4; ++i) page[n + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(sum >> (8 * i));
    try {
      store::decode_page(page, out, expected, "fuzz");
      if (out.size() != expected) bug("decode_page (resealed) returned " + std::to_string(out.size()) +
                                      " bytes, expected " + std::to_string(expected));
    } catch (const Error&) {
    }
  }

  // 3. Round trip of the rest: must succeed and give the same bytes.
  const std::vector<std::uint8_t> enc = store::encode_page(rest);
  std::vector<std::uint8_t> back;
  store::decode_page(enc, back, rest.size(), "fuzz round trip");  // an Error here escapes: a bug
  if (back.size() != rest.size() || !std::equal(back.begin(), back.end(), rest.begin()))
    bug("encode_page/decode_page round trip changed " + std::to_string(rest.size()) + " bytes");
}

std::string pristine_store_path() { return pristine().path; }

void run_store(const std::uint8_t* data, std::size_t size) {
  // A whole file: anything in it may be wrong (superblock, object headers,
  // chunk indexes, pages); only a dicer::Error may come out.
  static const std::uint8_t kHdf5[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  if (size >= sizeof kHdf5 && std::memcmp(data, kHdf5, sizeof kHdf5) == 0) {
    static const std::string path = temp_dir().path("whole.dice.h5");
    write_bytes(path, data, size);
    Trace t;
    try {
      trace_store(path, t);
    } catch (const Error&) {
    }
    return;
  }
  const Pristine& p = pristine();
  constexpr std::size_t kEditBytes = 5, kMaxEdits = 256;
  std::vector<std::uint8_t> bytes = p.bytes;
  std::vector<std::size_t> touched;  // chunk indexes edited
  for (std::size_t e = 0; e < size / kEditBytes && e < kMaxEdits; ++e) {
    const std::uint8_t* rec = data + e * kEditBytes;
    const std::uint64_t at = le32(rec) % p.total;
    const std::size_t c = static_cast<std::size_t>(std::upper_bound(p.start.begin(), p.start.end(), at) - p.start.begin() - 1);
    bytes[static_cast<std::size_t>(p.chunks[c].addr + (at - p.start[c]))] ^= rec[4];
    touched.push_back(c);
  }
  // A changed chunk whose Fletcher32 still verifies cannot be detected by
  // the store (checksum collision): then only "no crash" is required.
  bool collision = false;
  for (std::size_t c : touched) {
    const std::uint8_t* q = bytes.data() + p.chunks[c].addr;
    const std::size_t n = static_cast<std::size_t>(p.chunks[c].size);
    if (std::memcmp(q, p.bytes.data() + p.chunks[c].addr, n) != 0 && checksum_valid(q, n)) collision = true;
  }
  write_bytes(p.mutated_path, bytes.data(), bytes.size());
  Trace t;
  try {
    trace_store(p.mutated_path, t);
  } catch (const Error&) {
  }
  if (collision) return;
  if (t.size() > p.trace.size() || !std::equal(t.begin(), t.end(), p.trace.begin()))
    bug("a damaged store was read without an error and gave different data (silent corruption)");
}

}  // namespace dicer::fuzz
