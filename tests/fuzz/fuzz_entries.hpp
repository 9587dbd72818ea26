#pragma once
// Shared bodies of the libFuzzer targets (tests/fuzz/fuzz_*.cpp) and of the
// FuzzRegressions tests (tests/bad_inputs/test_fuzz_regressions.cpp), so a
// regression file replays exactly the code the fuzzer ran.
//
// Each entry takes arbitrary bytes and returns normally when the code under
// test either succeeded or threw dicer::Error (caught here). Anything else
// escapes: another exception (std::bad_alloc included: hostile counts must
// be refused before allocating), or a FuzzBug thrown when an oracle fails
// (silent corruption, a round trip that changes bytes). Under libFuzzer an
// escaping exception terminates the process and is recorded as a crash;
// under GoogleTest it fails the test. Sanitizer reports abort in both.
//
// Builds with g++ (test suite) and clang (fuzz build, scripts/run_fuzz.sh).
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace dicer::fuzz {

// An oracle failed: the code under test returned a wrong answer silently.
struct FuzzBug : std::logic_error {
  using std::logic_error::logic_error;
};

// MSH reader path: bytes -> a file -> read_coarse_mesh (reader + validation);
// meshes of at most kMaxDiceElements elements are then diced at interval 1
// and verified (counts, ids and bit identity must hold). Inputs that start
// with netCDF/HDF5 magic are ignored: they would go to the Exodus reader
// (netCDF's own parser), which is not this target.
inline constexpr long kMaxDiceElements = 2000;
void run_msh(const std::uint8_t* data, std::size_t size);

// Exodus reader path: bytes -> a file -> read_coarse_mesh through the real
// netCDF and Exodus libraries, then dice and verify as run_msh does. Only
// inputs that start with netCDF classic magic ("CDF" then 1, 2 or 5) are
// read: HDF5-based (netCDF-4) files are accepted as HDF5 opens them, and
// HDF5 1.10 is known not to survive hostile metadata (see run_store).
void run_exodus(const std::uint8_t* data, std::size_t size);

// Page decoder (filter 32004 layout + Fletcher32): the first 4 bytes (LE)
// modulo 1 MiB give expected_size, the rest is the stored page. Decodes it
// as is, then again with the header's size set to expected_size and the
// checksum recomputed (to reach the LZ4 layout checks), then round-trips
// the rest through encode_page/decode_page (must give the same bytes).
void run_page(const std::uint8_t* data, std::size_t size);

// Store opener, two kinds of input.
// 1. A whole file (it starts with the HDF5 signature): written as is and
//    read like a store (read_store, every block filled, a few node and
//    element queries, read_store_sets). Everything is fuzzed: superblock,
//    object headers, chunk indexes, attributes, pages. Only dicer::Error
//    may come out. Seeds: small real stores (tests/fuzz/corpus/fuzz_store).
// 2. Otherwise a list of 5-byte edits of a small real store built once per
//    process (cardinal_sphere.e diced at interval 2): a 4-byte LE offset
//    into the concatenated byte ranges of the store's chunks (modulo their
//    total) and 1 XOR byte. Any result that comes back must equal the
//    pristine store's bit for bit, unless the edits left some page's
//    Fletcher32 checksum valid (a checksum collision, e.g. a 0x0000 word
//    turned 0xffff: then the CRC-32 companion must catch it, and only "no
//    crash, no non-dicer exception" is required of the rest).
void run_store(const std::uint8_t* data, std::size_t size);

// Where the store target's pristine store lives (built on first use);
// exposed so tools can seed corpora. Throws std::runtime_error if the store
// cannot be built.
std::string pristine_store_path();

}  // namespace dicer::fuzz
