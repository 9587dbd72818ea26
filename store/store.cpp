// The store file: write (page by page, temp + rename) and lazy, paged read
// (see FORMAT.md).
#include "dicer/store.hpp"

#include <sys/random.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>

#include "dicer/atomic_output.hpp"
#include "dicer/diced_rows.hpp"
#include "dicer/error.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"
#include "hdf5_lock.hpp"
#include "hdf5_file.hpp"
#include "lz4_filter.hpp"

namespace dicer {
namespace {

// Serial HDF5 is not thread-safe: every HDF5 call goes under the process lock.
std::recursive_mutex& hdf5_mutex() { return hdf5_lock(); }

std::int64_t rows_per_page(std::int64_t width, std::size_t elem) {
  return std::max<std::int64_t>(1, static_cast<std::int64_t>(kStorePageBytes / (static_cast<std::uint64_t>(width) * elem)));
}

template <class T>
hid_t h5_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_IEEE_F64LE;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_STD_I64LE;
  else if constexpr (std::is_same_v<T, std::int32_t>) return H5T_STD_I32LE;
  else if constexpr (std::is_same_v<T, std::int8_t>) return H5T_STD_I8LE;
  else return H5T_STD_U8LE;
}

// Writes rows x width values as a chunked, LZ4 + Fletcher32 dataset, one
// H5Dwrite_chunk per page: every page is written once, never re-read.
// The CRC-32 of every decoded page of a dataset, as its companion dataset
// (1-D uint32, LZ4 + Fletcher32 like the rest; read whole at open: O(pages)).
// Entries per chunk of a `_crc` companion (its "pages").
constexpr hsize_t kCrcChunk = 16384;

void write_crcs(const h5::File& f, const std::string& name, const std::vector<std::uint32_t>& crcs) {
  hsize_t dims[1] = {crcs.size()}, chunk[1] = {std::max<hsize_t>(1, std::min<hsize_t>(crcs.size(), kCrcChunk))};
  h5::Handle space(H5Screate_simple(1, dims, nullptr), H5Sclose);
  h5::Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (!space || !dcpl || H5Pset_chunk(dcpl.get(), 1, chunk) < 0)
    throw Error(ErrorKind::Io, f.name() + ": " + name + ": cannot set up dataset");
  store::add_page_filters(dcpl.get());
  h5::Handle ds(H5Dcreate2(f.id(), name.c_str(), H5T_STD_U32LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                H5Dclose);
  // Flushed before the close, so a full disk fails here (see create_file_id).
  if (!ds || (!crcs.empty() && H5Dwrite(ds.get(), H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, crcs.data()) < 0) ||
      H5Dflush(ds.get()) < 0)
    throw Error(ErrorKind::Io, f.name() + ": " + name + ": write failed: " + f.write_failure());
}

// Pages written so far and in all (for write_store's progress callback).
struct WriteProgress {
  std::int64_t done = 0, total = 0;
  const std::function<void(std::int64_t, std::int64_t)>* fn = nullptr;
  // write_store's hold on the HDF5 lock, let go while the callback runs:
  // the callback may wait for a lock whose holder waits for HDF5 (Python's
  // GIL, held by a thread closing a store: a deadlock).
  std::unique_lock<std::recursive_mutex>* hdf5 = nullptr;
};
thread_local WriteProgress* g_write_progress = nullptr;

// fill(first, n, out) writes rows first .. first + n - 1 into out (n rows
// of `width` values), a page at a time: the rows need not exist anywhere
// else (DicedRows makes them as they are written).
template <class T, class Fill>
void write_paged(const h5::File& f, const std::string& name, std::int64_t rows, std::int64_t width, const Fill& fill) {
  const int rank = 2;
  // Ids, offsets and bounding codes are small numbers in 8-byte words: the
  // byte shuffle groups their zero high bytes, which LZ4 then squeezes
  // (the store shrinks by a third). Coordinates do not gain from it.
  const bool shuffle = std::is_integral_v<T> && sizeof(T) == 8;
  // Small datasets get one page of their own size, not a padded 64 KiB one.
  const std::int64_t rpp = std::min(rows_per_page(width, sizeof(T)), std::max<std::int64_t>(rows, 1));
  hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(width)};
  hsize_t maxdims[2] = {H5S_UNLIMITED, static_cast<hsize_t>(width)};
  hsize_t chunk[2] = {static_cast<hsize_t>(rpp), static_cast<hsize_t>(width)};
  h5::Handle space(H5Screate_simple(rank, dims, maxdims), H5Sclose);
  h5::Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (!space || !dcpl || H5Pset_chunk(dcpl.get(), rank, chunk) < 0)
    throw Error(ErrorKind::Io, f.name() + ": " + name + ": cannot set up dataset");
  if (shuffle && H5Pset_shuffle(dcpl.get()) < 0) throw Error(ErrorKind::Io, f.name() + ": " + name + ": cannot add shuffle");
  store::add_page_filters(dcpl.get());
  h5::Handle ds(H5Dcreate2(f.id(), name.c_str(), h5_type<T>(), space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                H5Dclose);
  if (!ds) throw Error(ErrorKind::Io, f.name() + ": " + name + ": cannot create dataset: " + f.write_failure());
  std::vector<T> values(static_cast<size_t>(rpp * width));
  const std::span<const std::uint8_t> page(reinterpret_cast<const std::uint8_t*>(values.data()), values.size() * sizeof(T));
  std::vector<std::uint32_t> crcs;
  std::vector<std::uint8_t> shuffled;
  for (std::int64_t first = 0; first < rows; first += rpp) {
    const std::int64_t n = std::min(rpp, rows - first);
    std::fill(values.begin(), values.end(), T{});  // a partial last page is padded
    fill(first, n, values.data());
    if (shuffle) store::shuffle_bytes(page, sizeof(T), shuffled);
    const std::vector<std::uint8_t> stored = store::encode_page(shuffle ? std::span<const std::uint8_t>(shuffled) : page);
    crcs.push_back(store::page_crc(page));
    hsize_t offset[2] = {static_cast<hsize_t>(first), 0};
    if (H5Dwrite_chunk(ds.get(), H5P_DEFAULT, 0, offset, stored.size(), stored.data()) < 0)
      throw Error(ErrorKind::Io, f.name() + ": " + name + ": writing page " + std::to_string(first / rpp) +
                                     " failed: " + f.write_failure());
    if (g_write_progress && g_write_progress->fn && *g_write_progress->fn) {
      ++g_write_progress->done;
      std::unique_lock<std::recursive_mutex>* held = g_write_progress->hdf5;
      if (held) held->unlock();
      struct Relock {
        std::unique_lock<std::recursive_mutex>* l;
        ~Relock() {
          if (l) l->lock();
        }
      } relock{held};
      (*g_write_progress->fn)(g_write_progress->done, std::max(g_write_progress->total, g_write_progress->done));
    }
  }
  if (H5Dflush(ds.get()) < 0) throw Error(ErrorKind::Io, f.name() + ": " + name + ": write failed: " + f.write_failure());
  write_crcs(f, name + store::kPageCrcSuffix, crcs);
}

template <class T>
void write_paged(const h5::File& f, const std::string& name, const std::vector<T>& v, std::int64_t width = 1) {
  write_paged<T>(f, name, static_cast<std::int64_t>(v.size()) / width, width, [&](std::int64_t first, std::int64_t n, T* out) {
    std::memcpy(out, v.data() + first * width, static_cast<size_t>(n * width) * sizeof(T));
  });
}

void write_strings(h5::File& f, const std::string& base, const std::vector<std::string>& names) {
  std::vector<std::int8_t> chars;
  std::vector<std::int64_t> off{0};
  for (const auto& s : names) {
    chars.insert(chars.end(), s.begin(), s.end());
    off.push_back(static_cast<std::int64_t>(chars.size()));
  }
  write_paged(f, base + "_chars", chars);
  write_paged(f, base + "_offset", off);
}

// ------------------------------------------------------------------ reading

// A paged dataset of the open store: what the cache's loader reads from.
struct PagedDataset {
  std::string name;
  h5::Handle ds;
  std::int64_t rows = 0, width = 0, rows_per_page = 0;
  std::size_t elem = 0;
  bool shuffled = false;           // HDF5 byte shuffle before LZ4 (every 8-byte integer table)
  std::vector<std::uint32_t> crc;  // CRC-32 of every decoded page (companion dataset)
  std::vector<int> derived;        // columns copied after the rows of each page (Table::derived)
  std::size_t rows_bytes() const { return static_cast<std::size_t>(rows_per_page * width) * elem; }
  // A decoded page's size (what the cache's budget counts): its rows, and
  // room for the derived columns from the start, so that the vector the
  // page ends in never grows past it.
  std::size_t page_bytes() const { return rows_bytes() + derived.size() * static_cast<std::size_t>(rows_per_page) * elem; }
};

struct OpenStore {
  h5::File file;
  std::vector<PagedDataset> arrays;

  // Reads and decodes one page: H5Dread_chunk (no HDF5 filters, no HDF5
  // chunk cache) then our LZ4 + checksum decode.
  std::uint64_t load(PageKey key, PageBytes& out) {
    if (key.array >= arrays.size()) throw Error(ErrorKind::Usage, file.path() + ": no paged array " + std::to_string(key.array));
    const PagedDataset& a = arrays[key.array];
    const std::string what = file.path() + ": dataset " + a.name + " page " + std::to_string(key.page);
    // The stored bytes, and a shuffled page's bytes before the unshuffle,
    // in buffers each loading thread keeps (a stored page and a page, held
    // until the thread ends: the sweeping threads, the read-ahead worker, a
    // caller's): only `out`, which the cache keeps, is allocated per page,
    // and no buffer is zero-filled (PageBytes). Three allocations and
    // memsets per page before: about a tenth of a cold random query
    // (bench/README.md, stop 41).
    thread_local PageBytes raw, packed;
    {
      std::lock_guard lock(hdf5_mutex());
      h5::quiet();  // this may be the cache's read-ahead thread
      hsize_t offset[2] = {key.page * static_cast<hsize_t>(a.rows_per_page), 0};
      hsize_t stored = 0;
      if (H5Dget_chunk_storage_size(a.ds.get(), offset, &stored) < 0 || stored == 0)
        throw Error(ErrorKind::Corrupt, what + ": page is missing");
      if (stored > 4 * kStorePageBytes + (1u << 20)) throw Error(ErrorKind::Corrupt, what + ": page size field is implausible");
      raw.resize(static_cast<size_t>(stored));
      std::uint32_t mask = 0;
      if (H5Dread_chunk(a.ds.get(), H5P_DEFAULT, offset, &mask, raw.data()) < 0)
        throw Error(ErrorKind::Corrupt, what + ": HDF5 cannot read the page (truncated or damaged file)");
      if (mask != 0) throw Error(ErrorKind::Corrupt, what + ": page was stored with filters skipped");
    }
    const size_t rows_bytes = a.rows_bytes();
    out.resize(a.page_bytes());  // PageBytes: not zero-filled; every byte is written below
#ifndef NDEBUG
    // Debug builds (the sanitizer stage too) poison the page first, so that
    // a byte this loader fails to write shows as garbage, not as the bytes
    // a freed page left in the same heap chunk.
    std::fill(out.begin(), out.end(), std::uint8_t{0xa5});
#endif
    const std::span<std::uint8_t> rows_out(out.data(), rows_bytes);
    if (a.shuffled) {
      packed.resize(rows_bytes);
      store::decode_page_into(raw, packed, what);
      store::unshuffle_bytes(packed, a.elem, rows_out.data());
    } else {
      store::decode_page_into(raw, rows_out, what);
    }
    if (key.page >= a.crc.size() || store::page_crc(rows_out) != a.crc[key.page])
      throw Error(ErrorKind::Corrupt, what + ": page checksum (CRC-32) mismatch: the page is damaged");
    if (!a.derived.empty()) {
      DICER_ASSERT(a.elem == sizeof(std::int64_t), "derived columns: 8-byte tables");
      std::int64_t* rows = reinterpret_cast<std::int64_t*>(out.data());
      for (size_t k = 0; k < a.derived.size(); ++k) {
        std::int64_t* col = rows + (a.width + static_cast<std::int64_t>(k)) * a.rows_per_page;
        for (std::int64_t r = 0; r < a.rows_per_page; ++r) col[r] = rows[r * a.width + a.derived[k]];
      }
    }
    return raw.size();
  }
};

// The pipeline dice writes: [shuffle,] LZ4 (32004), Fletcher32. HDF5 runs
// this pipeline itself when it reads a companion, so nothing else may be in
// it (no filter of HDF5's own with parameters from the file). Returns
// whether the byte shuffle is in it.
bool check_pipeline(hid_t dcpl, const std::string& what, bool may_shuffle) {
  const int n = H5Pget_nfilters(dcpl);
  H5Z_filter_t id[3] = {-1, -1, -1};
  for (int i = 0; i < n && i < 3; ++i)
    id[i] = H5Pget_filter2(dcpl, static_cast<unsigned>(i), nullptr, nullptr, nullptr, 0, nullptr, nullptr);
  const bool shuffled = may_shuffle && n == 3 && id[0] == H5Z_FILTER_SHUFFLE;
  const int at = shuffled ? 1 : 0;
  if (n != at + 2 || id[at] != store::kLz4FilterId || id[at + 1] != H5Z_FILTER_FLETCHER32)
    throw Error(ErrorKind::Corrupt, what + " does not have the store's filter pipeline (" +
                                        (may_shuffle ? "[shuffle,] " : "") + "LZ4 32004, Fletcher32)");
  return shuffled;
}

// dice writes every page, so a dataset whose shape needs more (or fewer)
// chunks than the file holds lies about its size: refused before that size
// allocates anything.
void check_chunk_count(hid_t ds, hsize_t pages, const std::string& what, hsize_t rows) {
  h5::Handle space(H5Dget_space(ds), H5Sclose);
  hsize_t n = 0;
  if (!space || H5Dget_num_chunks(ds, space.get(), &n) < 0)
    throw Error(ErrorKind::Corrupt, what + ": its page index cannot be read (damaged)");
  if (n != pages)
    throw Error(ErrorKind::Corrupt, what + " declares " + std::to_string(rows) + " rows in " + std::to_string(pages) +
                                        " pages, but the file holds " + std::to_string(n) + " pages");
}

// Row count of a dataset of the store, for those no attribute declares.
std::int64_t dataset_rows(const h5::File& f, const std::string& name) {
  std::lock_guard lock(hdf5_mutex());
  hsize_t dims[2] = {0, 0};
  h5::open_chunked_dataset(f, name, 2, dims);
  if (dims[0] > (hsize_t{1} << 48))
    throw Error(ErrorKind::Corrupt, f.path() + ": dataset " + name + " declares " + std::to_string(dims[0]) + " rows");
  return static_cast<std::int64_t>(dims[0]);
}

template <class T>
std::uint32_t open_paged(OpenStore& s, const std::string& name, std::int64_t width, std::int64_t want_rows) {
  std::lock_guard lock(hdf5_mutex());  // the read-ahead thread may be loading pages
  const std::string what = s.file.path() + ": dataset " + name;
  PagedDataset a;
  a.name = name;
  hsize_t dims[2] = {0, 0}, chunk[2] = {0, 0};
  a.ds = h5::open_chunked_dataset(s.file, name, 2, dims);
  h5::Handle dcpl(H5Dget_create_plist(a.ds.get()), H5Pclose);
  h5::Handle type(H5Dget_type(a.ds.get()), H5Tclose);
  if (!dcpl || !type || H5Pget_chunk(dcpl.get(), 2, chunk) != 2)
    throw Error(ErrorKind::Corrupt, what + " is not a 2-D chunked dataset");
  if (static_cast<std::int64_t>(dims[1]) != width || want_rows < 0 || dims[0] != static_cast<hsize_t>(want_rows))
    throw Error(ErrorKind::Corrupt, what + " has shape " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
                                        ", expected " + std::to_string(want_rows) + " x " + std::to_string(width));
  if (chunk[1] != dims[1] || chunk[0] == 0 || chunk[0] * dims[1] * sizeof(T) > 4 * kStorePageBytes)
    throw Error(ErrorKind::Corrupt, what + " has an unexpected page shape");
  if (H5Tget_size(type.get()) != sizeof(T) || H5Tequal(type.get(), h5_type<T>()) <= 0)
    throw Error(ErrorKind::Corrupt, what + " has an unexpected element type");
  a.shuffled = check_pipeline(dcpl.get(), what, true);
  const hsize_t pages = (dims[0] + chunk[0] - 1) / chunk[0];
  check_chunk_count(a.ds.get(), pages, what, dims[0]);
  a.rows = static_cast<std::int64_t>(dims[0]);
  a.width = width;
  a.rows_per_page = static_cast<std::int64_t>(chunk[0]);
  a.elem = sizeof(T);
  {
    const std::string crc_name = name + store::kPageCrcSuffix;
    const std::string crc_what = s.file.path() + ": dataset " + crc_name;
    hsize_t cdims[1] = {0}, cchunk[1] = {0};
    h5::Handle cds = h5::open_chunked_dataset(s.file, crc_name, 1, cdims);
    if (cdims[0] != pages) throw Error(ErrorKind::Corrupt, crc_what + " does not have one entry per page of " + name);
    h5::Handle cdcpl(H5Dget_create_plist(cds.get()), H5Pclose);
    h5::Handle ctype(H5Dget_type(cds.get()), H5Tclose);
    // HDF5 converts while it reads: a companion of another type (a changed
    // size byte) would be converted into a buffer sized for uint32.
    if (!cdcpl || !ctype || H5Tequal(ctype.get(), H5T_STD_U32LE) <= 0)
      throw Error(ErrorKind::Corrupt, crc_what + " has an unexpected element type (not uint32)");
    if (H5Pget_chunk(cdcpl.get(), 1, cchunk) != 1 || cchunk[0] == 0 || cchunk[0] > kCrcChunk)
      throw Error(ErrorKind::Corrupt, crc_what + " has an unexpected page shape");
    check_pipeline(cdcpl.get(), crc_what, false);
    check_chunk_count(cds.get(), (pages + cchunk[0] - 1) / cchunk[0], crc_what, pages);
    a.crc.resize(static_cast<size_t>(pages));
    // Read page by page of the companion (write_crcs' chunks) so that a
    // damaged one is named like any other page.
    h5::Handle csp(H5Dget_space(cds.get()), H5Sclose);
    for (hsize_t at = 0, page = 0; at < pages; at += cchunk[0], ++page) {
      hsize_t start[1] = {at}, count[1] = {std::min<hsize_t>(cchunk[0], pages - at)};
      h5::Handle fsp(H5Scopy(csp.get()), H5Sclose);
      h5::Handle msp(H5Screate_simple(1, count, nullptr), H5Sclose);
      if (!fsp || !msp || H5Sselect_hyperslab(fsp.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0 ||
          H5Dread(cds.get(), H5T_NATIVE_UINT32, msp.get(), fsp.get(), H5P_DEFAULT, a.crc.data() + at) < 0)
        throw Error(ErrorKind::Corrupt, crc_what + " page " + std::to_string(page) + ": cannot be read (damaged)");
    }
  }
  s.arrays.push_back(std::move(a));
  return static_cast<std::uint32_t>(s.arrays.size() - 1);
}

// Small datasets read whole (O(blocks)).
template <class T>
std::vector<T> read_small(OpenStore& s, const std::shared_ptr<PageCache>& cache, const std::string& name,
                          std::int64_t rows, std::int64_t width = 1) {
  const std::uint32_t id = open_paged<T>(s, name, width, rows);  // rows checked against the file first
  const PagedDataset& a = s.arrays[id];
  cache->set_array_pages(id, static_cast<std::uint64_t>((a.rows + a.rows_per_page - 1) / a.rows_per_page));
  Table<T> t(width, a.rows, cache, id, a.rows_per_page);
  TableCursor cur;
  std::vector<T> out(static_cast<size_t>(rows * width));
  for (std::int64_t i = 0; i < rows; ++i) std::copy_n(t.row(i, cur), width, out.data() + i * width);
  return out;
}

// A store holds hard links only: a soft, external or user-defined link
// could point outside the file (a FIFO would block every command), and
// HDF5 follows them when a path is opened. Checked before any path is.
struct LinkScan {
  std::string bad;
  H5L_type_t type = H5L_TYPE_HARD;
  std::uint64_t count = 0;
};
constexpr std::uint64_t kMaxLinks = 100000;

herr_t scan_link(hid_t, const char* name, const H5L_info_t* info, void* data) {
  auto* scan = static_cast<LinkScan*>(data);
  if (info->type != H5L_TYPE_HARD || ++scan->count > kMaxLinks) {
    scan->bad = name ? name : "";
    scan->type = info->type;
    return 1;
  }
  return 0;
}

void check_links(const h5::File& f) {
  LinkScan scan;
  const herr_t rc = H5Lvisit(f.id(), H5_INDEX_NAME, H5_ITER_NATIVE, scan_link, &scan);
  if (rc < 0) throw Error(ErrorKind::Corrupt, f.path() + ": its groups cannot be listed (damaged)");
  if (rc == 0) return;
  if (scan.count > kMaxLinks)
    throw Error(ErrorKind::BadInput, f.path() + ": more than " + std::to_string(kMaxLinks) + " objects (not a dicer store)");
  const char* kind = scan.type == H5L_TYPE_SOFT       ? "a soft link"
                     : scan.type == H5L_TYPE_EXTERNAL ? "an external link (to another file)"
                                                      : "a user-defined link";
  throw Error(ErrorKind::Corrupt, f.path() + ": " + scan.bad + " is " + kind +
                                      "; a store is one file of plain objects, and it is not followed");
}

bool is_store_uuid(const std::string& u) {
  return u.size() == 32 && u.find_first_not_of("0123456789abcdef") == std::string::npos;
}

// 128 random bits from the kernel, as 32 lowercase hex digits.
std::string new_store_uuid() {
  unsigned char b[16];
  std::size_t got = 0;
  while (got < sizeof b) {
    const ssize_t n = ::getrandom(b + got, sizeof b - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw Error(ErrorKind::Io, std::string("cannot draw a store uuid: ") + std::strerror(errno));
    got += static_cast<std::size_t>(n);
  }
  static const char* kHex = "0123456789abcdef";
  std::string s;
  for (unsigned char c : b) s += kHex[c >> 4], s += kHex[c & 15];
  return s;
}

// Opens the store file and reads its root attributes: format, version,
// uuid, mode, source and the declared counts (each checked against its
// dataset when that is opened, before it sizes anything).
struct StoreHeader {
  MeshInfo info;
  std::int64_t bounding_nodes = 0;
};

std::shared_ptr<OpenStore> open_store(const std::string& path, StoreHeader& h) {
  std::lock_guard lock(hdf5_mutex());
  store::register_lz4_filter();
  auto s = std::make_shared<OpenStore>();
  s->file = h5::File::open_read(path);
  check_links(s->file);
  if (H5Aexists(s->file.id(), "format") <= 0 || s->file.read_attr_string("format") != kStoreFormatName)
    throw Error(ErrorKind::BadInput, path + ": not a dicer store (format attribute missing or wrong)");
  const std::int64_t version = s->file.read_attr_int("format_version");
  if (version != kStoreFormatVersion)
    throw Error(ErrorKind::Unsupported, path + ": store format version " + std::to_string(version) +
                                            " is not known to this dicer (it reads version " +
                                            std::to_string(kStoreFormatVersion) + ")");
  MeshInfo& info = h.info;
  info.uuid = s->file.read_attr_string("uuid");
  if (!is_store_uuid(info.uuid))
    throw Error(ErrorKind::Corrupt, path + ": attribute uuid \"" + info.uuid + "\" is not 32 lowercase hex digits");
  const std::string mode = s->file.read_attr_string("mode");
  if (mode != "volume" && mode != "surface") throw Error(ErrorKind::Corrupt, path + ": unknown mode \"" + mode + "\"");
  info.mode = mode == "volume" ? Mode::Volume : Mode::Surface;
  info.source = s->file.read_attr_string("source");
  // Optional: absent when diced without a CAD (and before it was recorded).
  if (H5Aexists(s->file.id(), "geometry_source") > 0) info.geometry = s->file.read_attr_string("geometry_source");
  // Optional (absent before second-order input: a first-order source).
  if (H5Aexists(s->file.id(), "source_order") > 0) {
    const std::int64_t order = s->file.read_attr_int("source_order");
    if (order != 1 && order != 2)
      throw Error(ErrorKind::Corrupt, path + ": attribute source_order is " + std::to_string(order) + ", not 1 or 2");
    info.source_order = static_cast<int>(order);
  }
  auto count = [&](const char* name) {
    const std::int64_t v = s->file.read_attr_int(name);
    if (v < 0) throw Error(ErrorKind::Corrupt, path + ": attribute " + name + " is negative");
    return v;
  };
  info.coarse_vertices = count("coarse_vertices"), info.coarse_edges = count("coarse_edges");
  info.coarse_faces = count("coarse_faces"), info.coarse_elements = count("coarse_elements");
  info.sheets = count("sheets"), info.nodes = count("fine_nodes"), info.elements = count("fine_elements");
  h.bounding_nodes = count("bounding_nodes");
  return s;
}
}  // namespace

namespace {

// What a store holds, whoever makes its rows: a FineMesh's tables in memory
// or a DicedRows' rows made as each page is written. One writer for both, so
// the two stores are the same bytes but for the uuid.
template <class T>
struct PagedRows {
  std::int64_t rows = 0, width = 1;
  std::function<void(std::int64_t first, std::int64_t n, T* out)> fill;
};

template <class T>
void paged(const h5::File& f, const std::string& name, const PagedRows<T>& r) {
  write_paged<T>(f, name, r.rows, r.width, r.fill);
}

template <class T>
PagedRows<T> rows_of(const Table<T>& t) {
  return {t.rows(), t.width(), [&t](std::int64_t first, std::int64_t n, T* out) {
            std::memcpy(out, t.memory().data() + first * t.width(), static_cast<size_t>(n * t.width()) * sizeof(T));
          }};
}

struct StoreContent {
  const MeshInfo* info = nullptr;
  const CoarseMesh* coarse = nullptr;
  const std::vector<Id>* sheet_intervals = nullptr;
  const std::vector<SheetGrading>* sheet_gradings = nullptr;
  PagedRows<std::int64_t> vertex_nodes, edges, faces, elements, bounding;
  PagedRows<double> corners, bounds;
  const std::vector<std::int32_t>* vertex_owner = nullptr;
  std::vector<double> group_bounds;
  // (node_first, element_first) of element row h.
  std::function<std::array<Id, 2>(Id h)> firsts;
};

void write_content(const StoreContent& c, const std::string& path,
                   const std::function<void(std::int64_t, std::int64_t)>& progress) {
  const MeshInfo& info = *c.info;
  AtomicOutput out(path);
  const std::string& tmp = out.temp_path();
  std::unique_lock lock(hdf5_mutex());
  store::register_lz4_filter();
  WriteProgress wp;
  wp.fn = &progress;
  wp.hdf5 = &lock;
  auto pages = [](std::int64_t rows, std::int64_t width, std::size_t elem) {
    const std::int64_t rpp = rows_per_page(width, elem);
    return (rows + rpp - 1) / rpp;
  };
  auto table_pages = [&](const auto& r) { return pages(r.rows, r.width, 8); };
  wp.total = table_pages(c.vertex_nodes) + table_pages(c.edges) + table_pages(c.faces) + table_pages(c.elements) +
             table_pages(c.corners) + table_pages(c.bounds) + table_pages(c.bounding) +
             pages(static_cast<std::int64_t>(c.vertex_owner->size() / 2), 2, 4) + 40;
  g_write_progress = &wp;
  struct Reset {
    ~Reset() { g_write_progress = nullptr; }
  } reset_progress;
  {
    {
      h5::File f = h5::File::create(tmp, path);
      f.write_attr("format", std::string(kStoreFormatName));
      f.write_attr("format_version", kStoreFormatVersion);
      f.write_attr("uuid", new_store_uuid());
      f.write_attr("mode", std::string(mode_name(info.mode)));
      f.write_attr("source", info.source);
      f.write_attr("source_order", static_cast<std::int64_t>(info.source_order));
      if (!info.geometry.empty()) f.write_attr("geometry_source", info.geometry);
      f.write_attr("coarse_vertices", info.coarse_vertices);
      f.write_attr("coarse_edges", info.coarse_edges);
      f.write_attr("coarse_faces", info.coarse_faces);
      f.write_attr("coarse_elements", info.coarse_elements);
      f.write_attr("sheets", info.sheets);
      f.write_attr("fine_nodes", info.nodes);
      f.write_attr("fine_elements", info.elements);
      f.write_attr("bounding_nodes", c.bounding.rows);
      f.write_attr("page_bytes", static_cast<std::int64_t>(kStorePageBytes));
      for (const char* g : {"coarse", "topology", "sheets", "numbering", "geometry", "sets", "index"}) f.group(g);
      write_paged(f, "coarse/vertex_file_id", c.coarse->vertex_file_id);
      paged(f, row_dataset(RowTable::VertexNodes), c.vertex_nodes);
      write_paged(f, "geometry/vertex_owner", *c.vertex_owner, 2);
      paged(f, "geometry/bounding", c.bounding);
      paged(f, row_dataset(RowTable::Edges), c.edges);
      paged(f, row_dataset(RowTable::Faces), c.faces);
      paged(f, row_dataset(RowTable::Elements), c.elements);
      paged(f, row_dataset(RowTable::Corners), c.corners);
      paged(f, row_dataset(RowTable::Bounds), c.bounds);
      write_paged(f, "index/group_bounds", c.group_bounds);
      // Page index of the elements table: the first row's first owned node
      // and first fine element on every page (id -> element reads one page).
      {
        const std::int64_t rpp = std::min(rows_per_page(c.elements.width, 8), std::max<std::int64_t>(c.elements.rows, 1));
        std::vector<std::int64_t> node_first, element_first;
        for (std::int64_t r = 0; r < c.elements.rows; r += rpp) {
          const std::array<Id, 2> firsts = c.firsts(r);
          node_first.push_back(firsts[0]), element_first.push_back(firsts[1]);
        }
        write_paged(f, "numbering/element_page_node", node_first);
        write_paged(f, "numbering/element_page_element", element_first);
      }
      write_paged(f, "sheets/sheet_interval", *c.sheet_intervals);
      {
        // Per sheet: spacing kind, ratio (IEEE bits), start node's file id.
        std::vector<std::int64_t> grading;
        for (const SheetGrading& g : *c.sheet_gradings)
          grading.insert(grading.end(), {static_cast<std::int64_t>(g.grading.kind),
                                         std::bit_cast<std::int64_t>(g.grading.ratio), g.start});
        if (grading.empty())  // a mesh built without dice(): every sheet equally spaced
          for (Id q = 0; q < info.sheets; ++q) grading.insert(grading.end(), {0, std::bit_cast<std::int64_t>(1.0), -1});
        write_paged(f, "sheets/sheet_grading", grading, 3);
      }
      std::vector<std::int64_t> block_id;
      std::vector<std::string> block_name;
      for (const auto& b : info.blocks) block_id.push_back(b.id), block_name.push_back(b.name);
      write_paged(f, "coarse/block_id", block_id);
      write_strings(f, "coarse/block_name", block_name);
      write_paged(f, "coarse/block_coarse_elements", info.block_coarse_elements);
      write_paged(f, "coarse/block_fine_elements", info.block_fine_elements);
      // Side and node sets: ids, names, CSR offsets, members (element, side) / vertex.
      std::vector<std::int64_t> ss_id, ss_off{0}, ss_member, ns_id, ns_off{0}, ns_vert;
      std::vector<std::string> ss_name, ns_name;
      for (const auto& s : c.coarse->side_sets) {
        ss_id.push_back(s.id), ss_name.push_back(s.name);
        for (size_t i = 0; i < s.element.size(); ++i) ss_member.push_back(s.element[i]), ss_member.push_back(s.side[i]);
        ss_off.push_back(static_cast<std::int64_t>(ss_member.size() / 2));
      }
      for (const auto& s : c.coarse->node_sets) {
        ns_id.push_back(s.id), ns_name.push_back(s.name);
        ns_vert.insert(ns_vert.end(), s.vertex.begin(), s.vertex.end());
        ns_off.push_back(static_cast<std::int64_t>(ns_vert.size()));
      }
      write_paged(f, "sets/side_set_id", ss_id), write_paged(f, "sets/side_set_offset", ss_off);
      write_paged(f, "sets/side_set_member", ss_member, 2);
      write_strings(f, "sets/side_set_name", ss_name);
      write_paged(f, "sets/node_set_id", ns_id), write_paged(f, "sets/node_set_offset", ns_off);
      write_paged(f, "sets/node_set_vertex", ns_vert);
      write_strings(f, "sets/node_set_name", ns_name);
      if (H5Fflush(f.id(), H5F_SCOPE_GLOBAL) < 0) throw Error(ErrorKind::Io, path + ": cannot write: " + f.write_failure());
      f.close();
    }
    out.commit();  // an exception before this leaves the temporary to `out`, which removes it
  }
}

}  // namespace

void write_store(const FineMesh& mesh, const std::string& path,
                 const std::function<void(std::int64_t, std::int64_t)>& progress) {
  const CoarseMesh* coarse = mesh.coarse();
  if (!coarse) throw Error(ErrorKind::Usage, path + ": write_store needs a mesh diced in this process");
  const MeshTables& t = mesh.tables();
  StoreContent c;
  c.info = &mesh.info();
  c.coarse = coarse;
  c.sheet_intervals = &mesh.sheet_intervals();
  c.sheet_gradings = &mesh.sheet_gradings();
  c.vertex_nodes = rows_of(t.vertex_nodes), c.edges = rows_of(t.edges), c.faces = rows_of(t.faces);
  c.elements = rows_of(t.elements), c.bounding = rows_of(t.bounding);
  c.corners = rows_of(t.corners), c.bounds = rows_of(t.bounds);
  c.vertex_owner = &t.vertex_owner.memory();
  c.group_bounds = t.group_bounds;
  MeshCursor cur;
  const RowReader R(t, cur);
  c.firsts = [&](Id h) { return std::array<Id, 2>{R.node_first(h), R.element_first(h)}; };
  write_content(c, path, progress);
}

void write_store(const DicedRows& rows, const std::string& path,
                 const std::function<void(std::int64_t, std::int64_t)>& progress) {
  const MeshInfo& info = rows.info();
  const Mode mode = info.mode;
  StoreContent c;
  c.info = &info;
  c.coarse = &rows.coarse();
  c.sheet_intervals = &rows.sheet_intervals();
  c.sheet_gradings = &rows.sheet_gradings();
  // Each table's rows straight into the page being written.
  auto table = [&](RowTable kind, Id count, auto row) {
    const std::int64_t w = row_width(kind, mode);
    return PagedRows<std::int64_t>{count, w, [&rows, mode, w, row](std::int64_t first, std::int64_t n, std::int64_t* out) {
                                     for (std::int64_t i = 0; i < n; ++i) encode_row(mode, (rows.*row)(first + i), out + i * w);
                                   }};
  };
  c.vertex_nodes = table(RowTable::VertexNodes, info.coarse_vertices, &DicedRows::vertex);
  c.edges = table(RowTable::Edges, info.coarse_edges, &DicedRows::edge);
  c.faces = table(RowTable::Faces, info.coarse_faces, &DicedRows::face);
  c.elements = table(RowTable::Elements, info.coarse_elements, &DicedRows::element);
  c.bounding = {0, 3, [](std::int64_t, std::int64_t, std::int64_t*) {}};
  const int nc = rows.coarse().corners_per_element();
  auto bounds_of = [&rows, nc](Id h) {
    Vec3 xyz[8];
    rows.corners(h, xyz);
    return corner_bounds(xyz, nc);
  };
  const std::int64_t wc = row_width(RowTable::Corners, mode), wb = row_width(RowTable::Bounds, mode);
  c.corners = {info.coarse_elements, wc, [&rows, mode, wc](std::int64_t first, std::int64_t n, double* out) {
                 Vec3 xyz[8];
                 for (std::int64_t i = 0; i < n; ++i) rows.corners(first + i, xyz), encode_corners(mode, xyz, out + i * wc);
               }};
  c.bounds = {info.coarse_elements, wb, [bounds_of, wb](std::int64_t first, std::int64_t n, double* out) {
                for (std::int64_t i = 0; i < n; ++i) encode_bounds(bounds_of(first + i), out + i * wb);
              }};
  const std::vector<std::int32_t> owners = rows.vertex_owners();
  c.vertex_owner = &owners;
  c.group_bounds = group_bounds(info.coarse_elements, bounds_of);
  c.firsts = [&rows](Id h) {
    const ElementRow r = rows.element(h);
    return std::array<Id, 2>{r.node_first, r.element_first};
  };
  write_content(c, path, progress);
}

namespace {
// read_store's kept tables (store.hpp). Why: a random query reads a row of
// two or three of them, and a pin of each page is two atomic read-modify-
// writes (pin, release) on a line that every thread's pins of that page
// share; a kept page is one plain load. Stop 43 in bench/README.md measures
// it. Why a quarter of a budget of at least 32 MiB: the rest must hold a
// sweep's or an export's pinned and read-ahead pages, which smaller budgets
// need all of (the cache's read-ahead headroom rule, cache.hpp).
void keep_small_tables(MeshTables& tab, const OpenStore& s, std::uint64_t budget) {
  if (budget < (32ull << 20)) return;
  std::uint64_t room = budget / 4;
  auto keep = [&](auto& table) {
    if (table.rows() == 0) return;
    const std::uint64_t bytes = static_cast<std::uint64_t>(table.pages()) * s.arrays[table.array()].page_bytes();
    if (bytes > room) return;
    room -= bytes;
    table.keep_resident();
  };
  keep(tab.elements), keep(tab.corners), keep(tab.bounds), keep(tab.edges), keep(tab.faces);
  keep(tab.vertex_nodes), keep(tab.vertex_owner), keep(tab.bounding);
}
}  // namespace

FineMesh read_store(const std::string& path, const StoreOptions& options) {
  if (options.cache_bytes < (1u << 20))
    throw Error(ErrorKind::Usage, "cache budget " + std::to_string(options.cache_bytes) + " bytes is too small (at least 1 MiB)");
  StoreHeader header;
  auto s = open_store(path, header);
  MeshInfo info = std::move(header.info);
  const std::int64_t bounding_nodes = header.bounding_nodes;
  std::unique_lock lock(hdf5_mutex());

  PageCache::Options co;
  co.budget_bytes = options.cache_bytes;
  co.read_ahead_pages = options.read_ahead_pages;
  // The loader keeps the file open for as long as the cache lives.
  auto cache = std::make_shared<PageCache>(
      [s](PageKey key, PageBytes& out) { return s->load(key, out); }, co);
  MeshTables tab;
  tab.mode = info.mode;
  tab.cache = cache;
  tab.origin = path;
  tab.fine_nodes = info.nodes, tab.fine_elements = info.elements, tab.sheets = info.sheets;
  auto paged = [&](auto tag, const std::string& name, std::int64_t width, std::int64_t rows) {
    using T = decltype(tag);
    const std::uint32_t id = open_paged<T>(*s, name, width, rows);
    const PagedDataset& a = s->arrays[id];
    cache->set_array_pages(id, static_cast<std::uint64_t>((a.rows + a.rows_per_page - 1) / a.rows_per_page));
    return Table<T>(width, a.rows, cache, id, a.rows_per_page);
  };
  const Mode m = info.mode;
  tab.vertex_nodes = paged(std::int64_t{}, row_dataset(RowTable::VertexNodes), row_width(RowTable::VertexNodes, m),
                           info.coarse_vertices);
  tab.edges = paged(std::int64_t{}, row_dataset(RowTable::Edges), row_width(RowTable::Edges, m), info.coarse_edges);
  tab.faces = paged(std::int64_t{}, row_dataset(RowTable::Faces), row_width(RowTable::Faces, m), info.coarse_faces);
  tab.elements = paged(std::int64_t{}, row_dataset(RowTable::Elements), row_width(RowTable::Elements, m),
                       info.coarse_elements);
  // The id -> element searches' columns, dense (RowReader::search_first):
  // the loader lays them out, the table reads them.
  s->arrays[tab.elements.array()].derived = element_search_columns(m);
  tab.elements.set_derived_columns(s->arrays[tab.elements.array()].derived);
  tab.corners = paged(double{}, row_dataset(RowTable::Corners), row_width(RowTable::Corners, m), info.coarse_elements);
  tab.bounds = paged(double{}, row_dataset(RowTable::Bounds), row_width(RowTable::Bounds, m), info.coarse_elements);
  tab.bounding = paged(std::int64_t{}, "geometry/bounding", 3, bounding_nodes);
  tab.vertex_owner = paged(std::int32_t{}, "geometry/vertex_owner", 2, info.coarse_vertices);
  if (options.keep_coarse_tables) keep_small_tables(tab, *s, options.cache_bytes);
  // Small metadata, read whole now (O(blocks + pages)); pages come through
  // the cache so they are checked like every other page.
  lock.unlock();  // the loader takes the HDF5 lock itself
  auto index = [&](const char* name) {
    auto v = read_small<std::int64_t>(*s, cache, name, tab.elements.pages());
    for (size_t i = 1; i < v.size(); ++i)
      if (v[i] < v[i - 1]) throw Error(ErrorKind::Corrupt, path + ": " + name + " is not increasing");
    return v;
  };
  tab.node_index = index("numbering/element_page_node");
  tab.element_index = index("numbering/element_page_element");
  // The spatial index (48 B per kBoundsGroup elements): finite boxes.
  tab.group_bounds = read_small<double>(*s, cache, "index/group_bounds",
                                        6 * ((info.coarse_elements + kBoundsGroup - 1) / kBoundsGroup));
  for (size_t g = 0; g < tab.group_bounds.size(); g += 6)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(tab.group_bounds[g + d]) || !std::isfinite(tab.group_bounds[g + 3 + d]) ||
          tab.group_bounds[g + d] > tab.group_bounds[g + 3 + d])
        throw Error(ErrorKind::Corrupt, path + ": index/group_bounds row " + std::to_string(g / 6) +
                                            ": not finite or lower above upper");
  const std::int64_t nblocks = dataset_rows(s->file, "coarse/block_id");
  if (nblocks > (1 << 24)) throw Error(ErrorKind::Corrupt, path + ": dataset coarse/block_id holds an implausible " +
                                                               std::to_string(nblocks) + " blocks");
  tab.blocks = nblocks;
  const auto block_id = read_small<std::int64_t>(*s, cache, "coarse/block_id", nblocks);
  const auto name_off = read_small<std::int64_t>(*s, cache, "coarse/block_name_offset", nblocks + 1);
  if (name_off.front() != 0 || name_off.back() < 0 || name_off.back() > (1 << 24))
    throw Error(ErrorKind::Corrupt, path + ": coarse/block_name_offset is inconsistent");
  const auto chars = read_small<std::int8_t>(*s, cache, "coarse/block_name_chars", name_off.back());
  info.block_coarse_elements = read_small<std::int64_t>(*s, cache, "coarse/block_coarse_elements", nblocks);
  info.block_fine_elements = read_small<std::int64_t>(*s, cache, "coarse/block_fine_elements", nblocks);
  for (std::int64_t b = 0; b < nblocks; ++b) {
    if (name_off[b] > name_off[b + 1]) throw Error(ErrorKind::Corrupt, path + ": coarse/block_name_offset is not increasing");
    info.blocks.push_back({block_id[b], std::string(chars.begin() + name_off[b], chars.begin() + name_off[b + 1])});
  }
  {  // Ids name blocks (exporters write them as Exodus block ids, MSH physical tags): one each.
    std::vector<std::int64_t> ids(block_id.begin(), block_id.end());
    std::sort(ids.begin(), ids.end());
    if (const auto d = std::adjacent_find(ids.begin(), ids.end()); d != ids.end())
      throw Error(ErrorKind::Corrupt, path + ": coarse/block_id: block id " + std::to_string(*d) + " appears twice");
  }
  // The counts the tables determine: the last element ends the node and
  // element ids, the blocks add up to the elements (one page read).
  {
    __int128 coarse = 0, fine = 0;
    for (std::int64_t b = 0; b < nblocks; ++b) coarse += info.block_coarse_elements[b], fine += info.block_fine_elements[b];
    if (coarse != info.coarse_elements || fine != info.elements)
      throw Error(ErrorKind::Corrupt, path + ": per-block element counts do not add up to coarse_elements / fine_elements");
    MeshCursor cur;
    const RowReader R(tab, cur);
    Id nodes_end = 0, elements_end = 0;
    if (info.coarse_elements > 0) {
      const ElementRow last = R.element(info.coarse_elements - 1);
      const bool vol = m == Mode::Volume;
      nodes_end = vol ? last.cell_node + ids::cell_nodes(last.n) : last.cell_node + ids::face_nodes(last.n[0], last.n[1]);
      elements_end = last.element_first + last.n[0] * last.n[1] * last.n[2];
    }
    if (nodes_end != info.nodes || elements_end != info.elements)
      throw Error(ErrorKind::Corrupt, path + ": attributes fine_nodes / fine_elements (" + std::to_string(info.nodes) +
                                          " / " + std::to_string(info.elements) + ") disagree with the tables (" +
                                          std::to_string(nodes_end) + " / " + std::to_string(elements_end) + ")");
  }
  const auto sheet_interval = read_small<std::int64_t>(*s, cache, "sheets/sheet_interval", info.sheets);
  for (Id n : sheet_interval)
    if (n < 1 || n >= kMaxElementPoints) throw Error(ErrorKind::Corrupt, path + ": sheets/sheet_interval holds " + std::to_string(n));
  const auto sheet_grading = read_small<std::int64_t>(*s, cache, "sheets/sheet_grading", info.sheets, 3);
  std::vector<SheetGrading> gradings(static_cast<size_t>(info.sheets));
  for (size_t q = 0; q < gradings.size(); ++q) {
    const std::int64_t* r = &sheet_grading[3 * q];
    gradings[q] = {{static_cast<tfi::Spacing>(r[0] & 3), false, std::bit_cast<double>(r[1])}, r[2]};
    if (r[0] < 0 || r[0] > 2 || !tfi::grading_ok(gradings[q].grading) || r[2] < -1 ||
        (r[2] >= 0) != (gradings[q].grading.kind == tfi::Spacing::Geometric))
      throw Error(ErrorKind::Corrupt, path + ": sheets/sheet_grading row " + std::to_string(q) + " is not a grading");
  }
  FineMesh mesh(std::move(info), std::move(tab));
  mesh.set_sheet_intervals(sheet_interval);
  mesh.set_sheet_gradings(std::move(gradings));
  return mesh;
}

std::shared_ptr<PageCache> store_cache(const FineMesh& mesh) { return mesh.tables().cache; }

StoreSets read_store_sets(const std::string& path) {
  return read_store_sets(read_store(path, StoreOptions{4ull << 20, 0}), path);
}

StoreSets read_store_sets(const FineMesh& mesh, const std::string& path) {
  // Opened like a store (version checks included), then read through the
  // same cache machinery so every page is checksummed. The uuid ties it to
  // `mesh`: a store replaced since the mesh was read is not mixed into it.
  StoreHeader header;
  auto s = open_store(path, header);
  if (header.info.uuid != mesh.info().uuid)
    throw Error(ErrorKind::Io, path + ": the store was replaced after its mesh was read (uuid " + header.info.uuid +
                                   ", the mesh's " + (mesh.info().uuid.empty() ? "none" : mesh.info().uuid) +
                                   "); run the command again");
  auto cache = std::make_shared<PageCache>(
      [s](PageKey key, PageBytes& out) { return s->load(key, out); }, PageCache::Options{4ull << 20, 0, false});
  auto rows_of = [&](const std::string& name) { return dataset_rows(s->file, name); };
  auto strings = [&](const std::string& base, std::int64_t n) {
    const auto off = read_small<std::int64_t>(*s, cache, base + "_offset", n + 1);
    if (off.front() != 0 || off.back() < 0) throw Error(ErrorKind::Corrupt, path + ": " + base + "_offset is inconsistent");
    const auto chars = read_small<std::int8_t>(*s, cache, base + "_chars", off.back());
    std::vector<std::string> out;
    for (std::int64_t i = 0; i < n; ++i) {
      if (off[i] < 0 || off[i] > off[i + 1] || off[i + 1] > off.back())
        throw Error(ErrorKind::Corrupt, path + ": " + base + "_offset is inconsistent");
      out.emplace_back(chars.begin() + off[i], chars.begin() + off[i + 1]);
    }
    return out;
  };
  auto csr = [&](const std::vector<std::int64_t>& off, std::int64_t members, const std::string& name) {
    if (off.empty() || off.front() != 0 || off.back() != members)
      throw Error(ErrorKind::Corrupt, path + ": " + name + " offsets are inconsistent");
    for (size_t i = 1; i < off.size(); ++i)
      if (off[i] < off[i - 1]) throw Error(ErrorKind::Corrupt, path + ": " + name + " offsets are not increasing");
  };
  // Ids name sets (Exodus set ids, MSH physical tags): one each.
  auto unique = [&](std::vector<std::int64_t> ids, const std::string& name) {
    std::sort(ids.begin(), ids.end());
    if (const auto d = std::adjacent_find(ids.begin(), ids.end()); d != ids.end())
      throw Error(ErrorKind::Corrupt, path + ": " + name + ": set id " + std::to_string(*d) + " appears twice");
  };
  StoreSets out;
  const std::int64_t nss = rows_of("sets/side_set_id"), nns = rows_of("sets/node_set_id");
  const auto ss_id = read_small<std::int64_t>(*s, cache, "sets/side_set_id", nss);
  unique(ss_id, "sets/side_set_id");
  const auto ss_off = read_small<std::int64_t>(*s, cache, "sets/side_set_offset", nss + 1);
  const auto ss_names = strings("sets/side_set_name", nss);
  const std::int64_t nsm = rows_of("sets/side_set_member");
  csr(ss_off, nsm, "sets/side_set");
  const std::uint32_t sm = open_paged<std::int64_t>(*s, "sets/side_set_member", 2, nsm);
  cache->set_array_pages(sm, static_cast<std::uint64_t>((nsm + s->arrays[sm].rows_per_page - 1) / s->arrays[sm].rows_per_page));
  Table<std::int64_t> members(2, nsm, cache, sm, s->arrays[sm].rows_per_page);
  TableCursor cur;
  const std::int64_t nh = mesh.num_coarse_elements();
  for (std::int64_t k = 0; k < nss; ++k) {
    SideSet set{ss_id[k], ss_names[k], {}, {}};
    for (std::int64_t i = ss_off[k]; i < ss_off[k + 1]; ++i) {
      const std::int64_t* r = members.row(i, cur);
      if (r[0] < 0 || r[0] >= nh || r[1] < 0 || r[1] > 5)
        throw Error(ErrorKind::Corrupt, path + ": side set " + std::to_string(ss_id[k]) + ": entry out of range");
      set.element.push_back(r[0]);
      set.side.push_back(static_cast<std::int8_t>(r[1]));
    }
    out.side_sets.push_back(std::move(set));
  }
  const auto ns_id = read_small<std::int64_t>(*s, cache, "sets/node_set_id", nns);
  unique(ns_id, "sets/node_set_id");
  const auto ns_off = read_small<std::int64_t>(*s, cache, "sets/node_set_offset", nns + 1);
  const auto ns_names = strings("sets/node_set_name", nns);
  const std::int64_t nnv = rows_of("sets/node_set_vertex");
  csr(ns_off, nnv, "sets/node_set");
  const auto verts = read_small<std::int64_t>(*s, cache, "sets/node_set_vertex", nnv);
  for (std::int64_t k = 0; k < nns; ++k) {
    NodeSet set{ns_id[k], ns_names[k], {verts.begin() + ns_off[k], verts.begin() + ns_off[k + 1]}};
    for (Id v : set.vertex)
      if (v < 0 || v >= mesh.info().coarse_vertices)
        throw Error(ErrorKind::Corrupt, path + ": node set " + std::to_string(ns_id[k]) + ": vertex out of range");
    out.node_sets.push_back(std::move(set));
  }
  return out;
}

StoreSummary store_summary(const std::string& path) {
  std::lock_guard lock(hdf5_mutex());
  h5::File f = h5::File::open_read(path);
  check_links(f);
  StoreSummary s;
  const std::int64_t version = f.read_attr_int("format_version");
  s.format_version = static_cast<int>(std::clamp<std::int64_t>(version, -1, 1 << 30));
  if (s.format_version == kStoreFormatVersion) {
    s.bounding_nodes = f.read_attr_int("bounding_nodes");
    hsize_t dims[2];
    for (const auto& [name, rank] : {std::pair{"geometry/bounding", 2}, std::pair{"geometry/bounding_crc", 1}})
      s.bounding_bytes += H5Dget_storage_size(h5::open_chunked_dataset(f, name, rank, dims).get());
  }
  s.file_bytes = f.file_bytes();
  return s;
}

}  // namespace dicer
