// libFuzzer target fuzz_exodus: see fuzz_entries.hpp (run_exodus) and scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "fuzz_entries.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dicer::fuzz::run_exodus(data, size);
  return 0;
}
