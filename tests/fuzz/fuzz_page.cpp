// libFuzzer target fuzz_page: see fuzz_entries.hpp (run_page) and scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "fuzz_entries.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dicer::fuzz::run_page(data, size);
  return 0;
}
