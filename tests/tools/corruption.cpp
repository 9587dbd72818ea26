#include "corruption.hpp"

#include <hdf5.h>

#include <algorithm>
#include <bit>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "dicer/error.hpp"
#include "dicer/store.hpp"

namespace dicer::corruption {

namespace {

// Order-dependent 64-bit hash (splitmix64 finaliser per step).
struct Hash {
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  void add(std::uint64_t v) {
    std::uint64_t z = h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2));
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    h = z ^ (z >> 31);
  }
  void add(std::int64_t v) { add(static_cast<std::uint64_t>(v)); }
  void add(int v) { add(static_cast<std::uint64_t>(static_cast<std::int64_t>(v))); }
  void add(double v) { add(std::bit_cast<std::uint64_t>(v)); }
  void add(const std::string& s) {
    add(static_cast<std::uint64_t>(s.size()));
    for (unsigned char c : s) add(static_cast<std::uint64_t>(c));
  }
};

// Silences HDF5's automatic error printing for a scope.
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

struct VisitState {
  hid_t file;
  std::vector<Chunk>* out;
  std::string error;
};

herr_t visit_link(hid_t, const char* name, const H5L_info_t* info, void* data) {
  auto* st = static_cast<VisitState*>(data);
  if (info->type != H5L_TYPE_HARD) return 0;
  const hid_t obj = H5Oopen(st->file, name, H5P_DEFAULT);
  if (obj < 0) return 0;
  if (H5Iget_type(obj) == H5I_DATASET) {
    const hid_t dcpl = H5Dget_create_plist(obj);
    if (H5Pget_layout(dcpl) == H5D_CHUNKED) {
      hsize_t chunk_dims[2] = {0, 0};
      H5Pget_chunk(dcpl, 2, chunk_dims);
      const hid_t space = H5Dget_space(obj);
      hsize_t n = 0;
      if (H5Dget_num_chunks(obj, space, &n) < 0) st->error = std::string("H5Dget_num_chunks failed on ") + name;
      for (hsize_t i = 0; i < n; ++i) {
        hsize_t offset[2] = {0, 0}, size = 0;
        unsigned mask = 0;
        haddr_t addr = 0;
        if (H5Dget_chunk_info(obj, space, i, offset, &mask, &addr, &size) < 0) {
          st->error = std::string("H5Dget_chunk_info failed on ") + name;
          break;
        }
        st->out->push_back(Chunk{name, chunk_dims[0] ? offset[0] / chunk_dims[0] : 0, addr, size});
      }
      H5Sclose(space);
    }
    H5Pclose(dcpl);
  }
  H5Oclose(obj);
  return 0;
}

// Reads a whole dataset through HDF5's own filter pipeline (LZ4 as dicer
// registered it, then Fletcher32 verification). False when HDF5 refuses.
bool hdf5_reads_dataset(const std::string& path, const std::string& dataset) {
  QuietHdf5 quiet;
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return false;
  bool ok = false;
  const hid_t ds = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (ds >= 0) {
    const hid_t type = H5Dget_type(ds);
    const hid_t space = H5Dget_space(ds);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    std::vector<unsigned char> buf(static_cast<size_t>(std::max<hssize_t>(n, 1)) * H5Tget_size(type));
    ok = H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) >= 0;
    H5Sclose(space);
    H5Tclose(type);
    H5Dclose(ds);
  }
  H5Fclose(f);
  return ok;
}

template <class T>
std::uint64_t hash_table(const Table<T>& t) {
  Hash h;
  h.add(t.rows());
  h.add(t.width());
  TableCursor cur;
  for (std::int64_t i = 0; i < t.rows(); ++i) {
    const T* r = t.row(i, cur);
    for (std::int64_t c = 0; c < t.width(); ++c) h.add(r[c]);
  }
  return h.h;
}

std::uint64_t hash_vector(const std::vector<std::int64_t>& v) {
  Hash h;
  h.add(static_cast<std::uint64_t>(v.size()));
  for (std::int64_t x : v) h.add(x);
  return h.h;
}

}  // namespace

