// libFuzzer target fuzz_store: see fuzz_entries.hpp (run_store) and scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "fuzz_entries.hpp"

// Builds the pristine store (and lists its chunks) once, before fuzzing.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  dicer::fuzz::pristine_store_path();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dicer::fuzz::run_store(data, size);
  return 0;
}
