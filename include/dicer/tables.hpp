#pragma once
// MeshTables: the coarse mesh compiled into the four row tables the fine
// mesh is regenerated from. The same tables live in memory right after
// `dice` and in the store's pages afterwards; FineMesh reads them through a
// TableCursor either way, so there is one code path (DESIGN.md invariant 2).
//
// Rows never straddle a page: a table of width W is paged in chunks of
// rows_per_page whole rows, so one pinned page serves a whole row.
//
// Layouts (int64 unless noted; ids 0-based; "offset" = first fine id):
//   vertices  [V x 3] float64  x, y, z
//   vertex_elements [V x 1]  lowest coarse element using the vertex
//   edges     [E x 8]  lo, hi, n (interval), node offset, sheet, lowest
//                      coarse element using the edge, geometric owner,
//                      first bounding row (-1: the nodes are not moved)
//   faces     [F x 12] v0..v3 (canonical corners), e0..e3 (sides: v0v1,
//                      v3v2, v0v3, v1v2), node offset, lowest element,
//                      geometric owner, first bounding row (-1: none)
//   elements  [H x W]  corners (8|4), edges (12|4), faces (6|1), element
//                      offset, cell node offset, block index, file id,
//                      flags = edge reversal bits | face codes << 12 (3 bits
//                      each) | kElemCurvedBit, n1, n2, n3
//   bounding  [N x 3]  the bounding fine arrays: for every node moved onto
//                      the CAD, tfi::bounding_code of x, y, z against its
//                      TFI prediction (an edge's n-1 interior nodes in
//                      canonical order, a face's (nu-1)(nv-1), u fastest)
//   vertex_owner [V x 2] int32 geometric entity (dim, tag), -1 unknown
// Cost: a row lookup is a pointer computation in memory, and a page-index
// compare plus (on a page change) one cache pin when paged.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "dicer/cache.hpp"
#include "dicer/types.hpp"

namespace dicer {

// Column positions.
enum EdgeCol : int {
  kEdgeLo = 0, kEdgeHi, kEdgeN, kEdgeNodeOffset, kEdgeSheet, kEdgeMinElement, kEdgeOwner, kEdgeBound, kEdgeWidth
};
enum FaceCol : int {
  kFaceV = 0, kFaceE = 4, kFaceNodeOffset = 8, kFaceMinElement = 9, kFaceOwner = 10, kFaceBound = 11, kFaceWidth = 12
};
// Element flag: some edge or face of the element has bounding nodes, so its
// hex interior must read them (elements without it take the fast path).
inline constexpr int kElemCurvedBit = 30;

// Geometric owner of an edge or face: the lowest-dimensional CAD entity it
// lies on, packed as dim << 32 | tag; -1 when none is known. dim 3 (a
// volume) means "interior": nothing to move.
inline std::int64_t pack_owner(int dim, int tag) {
  return (static_cast<std::int64_t>(dim) << 32) | static_cast<std::uint32_t>(tag);
}
inline int owner_dim(std::int64_t o) { return o < 0 ? -1 : static_cast<int>(o >> 32); }
inline int owner_tag(std::int64_t o) { return o < 0 ? -1 : static_cast<std::int32_t>(o & 0xffffffff); }

// Element row layout, which depends on the mode.
struct ElementLayout {
  int corners, edges, faces;
  int conn() const { return 0; }
  int edge() const { return corners; }
  int face() const { return corners + edges; }
  int elem_offset() const { return corners + edges + faces; }
  int cell_offset() const { return elem_offset() + 1; }
  int block() const { return elem_offset() + 2; }
  int file_id() const { return elem_offset() + 3; }
  int flags() const { return elem_offset() + 4; }
  int n() const { return elem_offset() + 5; }  // intervals along local i, j, k (k = 1 in surface mode)
  int width() const { return elem_offset() + 8; }
  static ElementLayout of(Mode m) { return m == Mode::Volume ? ElementLayout{8, 12, 6} : ElementLayout{4, 4, 1}; }
};

class TableCursor;

// One table: rows x width values of T, in memory or in pages of a cache.
template <class T>
class Table {
 public:
  Table() = default;
  Table(std::int64_t width, std::vector<T> data)  // in memory
      : width_(width), rows_(width ? static_cast<std::int64_t>(data.size()) / width : 0), mem_(std::move(data)) {}
  Table(std::int64_t width, std::int64_t rows, std::shared_ptr<PageCache> cache, std::uint32_t array,
        std::int64_t rows_per_page)  // paged
      : width_(width), rows_(rows), cache_(std::move(cache)), array_(array), rows_per_page_(rows_per_page) {}

