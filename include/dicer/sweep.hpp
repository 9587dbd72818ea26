#pragma once
// Sweep: visit every fine node and element once, a batch at a time
// (batch.hpp), coarse elements cut into contiguous chunks of about equal
// work that free threads take in turn (kSweepChunksPerThread), and fold
// them into an order-independent checksum: the same for every thread count
// and cache budget (a test pins it), so two sweeps, two machines or two
// stores of the same mesh can be compared by one number.
//
// The checksum, all arithmetic mod 2^64:
//   mix(h)       = h ^= h >> 32; h *= 0xd6e8feb86659fd93; h ^= h >> 32
//   node term    = mix(id*K0 ^ bits(x) ^ rotl(bits(y), 21) ^ rotl(bits(z), 42))
//   element term = mix(id*K4 + node[0]*K5 + ... + node[c-1]*K(4+c)), c = 8 or 4 corners
//   checksum     = sum of every node's and every element's term
// with bits() the IEEE-754 bit pattern, rotl a left rotation and
// K = kChecksumKeys (odd, so each product is a bijection of its input; K1..K3
// served 0.3-0.4's node term). Each step is a bijection of each input with
// the others fixed, so a change in any one id, coordinate bit or corner
// always changes the term; the rotations keep a coordinate's bits from
// lining up with another's (x and y swapped changes the term), and mix ties
// the id to its coordinates (a node's coordinates given to another id
// change the sum). Terms are independent, so the sum vectorises: one 64-bit
// multiply per node beyond the id's (which a vector loop steps by adding),
// one per element.
//
// Values differ between versions: 0.3 replaced chained mixes by the sum of
// terms; 0.4's interior coordinates came from tfi.hpp's factored hex TFI;
// 0.5 computes straight hexes' and faces' interiors by their trilinear and
// bilinear forms (last bits can differ) and replaced murmur3's finaliser
// (two multiplies) and the coordinates' three keyed products by mix and the
// rotations. Compare checksums only between the same version.
#include <cstdint>
#include <functional>
#include <span>

#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"

namespace dicer {

struct SweepResult {
  Id nodes = 0, elements = 0;
  unsigned threads = 1;        // threads used (see sweep())
  double seconds = 0;
  std::uint64_t checksum = 0;  // sum over nodes of h(id, x, y, z bits) + over elements of h(id, node ids)
};

// threads >= 1. A thread pins up to kSweepPagesPerThread pages of a store's
// cache, so no more threads are used than the budget can hold pinned twice
// over (the result says how many ran); the checksum is the same anyway.
// progress(done, total) is called from the calling thread only, in units of
// nodes + elements.
inline constexpr unsigned kSweepPagesPerThread = 20;
// With several threads the coarse elements are cut into this many chunks of
// about equal work per thread, each taken by the next free thread. A
// store's chunks come from its page index (equal to within a page's work),
// so no page is read before the threads start.
inline constexpr unsigned kSweepChunksPerThread = 8;
// [first_coarse, end_coarse) restricts the sweep to those coarse elements
// (end -1: the last): their fine elements and the nodes they own (an MPI
// rank's chunk); the checksums of a partition of the mesh add up to the
// whole mesh's (mod 2^64).
SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress = {},
                  Id first_coarse = 0, Id end_coarse = -1);

inline constexpr std::uint64_t kChecksumKeys[13] = {
    0x9e3779b97f4a7c15ull, 0xbf58476d1ce4e5b9ull, 0x94d049bb133111ebull, 0xd6e8feb86659fd93ull,
    0xa0761d6478bd642full, 0xe7037ed1a0b428dbull, 0x8ebc6af09c88c6e3ull, 0x589965cc75374cc3ull,
    0x1d8e4e27c47d124full, 0x2545f4914f6cdd1dull, 0x5851f42d4c957f2dull, 0x14057b7ef767814full,
    0x9fb21c651e98df25ull};

// One term, and the sums over a batch's arrays (nodes first, first + 1, ...;
// elements likewise, `corners` node ids each). O(n), vectorised.
std::uint64_t node_checksum_term(Id id, const Vec3& x);
std::uint64_t element_checksum_term(const FineElement& e);
std::uint64_t checksum_nodes(Id first, std::span<const double> x, std::span<const double> y, std::span<const double> z);
std::uint64_t checksum_elements(Id first, int corners, std::span<const Id> conn);
// The same sum as checksum_elements over the hexes of `layers` element
// layers of an n[0] x n[1] grid (ids first, first + 1, ... in i, j, layer
// order), their corners read from `grid` (FineBatch::grid's layout:
// (n[0] + 1)(n[1] + 1)(layers + 1) node ids). Cheaper: no connectivity is
// formed, and along a row where the interiors of all four grid rows it
// reads are arithmetic progressions (a cell's interior steps by 1, a face's
// or an edge's by a constant of either sign), each term's argument is the
// previous one's plus a constant (K4 plus each corner's key times its grid
// row's step), and the two end elements' differ from that line only by
// their end points' offsets, so per element only an add and mix remain;
// rows are hashed side by side, one per vector lane. Error{Usage} when
// n[0] or n[1] < 1, layers < 0 or grid has the wrong size. Each calling
// thread keeps about 8 bytes per grid id and 90 per grid row of work space
// (allocated on its first calls).
std::uint64_t checksum_hex_grid(Id first, const std::array<Id, 3>& n, Id layers, std::span<const Id> grid);

}  // namespace dicer
