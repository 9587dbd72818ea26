// corrupt_trials STORE TRIALS SEED [--verbose]
//
// Flips one random byte (xor a random nonzero mask) in one random page of
// STORE per trial (pages weighted by stored size), reads the damaged copy
// back through the public API and classifies the outcome (corruption.hpp).
// Prints the counts; exit 1 if any trial returned different data without
// an error, 2 on a usage or setup problem.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include <unistd.h>

#include "corruption.hpp"

int main(int argc, char** argv) {
  using namespace dicer::corruption;
  if (argc < 4 || argc > 5 || (argc == 5 && std::string(argv[4]) != "--verbose")) {
    std::fprintf(stderr, "usage: corrupt_trials STORE TRIALS SEED [--verbose]\n");
    return 2;
  }
  const std::string store = argv[1];
  const long trials = std::strtol(argv[2], nullptr, 10);
  const unsigned long long seed = std::strtoull(argv[3], nullptr, 10);
  const bool verbose = argc == 5;
  if (trials < 1) {
    std::fprintf(stderr, "corrupt_trials: TRIALS must be a positive integer\n");
    return 2;
  }
  namespace fs = std::filesystem;
  const fs::path scratch = fs::temp_directory_path() / ("corrupt_trials." + std::to_string(::getpid()) + ".dice.h5");
  try {
    Trials t(store, scratch.string(), seed);
    std::printf("store %s: %zu pages in %zu-byte file, %llu page bytes; seed %llu\n", store.c_str(), t.chunks().size(),
                static_cast<size_t>(fs::file_size(store)), static_cast<unsigned long long>(t.chunk_bytes()), seed);
    Counts c;
    for (long i = 0; i < trials; ++i) {
      const TrialResult r = t.run_one();
      c.add(r);
      const bool notable = r.outcome == Outcome::DifferentData || r.outcome == Outcome::OtherError ||
                           (r.outcome == Outcome::Corrupt && !r.named_page);
      if (verbose || notable)
        std::printf("trial %ld: %s page %llu byte %llu ^0x%02x: %s %s\n", i, r.chunk.dataset.c_str(),
                    static_cast<unsigned long long>(r.chunk.page), static_cast<unsigned long long>(r.byte), r.mask,
                    outcome_name(r.outcome), r.message.c_str());
    }
    fs::remove(scratch);
    std::printf("\nflipped pages, by dataset (trials):\n");
    for (const auto& [name, n] : c.per_dataset) std::printf("  %-32s %llu\n", name.c_str(), static_cast<unsigned long long>(n));
    std::printf("\n%-44s %8s\n", "outcome", "trials");
    std::printf("%-44s %8llu\n", "identical (slack byte, HDF5 reads it too)", static_cast<unsigned long long>(c.identical));
    std::printf("%-44s %8llu\n", "Corrupt error", static_cast<unsigned long long>(c.corrupt));
    std::printf("%-44s %8llu\n", "  of which naming dataset and page", static_cast<unsigned long long>(c.corrupt_named));
    std::printf("%-44s %8llu\n", "other error", static_cast<unsigned long long>(c.other));
    std::printf("%-44s %8llu\n", "page not read (no public read path)", static_cast<unsigned long long>(c.not_read));
    std::printf("%-44s %8llu\n", "DIFFERENT DATA", static_cast<unsigned long long>(c.different));
    std::printf("%-44s %8llu\n", "total", static_cast<unsigned long long>(c.trials));
    return c.different == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(scratch, ec);
    std::fprintf(stderr, "corrupt_trials: %s\n", e.what());
    return 2;
  }
}
