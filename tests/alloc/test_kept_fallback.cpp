// A store's kept pages when the kept arena gets no memory: PageCache copies
// a kept page into 2 MiB-aligned chunks (page_cache.cpp KeptArena) and,
// when aligned_alloc refuses one, keeps the page in its own heap buffer.
// This binary replaces aligned_alloc (its own binary already replaces
// operator new) so that the refusal is the C library's real answer, null,
// not a flag inside the cache: every query must still be the in-memory
// mesh's, bit for bit.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <random>

#include "dicer/cache.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

namespace {
std::atomic<bool> g_refuse_chunks{false};
std::atomic<long> g_chunks_asked{0};
constexpr std::size_t kChunkAlignment = std::size_t{2} << 20;  // KeptArena's
}  // namespace

// Only the arena asks for 2 MiB alignment; everything else (aligned new in
// libstdc++) is served as the C library would.
extern "C" void* aligned_alloc(std::size_t alignment, std::size_t size) {
  if (alignment >= kChunkAlignment) {
    g_chunks_asked.fetch_add(1, std::memory_order_relaxed);
    if (g_refuse_chunks.load(std::memory_order_relaxed)) return nullptr;
  }
  void* p = nullptr;
  return ::posix_memalign(&p, alignment < sizeof(void*) ? sizeof(void*) : alignment, size) == 0 ? p : nullptr;
}

using namespace dicer;

namespace {

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every node and element of a store opened with its coarse tables kept,
// against the mesh it was written from; a small budget beside them so the
// other arrays' pages are evicted while the kept ones stay.
void check_store(const FineMesh& mem, const std::string& path) {
  const FineMesh m = read_store(path, StoreOptions{32ull << 20, 4, true});
  ASSERT_NE(m.tables().node_row_guide, nullptr) << "the element table is kept";
  std::vector<Id> ids(static_cast<size_t>(std::max(mem.num_nodes(), mem.num_elements())));
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<Id>(i);
  std::mt19937_64 rng(3);
  MeshCursor cur;
  for (int round = 0; round < 2; ++round) {
    std::shuffle(ids.begin(), ids.end(), rng);
    for (const Id id : ids) {
      if (id < mem.num_nodes()) {
        ASSERT_TRUE(same_bits(m.node(id, cur), mem.node(id))) << "node " << id;
      }
      if (id < mem.num_elements()) {
        const FineElement a = m.element(id, cur), b = mem.element(id);
        ASSERT_EQ(a.nodes, b.nodes) << "element " << id;
        ASSERT_EQ(a.ijk, b.ijk) << "element " << id;
      }
    }
  }
  EXPECT_GT(store_cache(m)->stats().kept_bytes, 0u);
  EXPECT_LE(store_cache(m)->stats().peak_resident_bytes, store_cache(m)->budget());
}

}  // namespace

TEST(KeptArena, QueriesAreRightWhetherTheArenaGetsMemoryOrNot) {
  std::mt19937_64 rng(9);
  test::BoxSpec spec;
  spec.a = 7, spec.b = 6, spec.c = 5, spec.blocks = 2;  // 210 hexes: two pages of element rows
  IntervalRequest req;
  req.global = 2;
  const FineMesh mem = FineMesh::dice(test::random_box(spec, rng), req);
  test::TempDir dir;
  const std::string path = dir.path("box.dice.h5");
  write_store(mem, path);

  g_chunks_asked = 0;
  check_store(mem, path);
  EXPECT_GT(g_chunks_asked.load(), 0) << "the arena asks for its chunks here (the hook sees them)";

  g_chunks_asked = 0;
  g_refuse_chunks = true;
  check_store(mem, path);
  g_refuse_chunks = false;
  EXPECT_GT(g_chunks_asked.load(), 0) << "the arena was refused, so its pages stayed in their buffers";
}
