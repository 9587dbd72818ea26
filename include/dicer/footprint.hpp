#pragma once
// Footprint: what a diced mesh costs, next to what the same mesh would cost
// stored explicitly (float64 xyz per node + int64 node ids per element, the
// layout of an explicit HDF5 or Exodus mesh), raw and LZ4-compressed in
// 64 KiB pages like our own store.
//
// The explicit LZ4 size needs every fine node and element compressed, which
// is O(fine mesh) time (memory stays bounded). For big meshes a sample of
// evenly spaced pages is compressed and the ratio extrapolated; the report
// says which.
#include <cstdint>

#include "dicer/fine_mesh.hpp"

namespace dicer {

struct Footprint {
  std::uint64_t store_bytes = 0;            // bytes on disk of the store
  std::uint64_t open_resident_bytes = 0;    // resident after opening: metadata + pages read to open
  std::uint64_t query_resident_bytes = 0;   // plus the pages one block fill pins (one per table)
  std::uint64_t bounding_bytes = 0;         // bounding fine arrays on disk (StoreSummary; 0 without geometry)
  std::uint64_t explicit_raw_bytes = 0;     // 24 B per node + 8 B per element corner
  std::uint64_t explicit_lz4_bytes = 0;     // the same, LZ4 in 64 KiB pages (measured or extrapolated)
  double lz4_sampled_fraction = 1.0;        // 1: every page compressed
};

// `sample_pages_max`: compress at most this many 64 KiB pages of each kind
// (coordinates, connectivity); 0 means all of them.
Footprint measure_footprint(const FineMesh& mesh, std::uint64_t store_bytes, std::uint64_t sample_pages_max);

}  // namespace dicer
