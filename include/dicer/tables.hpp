#pragma once
// MeshTables: the coarse mesh compiled into the row tables the fine mesh is
// regenerated from. The same tables live in memory right after `dice` and
// in the store's pages afterwards; the fine mesh reads them through a
// TableCursor either way, so there is one code path (DESIGN.md invariant 2).
//
// Rows never straddle a page: a table of width W is paged in chunks of
// rows_per_page whole rows, so one pinned page serves a whole row.
//
// What a row holds is the business of the row layer (rows.hpp): read and
// write table rows only through its typed, validated views. The tables
// (ids 0-based, in the store's numbering, every entity in owner order):
//   vertex_nodes    [V x 3]  owner element, its corner slot, fine node id:
//                   a vertex's coordinates are its owner's corner there
//   edges           [E x 11], faces [F x 15], elements [H x W]: rows.hpp
//   corners         [H x 3c] float64  the element's c corner coordinates:
//                   the only coordinates of the coarse mesh, so that a
//                   sweep over straight elements reads nothing but
//                   `elements` and `corners`, each page once
//   bounds          [H x 6] float64  each element's box (rows.hpp ElementBounds)
//   bounding        [N x 3]  the bounding fine arrays (nodes moved onto the
//                   CAD or a curved coarse element), tfi::bounding_code
//   vertex_owner    [V x 2] int32 geometric entity (dim, tag), -1 unknown
// Cost: a row lookup is a pointer computation in memory, and a page-index
// compare plus (on a page change) one cache pin when paged.
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "dicer/cache.hpp"
#include "dicer/error.hpp"
#include "dicer/types.hpp"

namespace dicer {

// Geometric owner of an edge or face: the lowest-dimensional CAD entity it
// lies on, packed as dim << 32 | tag; -1 when none is known. dim 3 (a
// volume) means "interior": nothing to move.
inline std::int64_t pack_owner(int dim, int tag) {
  return (static_cast<std::int64_t>(dim) << 32) | static_cast<std::uint32_t>(tag);
}
inline int owner_dim(std::int64_t o) { return o < 0 ? -1 : static_cast<int>(o >> 32); }
inline int owner_tag(std::int64_t o) { return o < 0 ? -1 : static_cast<std::int32_t>(o & 0xffffffff); }

class TableCursor;

// Division by a divisor fixed at construction, as a multiply and two shifts
// (Granlund and Montgomery, "Division by invariant integers using
// multiplication", 1994, figure 4.1; exact for every 64-bit dividend). A
// paged table's row(i) divides i by its rows per page on every call, and
// a 64-bit idiv (40 cycles and more on the VM's Xeon) was a quarter of a
// row lookup, several of which make a random node(id) (bench/README.md,
// stop 43). libdivide does the same; one struct does not justify the
// dependency.
struct FixedDivisor {
  std::uint64_t magic = 1;  // the default divides by 1
  int shift1 = 0, shift2 = 0;
  FixedDivisor() = default;
  explicit FixedDivisor(std::uint64_t d) {
    DICER_ASSERT(d >= 1 && d < (std::uint64_t{1} << 62), "FixedDivisor: 1 <= d < 2^62");
    int l = 0;  // ceil(log2 d)
    while ((std::uint64_t{1} << l) < d) ++l;
    const unsigned __int128 excess = static_cast<unsigned __int128>((std::uint64_t{1} << l) - d) << 64;
    magic = static_cast<std::uint64_t>(excess / d) + 1;
    shift1 = l < 1 ? l : 1;
    shift2 = l > 1 ? l - 1 : 0;
  }
  std::uint64_t operator()(std::uint64_t n) const {
    const auto t = static_cast<std::uint64_t>((static_cast<unsigned __int128>(magic) * n) >> 64);
    return (t + ((n - t) >> shift1)) >> shift2;
  }
};

// One table: rows x width values of T, in memory or in pages of a cache.
template <class T>
class Table {
 public:
  Table() = default;
  Table(std::int64_t width, std::vector<T> data)  // in memory
      : width_(width), rows_(width ? static_cast<std::int64_t>(data.size()) / width : 0), mem_(std::move(data)) {}
  Table(std::int64_t width, std::int64_t rows, std::shared_ptr<PageCache> cache, std::uint32_t array,
        std::int64_t rows_per_page)  // paged
      : width_(width),
        rows_(rows),
        cache_(std::move(cache)),
        array_(array),
        rows_per_page_(rows_per_page),
        page_of_(rows_per_page > 0 ? FixedDivisor(static_cast<std::uint64_t>(rows_per_page)) : FixedDivisor()) {}