  std::int64_t rows() const { return rows_; }
  std::int64_t width() const { return width_; }
  bool in_memory() const { return !cache_; }
  const std::vector<T>& memory() const { return mem_; }
  std::vector<T>& memory() { return mem_; }  // in-memory tables only (dicing)
  void reshape() { rows_ = width_ ? static_cast<std::int64_t>(mem_.size()) / width_ : 0; }  // after memory() grew
  std::int64_t rows_per_page() const { return rows_per_page_; }
  std::uint32_t array() const { return array_; }

  // Pointer to row i (width() values), valid until cur moves to another page.
  inline const T* row(std::int64_t i, TableCursor& cur) const;

 private:
  std::int64_t width_ = 0, rows_ = 0;
  std::vector<T> mem_;
  std::shared_ptr<PageCache> cache_;
  std::uint32_t array_ = 0;
  std::int64_t rows_per_page_ = 0;
};

// Caches the last two pages touched in one table (STYLE.md #4): rows on
// either cost no lookup, and a query that alternates between two pages (a
// hex's edges often straddle a page boundary) does not thrash. Move-only;
// holds a pin on each cached page, so a cursor pins at most 2 pages per
// table (8 for a MeshCursor).
class TableCursor {
 public:
  TableCursor() = default;
  TableCursor(TableCursor&&) noexcept = default;
  TableCursor& operator=(TableCursor&&) noexcept = default;
  void release() {
    for (auto& w : way_) w = Way{};
  }

 private:
  template <class T>
  friend class Table;
  struct Way {
    PageCache::Handle handle;
    std::int64_t page = -1;
    const std::uint8_t* data = nullptr;
  };
  Way way_[2];  // way_[0] most recently used
};

template <class T>
inline const T* Table<T>::row(std::int64_t i, TableCursor& cur) const {
  if (!cache_) return mem_.data() + i * width_;
  const std::int64_t page = i / rows_per_page_;
  auto* w = cur.way_;
  if (page != w[0].page) {
    if (page == w[1].page) {
      std::swap(w[0], w[1]);
    } else {
      w[1] = TableCursor::Way{};  // unpin the least recently used page before pinning the next
      w[1].handle = cache_->pin(PageKey{array_, static_cast<std::uint64_t>(page)});
      w[1].page = page;
      w[1].data = w[1].handle.data();
      std::swap(w[0], w[1]);
    }
  }
  return reinterpret_cast<const T*>(w[0].data) + (i - page * rows_per_page_) * width_;
}

struct MeshTables {
  Mode mode = Mode::Volume;
  std::shared_ptr<PageCache> cache;  // the pages behind paged tables (nullptr in memory)
  std::string origin;                // the store's path, named in errors ("" in memory)
  // Page indexes of paged tables (empty in memory): the searched column's
  // value in the first row of every page, so an id -> entity lookup reads
  // one page of the table. O(rows / rows_per_page) each.
  std::vector<std::int64_t> edge_index, face_index, elem_index, cell_index;
  Table<double> vertices;
  Table<std::int64_t> vertex_elements, edges, faces, elements;
  Table<std::int64_t> bounding;       // [N x 3], N = 0 without geometry
  Table<std::int32_t> vertex_owner;   // [V x 2]
  ElementLayout layout() const { return ElementLayout::of(mode); }
};

// One cursor per table: what a reader (a block, a query, a thread) carries.
struct MeshCursor {
  TableCursor vertices, vertex_elements, edges, faces, elements, bounding, vertex_owner;
  void release() {
    vertices.release(), vertex_elements.release(), edges.release(), faces.release(), elements.release();
    bounding.release(), vertex_owner.release();
  }
};

}  // namespace dicer
