#pragma once
// Store: one HDF5 file holding everything needed to regenerate a fine mesh
// (coarse mesh, blocks and sets, topology with orientation codes, sheets,
// intervals). Layout: store/FORMAT.md; version: kStoreFormatVersion.
//
// Writes go to a temporary name in the same directory and are renamed into
// place only when complete, so an interrupted write never damages an
// existing store of the same name. Readers refuse unknown versions and
// inconsistent content with Error{Corrupt|BadInput}, naming file and dataset.
#include <cstdint>
#include <string>

#include "dicer/fine_mesh.hpp"

namespace dicer {

inline constexpr int kStoreFormatVersion = 1;
inline constexpr const char* kStoreFormatName = "dicer-store";

void write_store(const FineMesh& mesh, const std::string& path);

// Reads the whole coarse description into memory (O(coarse mesh)) and
// rebuilds the topology from it, checking it against the stored arrays.
FineMesh read_store(const std::string& path);

struct StoreSummary {
  int format_version = 0;
  std::uint64_t file_bytes = 0;
};
StoreSummary store_summary(const std::string& path);

}  // namespace dicer
