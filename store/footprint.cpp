#include "dicer/footprint.hpp"

#include <lz4.h>

#include <algorithm>
#include <cstring>

#include "dicer/store.hpp"

namespace dicer {
namespace {

constexpr std::uint64_t kPage = 64 * 1024;

std::uint64_t lz4_size(const std::vector<std::uint8_t>& page, std::vector<char>& work) {
  work.resize(static_cast<size_t>(LZ4_compressBound(static_cast<int>(page.size()))));
  const int n = LZ4_compress_default(reinterpret_cast<const char*>(page.data()), work.data(),
                                     static_cast<int>(page.size()), static_cast<int>(work.size()));
  return static_cast<std::uint64_t>(n > 0 && static_cast<size_t>(n) < page.size() ? n : static_cast<int>(page.size()));
}

}  // namespace

Footprint measure_footprint(const FineMesh& mesh, std::uint64_t store_bytes, std::uint64_t sample_pages_max) {
  Footprint fp;
  fp.store_bytes = store_bytes;
  const int corners = mesh.corners();
  fp.explicit_raw_bytes = static_cast<std::uint64_t>(mesh.num_nodes()) * 24 +
                          static_cast<std::uint64_t>(mesh.num_elements()) * 8 * static_cast<std::uint64_t>(corners);
  if (auto cache = store_cache(mesh)) {
    fp.open_resident_bytes = cache->stats().resident_bytes + sizeof(MeshInfo) +
                             mesh.info().blocks.size() * (sizeof(Block) + 3 * sizeof(Id));
    fp.query_resident_bytes = fp.open_resident_bytes + 4 * kPage;
  }
  // Explicit coordinates: pages of 8192 interleaved xyz... rows of 24 bytes.
  const std::uint64_t nodes_per_page = kPage / 24, elems_per_page = kPage / (8 * static_cast<std::uint64_t>(corners));
  const std::uint64_t node_pages = (static_cast<std::uint64_t>(mesh.num_nodes()) + nodes_per_page - 1) / nodes_per_page;
  const std::uint64_t elem_pages = (static_cast<std::uint64_t>(mesh.num_elements()) + elems_per_page - 1) / elems_per_page;
  auto stride_of = [&](std::uint64_t pages) {
    return sample_pages_max == 0 || pages <= sample_pages_max ? std::uint64_t{1} : (pages + sample_pages_max - 1) / sample_pages_max;
  };
  const std::uint64_t ns = stride_of(node_pages), es = stride_of(elem_pages);
  std::vector<std::uint8_t> page;
  std::vector<char> work;
  std::uint64_t sampled_raw = 0, sampled_lz4 = 0, node_sampled = 0, elem_sampled = 0;
  std::uint64_t node_lz4 = 0, elem_lz4 = 0, node_raw = 0, elem_raw = 0;
  for (std::uint64_t p = 0; p < node_pages; p += ns) {
    const Id first = static_cast<Id>(p * nodes_per_page);
    const Id last = std::min<Id>(mesh.num_nodes(), first + static_cast<Id>(nodes_per_page));
    page.clear();
    NodeCursor c(mesh, first, last);
    Id id;
    Vec3 x;
    while (c.next(id, x)) {
      const double v[3] = {x.x, x.y, x.z};
      const auto* b = reinterpret_cast<const std::uint8_t*>(v);
      page.insert(page.end(), b, b + 24);
    }
    node_raw += page.size();
    node_lz4 += lz4_size(page, work);
    ++node_sampled;
  }
  for (std::uint64_t p = 0; p < elem_pages; p += es) {
    const Id first = static_cast<Id>(p * elems_per_page);
    const Id last = std::min<Id>(mesh.num_elements(), first + static_cast<Id>(elems_per_page));
    page.clear();
    ElementCursor c(mesh, first, last);
    FineElement el;
    while (c.next(el)) {
      const auto* b = reinterpret_cast<const std::uint8_t*>(el.nodes.data());
      page.insert(page.end(), b, b + 8 * corners);
    }
    elem_raw += page.size();
    elem_lz4 += lz4_size(page, work);
    ++elem_sampled;
  }
  // Extrapolate each kind by its own compression ratio.
  const double node_ratio = node_raw ? static_cast<double>(node_lz4) / static_cast<double>(node_raw) : 1.0;
  const double elem_ratio = elem_raw ? static_cast<double>(elem_lz4) / static_cast<double>(elem_raw) : 1.0;
  fp.explicit_lz4_bytes = static_cast<std::uint64_t>(node_ratio * static_cast<double>(mesh.num_nodes()) * 24 +
                                                     elem_ratio * static_cast<double>(mesh.num_elements()) * 8 * corners);
  sampled_raw = node_raw + elem_raw;
  sampled_lz4 = node_lz4 + elem_lz4;
  (void)sampled_lz4;
  fp.lz4_sampled_fraction = fp.explicit_raw_bytes ? std::min(1.0, static_cast<double>(sampled_raw) /
                                                                    static_cast<double>(fp.explicit_raw_bytes))
                                                  : 1.0;
  (void)node_sampled, (void)elem_sampled;
  return fp;
}

}  // namespace dicer