std::vector<Chunk> list_chunks(const std::string& path) {
  QuietHdf5 quiet;
  std::vector<Chunk> out;
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) throw std::runtime_error(path + ": HDF5 cannot open the file");
  VisitState st{f, &out, {}};
  const herr_t rc = H5Lvisit(f, H5_INDEX_NAME, H5_ITER_INC, visit_link, &st);
  H5Fclose(f);
  if (rc < 0 || !st.error.empty()) throw std::runtime_error(path + ": cannot list chunks: " + st.error);
  std::sort(out.begin(), out.end(), [](const Chunk& a, const Chunk& b) { return a.address < b.address; });
  return out;
}

std::string Fingerprint::first_difference(const Fingerprint& o) const {
  if (info != o.info) return "mesh info (counts, blocks)";
  if (element.size() != o.element.size()) return "number of coarse elements";
  for (size_t h = 0; h < element.size(); ++h)
    if (element[h] != o.element[h]) return "fill_block of coarse element " + std::to_string(h);
  if (nodes != o.nodes) return "NodeCursor sweep";
  if (elements != o.elements) return "ElementCursor sweep";
  for (const auto& [name, v] : tables) {
    auto it = o.tables.find(name);
    if (it == o.tables.end() || it->second != v) return "table " + name;
  }
  if (tables.size() != o.tables.size()) return "table list";
  if (sets != o.sets) return "side and node sets";
  return "";
}

Fingerprint sweep(const std::string& path) {
  Fingerprint f;
  {
    const FineMesh m = read_store(path);
    const MeshInfo& in = m.info();
    Hash hi;
    hi.add(static_cast<int>(in.mode));
    hi.add(in.source);
    for (Id v : {in.coarse_vertices, in.coarse_edges, in.coarse_faces, in.coarse_elements, in.sheets, in.nodes, in.elements})
      hi.add(v);
    for (const Block& b : in.blocks) hi.add(b.id), hi.add(b.name);
    for (Id v : in.block_coarse_elements) hi.add(v);
    for (Id v : in.block_fine_elements) hi.add(v);
    f.info = hi.h;

    FineBlock b;
    f.element.resize(static_cast<size_t>(m.num_coarse_elements()));
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b);
      Hash he;
      for (Id n : b.n) he.add(n);
      he.add(b.first_element);
      he.add(static_cast<int>(b.block));
      for (Id g = 0; g < b.num_points(); ++g) he.add(b.node_id[g]), he.add(b.x[g]), he.add(b.y[g]), he.add(b.z[g]);
      for (Id c : b.conn) he.add(c);
      f.element[static_cast<size_t>(h)] = he.h;
    }

    Hash hn;
    NodeCursor nc(m);
    Id id = 0;
    Vec3 xyz{};
    while (nc.next(id, xyz)) hn.add(id), hn.add(xyz.x), hn.add(xyz.y), hn.add(xyz.z);
    f.nodes = hn.h;

    Hash hel;
    ElementCursor ec(m);
    FineElement e;
    while (ec.next(e)) {
      hel.add(e.id), hel.add(e.coarse_element), hel.add(static_cast<int>(e.block));
      for (int k = 0; k < e.num_nodes; ++k) hel.add(e.nodes[static_cast<size_t>(k)]);
      for (Id v : e.ijk) hel.add(v);
    }
    f.elements = hel.h;

    const MeshTables& t = m.tables();
    f.tables["topology/vertex_nodes"] = hash_table(t.vertex_nodes);
    f.tables["topology/edges"] = hash_table(t.edges);
    f.tables["topology/faces"] = hash_table(t.faces);
    f.tables["topology/elements"] = hash_table(t.elements);
    f.tables["topology/element_corners"] = hash_table(t.corners);
    f.tables["numbering/element_page_node"] = hash_vector(t.node_index);
    f.tables["numbering/element_page_element"] = hash_vector(t.element_index);
    f.tables["sheets (in memory)"] = hash_vector(m.sheet_intervals());
  }  // the mesh (and its cache's file handle) is gone before the sets are read

  const StoreSets sets = read_store_sets(path);
  Hash hs;
  for (const SideSet& s : sets.side_sets) {
    hs.add(s.id), hs.add(s.name), hs.add(static_cast<std::uint64_t>(s.element.size()));
    for (size_t i = 0; i < s.element.size(); ++i) hs.add(s.element[i]), hs.add(static_cast<int>(s.side[i]));
  }
  for (const NodeSet& s : sets.node_sets) {
    hs.add(s.id), hs.add(s.name), hs.add(static_cast<std::uint64_t>(s.vertex.size()));
    for (Id v : s.vertex) hs.add(v);
  }
  f.sets = hs.h;
  return f;
}

