#pragma once
// Forging store pages for tests: decode a page, edit its bytes, re-encode it
// with a valid Fletcher32 and (optionally) a valid CRC-32 companion, so that
// only dicer's deeper checks (row validation, a sweep's comparison) can
// notice. Tests of the checks themselves use it; nothing else should.
#include <hdf5.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace dicer::test {

void forge_page(hid_t file, const std::string& dataset, hsize_t page,
                const std::function<void(std::vector<std::uint8_t>&)>& edit, bool keep_crc_valid);

// Copies `store` to `path` (replacing it), opens the copy read-write, runs
// edit(file) and closes it; returns path.
std::string edited_copy(const std::string& store, const std::string& path, const std::function<void(hid_t)>& edit);

}  // namespace dicer::test