  std::int64_t rows() const { return rows_; }
  std::int64_t width() const { return width_; }
  bool in_memory() const { return !cache_; }
  const std::vector<T>& memory() const { return mem_; }
  // In-memory tables only (dicing). Drops the dense columns (they would go
  // stale): a search then reads the rows, slower but right.
  std::vector<T>& memory() {
    if (!cache_) derived_.clear(), dense_.clear();
    return mem_;
  }
  void reshape() { rows_ = width_ ? static_cast<std::int64_t>(mem_.size()) / width_ : 0; }  // after memory() grew
  std::int64_t rows_per_page() const { return rows_per_page_; }
  std::int64_t pages() const { return rows_per_page_ > 0 ? (rows_ + rows_per_page_ - 1) / rows_per_page_ : 0; }
  std::uint32_t array() const { return array_; }
  // Rows from row i to the end of its page (in memory: to the end of the
  // table): what one row() pointer covers.
  std::int64_t run(std::int64_t i) const { return cache_ ? rows_per_page_ - (i - page_of(i) * rows_per_page_) : rows_ - i; }

  // Pointer to row i (width() values), valid until cur moves to another page.
  inline const T* row(std::int64_t i, TableCursor& cur) const;

  // Paged tables: the cache keeps every page of this table once read
  // (PageCache::keep_resident), and row() finds such a page with one load,
  // without the cursor or a pin. The store decides which tables (store.hpp).
  void keep_resident() {
    DICER_ASSERT(cache_ && rows_per_page_ > 0, "keep_resident: a paged table");
    kept_ = cache_->keep_resident(array_);
  }
  bool kept_resident() const { return kept_ != nullptr; }

  // Columns the store's loader copies out of a page's rows into a dense
  // array after them (rows_per_page() values each, in the order of
  // derived_columns()): a search over one column of a page touches a few
  // cache lines of 1 KiB instead of one line in each ~520-byte row probed.
  // The page's bytes are exactly what the CRC checked, so a derived value
  // equals its row's.
  const std::vector<int>& derived_columns() const { return derived_; }
  // The store sets them with its loader's (the two must agree); paged only.
  void set_derived_columns(std::vector<int> columns) {
    DICER_ASSERT(cache_ && rows_per_page_ > 0, "derived columns: a paged table");
    derived_ = std::move(columns);
  }
  // In memory: copies the columns out of the rows into one dense array each
  // (8 bytes per row and column), once the table is complete (FineMesh's
  // constructor); memory() drops them again. Where the rows outgrow the
  // caches, a search over such a column hits L1/L2 where each probe of the
  // rows was a miss.
  void derive_in_memory(std::vector<int> columns) {
    DICER_ASSERT(!cache_, "derive_in_memory: an in-memory table");
    derived_ = std::move(columns);
    dense_.resize(derived_.size() * static_cast<size_t>(rows_));
    for (size_t k = 0; k < derived_.size(); ++k)
      for (std::int64_t i = 0; i < rows_; ++i)
        dense_[k * static_cast<size_t>(rows_) + static_cast<size_t>(i)] = mem_[static_cast<size_t>(i * width_ + derived_[k])];
  }
  // Pointer to the k-th derived column's value of row i; the values of the
  // rows after i on its page (in memory: to the table's end) follow (run(i)
  // in all). nullptr when the table has no derived columns (read
  // row(i)[column]). Valid like row().
  inline const T* derived(std::int64_t i, int k, TableCursor& cur) const;

