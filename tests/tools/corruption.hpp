#pragma once
// Corruption trials: flip one random byte in one page of a store and read
// everything back through the public API. Shared by the `corrupt_trials`
// program (scripts/corruption.sh) and the `Corruption` test suite.
//
// Every trial ends in exactly one class:
//   Identical     no error and every fingerprint equal, and HDF5's own
//                 filter pipeline (Fletcher32) also reads the dataset: the
//                 byte was slack
//   Corrupt       dicer::Error{Corrupt} (named_page: the message names the
//                 flipped dataset and page)
//   OtherError    any other error kind or exception type
//   DifferentData no error but some fingerprint differs: must never happen
//   PageNotRead   no error, fingerprints equal, but HDF5's pipeline refuses
//                 the dataset: the page belongs to a dataset no public read
//                 path touches (coarse/vertex_file_id, ...)
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

namespace dicer::corruption {

// One stored chunk (a page) of one dataset.
struct Chunk {
  std::string dataset;
  std::uint64_t page = 0;
  std::uint64_t address = 0, size = 0;
};

// Every chunk of every dataset in the file (H5Dget_chunk_info).
std::vector<Chunk> list_chunks(const std::string& path);

// Everything the public API reads back from a store, hashed.
struct Fingerprint {
  std::vector<std::uint64_t> element;            // per coarse element: fill_block ids, xyz, connectivity
  std::uint64_t nodes = 0;                       // NodeCursor over every node id: id, xyz
  std::uint64_t elements = 0;                    // ElementCursor over every element
  std::map<std::string, std::uint64_t> tables;   // every row of every paged table
  std::uint64_t info = 0;                        // MeshInfo: counts, kind bases, blocks
  std::uint64_t sets = 0;                        // read_store_sets
  bool operator==(const Fingerprint&) const = default;
  // First differing part, for reports ("" when equal).
  std::string first_difference(const Fingerprint& other) const;
};

// Reads the whole store; throws whatever the readers throw.
Fingerprint sweep(const std::string& path);

enum class Outcome { Identical, Corrupt, OtherError, DifferentData, PageNotRead };
const char* outcome_name(Outcome o);

struct TrialResult {
  Outcome outcome = Outcome::Identical;
  Chunk chunk;
  std::uint64_t byte = 0;       // offset inside the chunk
  std::uint8_t mask = 0;        // xor mask
  bool named_page = false;      // Corrupt: the message names "dataset D page P"
  std::string message;          // error message or first difference
};

struct Counts {
  std::uint64_t trials = 0, identical = 0, corrupt = 0, corrupt_named = 0, other = 0, different = 0, not_read = 0;
  std::map<std::string, std::uint64_t> per_dataset;  // trials per flipped dataset
  void add(const TrialResult& r);
};

class Trials {
 public:
  // Reads the pristine store (fingerprint, chunk list). `scratch` is where
  // each damaged copy is written.
  Trials(const std::string& store, const std::string& scratch, std::uint64_t seed);
  TrialResult run_one();
  // Reads the store at `path` (damaged in `chunk`) and classifies it
  // against the pristine fingerprint (byte and mask are left 0).
  TrialResult check(const std::string& path, const Chunk& chunk) const;
  const std::vector<Chunk>& chunks() const { return chunks_; }
  const Fingerprint& pristine() const { return pristine_; }
  std::uint64_t chunk_bytes() const { return chunk_bytes_; }

 private:
  std::string store_, scratch_, bytes_;
  std::vector<Chunk> chunks_;
  std::uint64_t chunk_bytes_ = 0;
  Fingerprint pristine_;
  std::mt19937_64 rng_;
};

}  // namespace dicer::corruption
