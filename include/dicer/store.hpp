#pragma once
// Store: one HDF5 file holding everything needed to regenerate a fine mesh:
// the coarse mesh tables (tables.hpp: vertices, edges, faces, elements,
// which carry topology, orientation codes, intervals and numbering offsets),
// blocks, side and node sets, sheets, geometric owners and the bounding
// fine arrays (nodes moved onto the CAD, geometry.hpp, or onto quadratic edges and faces, quadratic.hpp). Layout: store/FORMAT.md; version kStoreFormatVersion.
//
// Every dataset is chunked; a chunk is a page of whole rows, compressed with
// HDF5 filter 32004 (LZ4) and checksummed with Fletcher32. read_store opens
// lazily: only O(blocks) metadata is read; every row comes through a
// PageCache with a fixed byte budget, so memory stays under the budget plus
// a small constant whatever the mesh size (and, per thread that has loaded
// a page, a stored page and a decoded one that the loader keeps for reuse).
//
// write_store writes every page once (H5Dwrite_chunk), to a temporary name
// in the same directory, renamed into place only when complete: an
// interrupted write never damages an existing store of the same name.
// Readers refuse unknown versions, damaged pages (checksum) and
// inconsistent content with Error{Unsupported|Corrupt|BadInput}, naming the
// file, the dataset and the page.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "dicer/cache.hpp"
#include "dicer/diced_rows.hpp"
#include "dicer/fine_mesh.hpp"

namespace dicer {

inline constexpr int kStoreFormatVersion = 8;
inline constexpr const char* kStoreFormatName = "dicer-store";
inline constexpr std::uint64_t kStorePageBytes = 64 * 1024;  // target page size (whole rows)

// Precondition: mesh was diced in this process (mesh.coarse() != nullptr).
// progress(done, total) is called after each page written, when given.
void write_store(const FineMesh& mesh, const std::string& path,
                 const std::function<void(std::int64_t, std::int64_t)>& progress = {});
// The same store from rows made as each page is written: memory is `rows`
// and one page per table, not the tables (diced_rows.hpp). The same bytes
// as write_store(std::move(rows).compile(), ...) but for the uuid.
void write_store(const DicedRows& rows, const std::string& path,
                 const std::function<void(std::int64_t, std::int64_t)>& progress = {});

struct StoreOptions {
  std::uint64_t cache_bytes = 64ull << 20;  // decoded pages resident, at most (>= 1 MiB)
  unsigned read_ahead_pages = 4;
  bool keep_coarse_tables = true;  // small coarse tables stay resident once read (read_store)
};

// Opens a store. With keep_coarse_tables, the coarse tables that fit
// together in a quarter of a budget of at least 32 MiB (in the order
// queries need them: elements, corners, bounds, edges, faces, vertices,
// vertex owners, bounding arrays) are kept resident once read
// (PageCache::keep_resident): random queries read their rows with one load
// and no pin. Those pages count toward the budget (CacheStats::kept_bytes);
// nothing is read for them in advance. A kept element table also gets a
// node-id guide (tables.hpp LazyIdGuide), 24 bytes per coarse element
// outside the budget. The element table takes about 540
// bytes per coarse hex: the default 64 MiB budget keeps it up to ~31,000
// coarse hexes, 256 MiB up to ~125,000.
FineMesh read_store(const std::string& path, const StoreOptions& options = {});

// The cache behind a FineMesh opened from a store (nullptr for in-memory meshes).
std::shared_ptr<PageCache> store_cache(const FineMesh& mesh);

// Side sets and node sets of a store, read on demand (O(sets) memory),
// in the store's element and vertex numbering.
struct StoreSets {
  std::vector<SideSet> side_sets;
  std::vector<NodeSet> node_sets;
};
// The sets of `mesh`, read from `path`: Error{Io} when the store there is
// no longer the one `mesh` was read from (another uuid: replaced since),
// so a command never mixes two stores. Use this one when the mesh is open.
StoreSets read_store_sets(const FineMesh& mesh, const std::string& path);
// Opens the store once more for its mesh first.
StoreSets read_store_sets(const std::string& path);

struct StoreSummary {
  int format_version = 0;
  std::uint64_t file_bytes = 0;
  std::uint64_t bounding_bytes = 0;   // stored (compressed) bytes of geometry/bounding + its CRCs
  std::int64_t bounding_nodes = 0;    // fine nodes moved (CAD or second order)
};
StoreSummary store_summary(const std::string& path);

}  // namespace dicer