 private:
  std::int64_t width_ = 0, rows_ = 0;
  std::vector<T> mem_;
  std::shared_ptr<PageCache> cache_;
  std::uint32_t array_ = 0;
  std::int64_t rows_per_page_ = 0;
  FixedDivisor page_of_;  // by rows_per_page_ (paged)
  // The page of row i (paged tables; i >= 0).
  std::int64_t page_of(std::int64_t i) const {
    return static_cast<std::int64_t>(page_of_(static_cast<std::uint64_t>(i)));
  }
  // The cache's page directory of a kept table (nullptr: not kept); owned
  // by the cache, which cache_ keeps alive.
  const std::atomic<const std::uint8_t*>* kept_ = nullptr;
  std::vector<int> derived_;
  std::vector<T> dense_;  // in memory: the derived columns, rows_ values each
};

// Caches the last two pages touched in one table (STYLE.md #4): rows on
// either cost no lookup, and a query that alternates between two pages (a
// hex's edges often straddle a page boundary) does not thrash. Move-only;
// holds a pin on each cached page, so a cursor pins at most 2 pages per
// table.
class TableCursor {
 public:
  TableCursor() = default;
  TableCursor(TableCursor&&) noexcept = default;
  TableCursor& operator=(TableCursor&&) noexcept = default;
  void release() {
    for (auto& w : way_) w = Way{};
    mru_ = 0;
  }

