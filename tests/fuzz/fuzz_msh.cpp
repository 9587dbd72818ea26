// libFuzzer target fuzz_msh: see fuzz_entries.hpp (run_msh) and scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "fuzz_entries.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dicer::fuzz::run_msh(data, size);
  return 0;
}
