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
  // Explicit layout: xyz rows of 24 bytes, connectivity rows of 8 B per corner.
  const std::uint64_t nodes_per_page = kPage / 24, elems_per_page = kPage / (8 * static_cast<std::uint64_t>(corners));
  const std::uint64_t node_pages = (static_cast<std::uint64_t>(mesh.num_nodes()) + nodes_per_page - 1) / nodes_per_page;
  const std::uint64_t elem_pages = (static_cast<std::uint64_t>(mesh.num_elements()) + elems_per_page - 1) / elems_per_page;
  auto stride_of = [&](std::uint64_t pages) {
    return sample_pages_max == 0 || pages <= sample_pages_max ? std::uint64_t{1} : (pages + sample_pages_max - 1) / sample_pages_max;
  };
  // Compresses every stride-th page of one kind; returns (raw, lz4) bytes of
  // the pages it read. fill(first, last, page) appends the explicit bytes.
  std::vector<std::uint8_t> page;
  std::vector<char> work;
  auto sample = [&](std::uint64_t pages, std::uint64_t per_page, Id count, auto&& fill) {
    std::uint64_t raw = 0, lz4 = 0;
    for (std::uint64_t p = 0; p < pages; p += stride_of(pages)) {
      const Id first = static_cast<Id>(p * per_page);
      page.clear();
      fill(first, std::min<Id>(count, first + static_cast<Id>(per_page)), page);
      raw += page.size();
      lz4 += lz4_size(page, work);
    }
    return std::pair{raw, lz4};
  };
  const auto [node_raw, node_lz4] =
      sample(node_pages, nodes_per_page, mesh.num_nodes(), [&](Id first, Id last, std::vector<std::uint8_t>& out) {
        NodeCursor c(mesh, first, last);
        Id id;
        Vec3 x;
        while (c.next(id, x)) {
          const double v[3] = {x.x, x.y, x.z};
          const auto* b = reinterpret_cast<const std::uint8_t*>(v);
          out.insert(out.end(), b, b + 24);
        }
      });
  const auto [elem_raw, elem_lz4] =
      sample(elem_pages, elems_per_page, mesh.num_elements(), [&](Id first, Id last, std::vector<std::uint8_t>& out) {
        ElementCursor c(mesh, first, last);
        FineElement el;
        while (c.next(el)) {
          const auto* b = reinterpret_cast<const std::uint8_t*>(el.nodes.data());
          out.insert(out.end(), b, b + 8 * corners);
        }
      });
  // Extrapolate each kind by its own compression ratio.
  const double node_ratio = node_raw ? static_cast<double>(node_lz4) / static_cast<double>(node_raw) : 1.0;
  const double elem_ratio = elem_raw ? static_cast<double>(elem_lz4) / static_cast<double>(elem_raw) : 1.0;
  fp.explicit_lz4_bytes = static_cast<std::uint64_t>(node_ratio * static_cast<double>(mesh.num_nodes()) * 24 +
                                                     elem_ratio * static_cast<double>(mesh.num_elements()) * 8 * corners);
  fp.lz4_sampled_fraction = fp.explicit_raw_bytes ? std::min(1.0, static_cast<double>(node_raw + elem_raw) /
                                                                    static_cast<double>(fp.explicit_raw_bytes))
                                                  : 1.0;
  return fp;
}

}  // namespace dicer