 private:
  template <class T>
  friend class Table;
  struct Way {
    PageCache::Handle handle;
    std::int64_t page = -1;
    const std::uint8_t* data = nullptr;
    const PageCache* cache = nullptr;  // whose page: one cursor may serve several meshes in turn
    Way() = default;
    // A moved-from way holds no page (its handle is empty): it must not hit.
    Way(Way&& o) noexcept
        : handle(std::move(o.handle)),
          page(std::exchange(o.page, -1)),
          data(std::exchange(o.data, nullptr)),
          cache(std::exchange(o.cache, nullptr)) {}
    Way& operator=(Way&& o) noexcept {
      handle = std::move(o.handle);
      page = std::exchange(o.page, -1), data = std::exchange(o.data, nullptr), cache = std::exchange(o.cache, nullptr);
      return *this;
    }
  };
  Way way_[2];
  int mru_ = 0;  // the most recently used way: an index flips, no handle moves
};

template <class T>
inline const T* Table<T>::row(std::int64_t i, TableCursor& cur) const {
  if (!cache_) return mem_.data() + i * width_;
  const std::int64_t page = page_of(i);
  // A kept page: no pin (a row past the table goes the cursor's way, which
  // throws).
  if (kept_ != nullptr && i >= 0 && i < rows_)
    if (const std::uint8_t* p = kept_[page].load(std::memory_order_acquire))
      return reinterpret_cast<const T*>(p) + (i - page * rows_per_page_) * width_;
  const PageCache* cache = cache_.get();
  TableCursor::Way* w = cur.way_ + cur.mru_;
  if (page != w->page || cache != w->cache) {
    cur.mru_ ^= 1;
    w = cur.way_ + cur.mru_;
    if (page != w->page || cache != w->cache) {
      // The least recently used page is unpinned before the next is pinned.
      w->page = -1, w->data = nullptr, w->cache = nullptr;
      cache_->pin_into(w->handle, PageKey{array_, static_cast<std::uint64_t>(page)});
      w->page = page;
      w->data = w->handle.data();
      w->cache = cache;
    }
  }
  return reinterpret_cast<const T*>(w->data) + (i - page * rows_per_page_) * width_;
}

template <class T>
inline const T* Table<T>::derived(std::int64_t i, int k, TableCursor& cur) const {
  if (derived_.empty()) return nullptr;
  DICER_ASSERT(k >= 0 && static_cast<size_t>(k) < derived_.size(), "derived column out of range");
  if (!cache_) return dense_.data() + static_cast<std::int64_t>(k) * rows_ + i;
  const std::int64_t at = i - page_of(i) * rows_per_page_;
  const T* page = row(i, cur) - at * width_;
  return page + rows_per_page_ * (width_ + k) + at;
}

// Coarse elements per group of the spatial index (MeshTables::group_bounds).
inline constexpr Id kBoundsGroup = 32;

// In memory, what the page index is to a store: for each bucket b of
// 2^shift ids, row[b] is the last element row whose first id (node_first or
// element_first) is <= b << shift, so the owner of id x lies in rows
// [row[x >> shift], row[(x >> shift) + 1]]: one or two rows where a search
// of the whole table probed a dozen. About two buckets per row (16 bytes
// per coarse element and column); built by FineMesh's constructor from the
// final rows (numbering.hpp build_id_guide).
struct IdGuide {
  int shift = 0;
  std::vector<std::int64_t> row;  // empty: no guide (a store, or tables still being built)
};

// A store's IdGuide, filled as it goes: when a search first lands on a page
// of a kept element table (Table::keep_resident), it fills the buckets
// whose start lies on that page from the page's rows, and later searches in
// those buckets go to their one or two rows as in memory, where the page
// index left an interpolation search over the page (a division and a
// dependent miss). row[b] < 0: not filled yet. Values depend only on the
// store's rows, so threads that fill a bucket at once write the same value
// (relaxed atomics). The same fill copies the page's rows' first ids into
// one array: the guided search reads its one or two rows' values there,
// where the page's own column lies at its end, one TLB entry and line per
// page (the in-memory tables' dense column is one array too). 24 bytes
// per coarse element, only for a kept table (at most a quarter of the
// cache budget, 536 bytes per element: about 1% of the budget).
struct LazyIdGuide {
  int shift = 0;
  std::size_t buckets = 0;
  std::unique_ptr<std::atomic<std::int64_t>[]> row;    // buckets entries
  std::unique_ptr<std::atomic<std::int64_t>[]> first;  // per row: its first id (-1: page not filled)
  std::unique_ptr<std::atomic<bool>[]> page_done;      // pages whose buckets are filled
};

struct MeshTables {
  Mode mode = Mode::Volume;
  std::shared_ptr<PageCache> cache;  // the pages behind paged tables (nullptr in memory)
  std::string origin;                // the store's path, named in errors ("" in memory)
  // What rows are validated against (rows.hpp): fine counts, sheets, blocks.
  Id fine_nodes = 0, fine_elements = 0, sheets = 0, blocks = 0;
  // Page indexes of paged tables (empty in memory): the first element's
  // first owned node id and first fine element id on every page of
  // `elements`, so an id -> element search reads one page. O(pages).
  std::vector<std::int64_t> node_index, element_index;
  IdGuide node_guide, element_guide;  // in memory (IdGuide)
  // A store's: the page index's guide, so that an id finds its page in one
  // or two probes instead of a binary search (numbering.hpp build_page_guide).
  IdGuide node_page_guide, element_page_guide;
  // A store whose element table is kept: the row guide of node ids (null
  // otherwise). Element ids have none: their search through the page index
  // prefetches the row it will land on (the index's interpolation names
  // it), which a guided search cannot, and measured 1.1x slower with one.
  std::shared_ptr<const LazyIdGuide> node_row_guide;
  Table<std::int64_t> vertex_nodes, edges, faces, elements;
  Table<double> corners;
  Table<double> bounds;               // [H x 6]
  // The spatial index: the union of the bounds of elements
  // [g kBoundsGroup, (g + 1) kBoundsGroup), 6 values (lo, hi) per group g,
  // always in memory (48 B per 32 coarse elements). Store order is a
  // Morton curve, so a group is a compact cluster.
  std::vector<double> group_bounds;
  Table<std::int64_t> bounding;       // [N x 3], N = 0 without moved nodes
  Table<std::int32_t> vertex_owner;   // [V x 2]
  Id num_vertices() const { return vertex_nodes.rows(); }
};

// One cursor per table: what a reader (a block, a query, a thread) carries.
struct MeshCursor {
  TableCursor vertex_nodes, edges, faces, elements, corners, bounds, bounding, vertex_owner;
  void release() {
    vertex_nodes.release(), edges.release(), faces.release(), elements.release();
    corners.release(), bounds.release(), bounding.release(), vertex_owner.release();
  }
};

}  // namespace dicer