const char* outcome_name(Outcome o) {
  switch (o) {
    case Outcome::Identical: return "identical";
    case Outcome::Corrupt: return "corrupt";
    case Outcome::OtherError: return "other-error";
    case Outcome::DifferentData: return "DIFFERENT-DATA";
    case Outcome::PageNotRead: return "page-not-read";
  }
  return "?";
}

void Counts::add(const TrialResult& r) {
  ++trials;
  ++per_dataset[r.chunk.dataset];
  switch (r.outcome) {
    case Outcome::Identical: ++identical; break;
    case Outcome::Corrupt: ++corrupt, corrupt_named += r.named_page ? 1 : 0; break;
    case Outcome::OtherError: ++other; break;
    case Outcome::DifferentData: ++different; break;
    case Outcome::PageNotRead: ++not_read; break;
  }
}

Trials::Trials(const std::string& store, const std::string& scratch, std::uint64_t seed)
    : store_(store), scratch_(scratch), rng_(seed) {
  {
    std::ifstream in(store, std::ios::binary);
    if (!in) throw std::runtime_error(store + ": cannot read");
    bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  pristine_ = sweep(store);  // registers the LZ4 filter with HDF5 too
  chunks_ = list_chunks(store);
  for (const Chunk& c : chunks_) {
    if (c.address + c.size > bytes_.size()) throw std::runtime_error(store + ": chunk outside the file");
    chunk_bytes_ += c.size;
  }
  if (chunk_bytes_ == 0) throw std::runtime_error(store + ": no chunks");
}

TrialResult Trials::run_one() {
  TrialResult r;
  // A uniform byte over all chunk bytes = a chunk weighted by size, then a
  // uniform byte in it.
  std::uint64_t pick = std::uniform_int_distribution<std::uint64_t>(0, chunk_bytes_ - 1)(rng_);
  size_t k = 0;
  while (pick >= chunks_[k].size) pick -= chunks_[k].size, ++k;
  r.chunk = chunks_[k];
  r.byte = pick;
  r.mask = static_cast<std::uint8_t>(std::uniform_int_distribution<int>(1, 255)(rng_));
  {
    std::string copy = bytes_;
    copy[r.chunk.address + r.byte] = static_cast<char>(static_cast<std::uint8_t>(copy[r.chunk.address + r.byte]) ^ r.mask);
    std::ofstream out(scratch_, std::ios::binary | std::ios::trunc);
    out.write(copy.data(), static_cast<std::streamsize>(copy.size()));
    if (!out) throw std::runtime_error(scratch_ + ": cannot write");
  }
  const TrialResult c = check(scratch_, r.chunk);
  r.outcome = c.outcome, r.named_page = c.named_page, r.message = c.message;
  return r;
}

TrialResult Trials::check(const std::string& path, const Chunk& chunk) const {
  TrialResult r;
  r.chunk = chunk;
  try {
    const Fingerprint f = sweep(path);
    if (f == pristine_) {
      r.outcome = hdf5_reads_dataset(path, r.chunk.dataset) ? Outcome::Identical : Outcome::PageNotRead;
    } else {
      r.outcome = Outcome::DifferentData;
      r.message = f.first_difference(pristine_);
    }
  } catch (const Error& e) {
    r.message = e.what();
    if (e.kind() == ErrorKind::Corrupt) {
      r.outcome = Outcome::Corrupt;
      const std::string where = "dataset " + r.chunk.dataset + " page " + std::to_string(r.chunk.page) + ":";
      r.named_page = r.message.find(where) != std::string::npos;
    } else {
      r.outcome = Outcome::OtherError;
      r.message = "Error kind " + std::to_string(static_cast<int>(e.kind())) + ": " + r.message;
    }
  } catch (const std::exception& e) {
    r.outcome = Outcome::OtherError;
    r.message = std::string("std::exception: ") + e.what();
  } catch (...) {
    r.outcome = Outcome::OtherError;
    r.message = "unknown exception";
  }
  return r;
}

}  // namespace dicer::corruption
