// Replays every input the fuzzers found (tests/fuzz/regressions/<target>/)
// and the seed corpus (tests/fuzz/corpus/<target>/) through the same entry
// functions the libFuzzer targets call (tests/fuzz/fuzz_entries.cpp). Each
// must return normally: the entries swallow dicer::Error and let anything
// else out (another exception, a FuzzBug from a failed oracle); sanitizer
// builds (DICER_SANITIZE) also catch memory errors here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "../fuzz/fuzz_entries.hpp"

namespace {

namespace fs = std::filesystem;

std::vector<fs::path> inputs(const std::string& target) {
  std::vector<fs::path> out;
  for (const char* kind : {"regressions", "corpus"}) {
    const fs::path dir = fs::path(DICER_SOURCE_DIR) / "tests" / "fuzz" / kind / target;
    if (!fs::is_directory(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::uint8_t> bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void replay(const std::string& target, void (*entry)(const std::uint8_t*, std::size_t), std::size_t at_least) {
  const auto files = inputs(target);
  EXPECT_GE(files.size(), at_least) << "seed corpus of " << target << " is missing";
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    const auto data = bytes_of(f);
    EXPECT_NO_THROW(entry(data.data(), data.size()));
  }
}

}  // namespace

TEST(FuzzRegressions, MshInputsReturnNormally) { replay("fuzz_msh", dicer::fuzz::run_msh, 3); }
TEST(FuzzRegressions, ExodusInputsReturnNormally) { replay("fuzz_exodus", dicer::fuzz::run_exodus, 4); }
TEST(FuzzRegressions, PageInputsReturnNormally) { replay("fuzz_page", dicer::fuzz::run_page, 3); }
TEST(FuzzRegressions, StoreInputsReturnNormally) { replay("fuzz_store", dicer::fuzz::run_store, 1); }
