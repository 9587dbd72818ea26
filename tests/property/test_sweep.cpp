// The sweep checksum: independent of thread count and cache budget, and
// equal to the same sum computed through node(id) and element(id).
#include <gtest/gtest.h>

#include <bit>
#include <random>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "random_mesh.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"
#include "work_split.hpp"  // dicer/: the threads' split

using namespace dicer;

namespace {

// The checksum as sweep.hpp documents it, written here from that text
// (not by calling the library's terms).
std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 32;
  h *= 0xd6e8feb86659fd93ull;
  h ^= h >> 32;
  return h;
}
std::uint64_t bits(double x) { return std::bit_cast<std::uint64_t>(x); }
std::uint64_t rotl(std::uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
std::uint64_t node_term(Id id, const Vec3& p) {
  return mix(static_cast<std::uint64_t>(id) * kChecksumKeys[0] ^ bits(p.x) ^ rotl(bits(p.y), 21) ^ rotl(bits(p.z), 42));
}
std::uint64_t element_term(const FineElement& e) {
  const std::uint64_t* K = kChecksumKeys;
  std::uint64_t h = static_cast<std::uint64_t>(e.id) * K[4];
  for (int q = 0; q < e.num_nodes; ++q) h += static_cast<std::uint64_t>(e.nodes[q]) * K[5 + q];
  return mix(h);
}

}  // namespace

TEST(Sweep, ChecksumKeysAreOddAndDistinct) {
  for (int i = 0; i < 13; ++i) {
    EXPECT_EQ(kChecksumKeys[i] & 1, 1u) << i;
    for (int j = 0; j < i; ++j) EXPECT_NE(kChecksumKeys[i], kChecksumKeys[j]);
  }
}

TEST(Sweep, ChecksumSeesEveryFieldAndWhichIdHasWhichCoordinates) {
  const Vec3 a{1.0, 2.0, 3.0}, b{1.0, 2.0, 3.0000000000000004};
  EXPECT_NE(node_checksum_term(5, a), node_checksum_term(5, b)) << "last bit of z";
  EXPECT_NE(node_checksum_term(5, a), node_checksum_term(6, a)) << "id";
  EXPECT_NE(node_checksum_term(5, a) + node_checksum_term(6, b), node_checksum_term(5, b) + node_checksum_term(6, a))
      << "two nodes' coordinates swapped";
  EXPECT_NE(node_checksum_term(5, {1.0, 2.0, 3.0}), node_checksum_term(5, {2.0, 1.0, 3.0})) << "x and y swapped";
  FineElement e;
  e.id = 9, e.num_nodes = 8, e.nodes = {1, 2, 3, 4, 5, 6, 7, 8};
  FineElement r = e;
  std::swap(r.nodes[0], r.nodes[1]);
  EXPECT_NE(element_checksum_term(e), element_checksum_term(r)) << "corner order";
  // The library's terms are the documented formula.
  EXPECT_EQ(node_checksum_term(5, b), node_term(5, b));
  EXPECT_EQ(element_checksum_term(e), element_term(e));
  e.num_nodes = 4;
  EXPECT_EQ(element_checksum_term(e), element_term(e));
}

TEST(Sweep, ChecksumIsTheSameForEveryThreadCountAndCacheBudget) {
  IntervalRequest r;
  r.global = 3;
  const FineMesh mem = FineMesh::dice(read_coarse_mesh(test::data_path("vtkdata_mug.e")), r);
  // Independent: the sum over node(id) and element(id), in id order.
  std::uint64_t expected = 0;
  for (Id id = 0; id < mem.num_nodes(); ++id) expected += node_term(id, mem.node(id));
  for (Id id = 0; id < mem.num_elements(); ++id) expected += element_term(mem.element(id));
  test::TempDir tmp;
  write_store(mem, tmp.path("m.dice.h5"));
  for (unsigned threads : {1u, 2u, 3u, 7u}) {
    const SweepResult a = sweep(mem, threads);
    EXPECT_EQ(a.checksum, expected) << threads << " threads, in memory";
    EXPECT_EQ(a.nodes, mem.num_nodes());
    EXPECT_EQ(a.elements, mem.num_elements());
    for (std::uint64_t mb : {1, 5, 64}) {  // 1 MiB: one thread; 5 MiB: two
      const FineMesh s = read_store(tmp.path("m.dice.h5"), StoreOptions{mb << 20, 4});
      const SweepResult b = sweep(s, threads);
      EXPECT_EQ(b.checksum, expected) << threads << " threads, " << mb << " MiB";
      EXPECT_LE(store_cache(s)->stats().peak_resident_bytes, store_cache(s)->budget());
      EXPECT_EQ(b.threads, std::min<unsigned>(threads, mb == 1 ? 1 : mb == 5 ? 2 : threads));
    }
  }
  // The command line prints the same checksum, whatever --threads says.
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(expected));
  for (const char* t : {"1", "2"}) {
    const auto c = test::run_cli({"sweep", tmp.path("m.dice.h5"), "--threads", t, "--json"});
    ASSERT_EQ(c.exit_code, 0) << c.err;
    EXPECT_NE(c.out.find(std::string("\"checksum\":\"") + hex + "\""), std::string::npos) << c.out;
    EXPECT_NE(c.out.find("\"nodes_per_s\":"), std::string::npos);
  }
}

// The sweep's hex terms from the batches' lines take the element rows of
// a hex's inner layers (both their grid planes inside the hex) from the
// two layers before them (sweep.cpp: affine in the layer). Here the
// checksum is the sum over node(id) and element(id) on random boxes
// (random local numbering: every face orientation) whose hexes have 1 to
// 9 intervals per axis, with a whole hex in one batch, and on one hex cut
// into slabs of 4 layers (127 x 127 points a plane: the slab ends inside
// the hex), whose slabs start on, before and after the inner layers.
TEST(Sweep, InnerLayersOfEveryShapeAndSlabEqualTheTermsOfTheirElements) {
  std::mt19937_64 rng(20261128);
  auto expected = [](const FineMesh& f) {
    std::uint64_t want = 0;
    for (Id id = 0; id < f.num_nodes(); ++id) want += node_term(id, f.node(id));
    for (Id id = 0; id < f.num_elements(); ++id) want += element_term(f.element(id));
    return want;
  };
  for (int trial = 0; trial < 6; ++trial) {
    test::BoxSpec spec;
    spec.a = 2, spec.b = 1 + trial % 2, spec.c = 2;
    IntervalRequest req;
    req.global = 5 + trial % 3;
    std::uniform_int_distribution<Id> n(1, 9);
    for (Id sheet = 0; sheet < 5; ++sheet) req.sheets.push_back({sheet, n(rng)});
    const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
    EXPECT_EQ(sweep(f, 1).checksum, expected(f)) << "trial " << trial;
    EXPECT_EQ(sweep(f, 2).checksum, expected(f)) << "trial " << trial;
  }
  test::BoxSpec one;
  one.a = one.b = one.c = 1;
  const CoarseMesh hex = test::random_box(one, rng);
  for (const Id layers : {Id{12}, Id{9}, Id{3}}) {
    // The sheet across the hex's local k axis: the one whose interval is
    // its n[2].
    bool found = false;
    for (Id across = 0; across < 3 && !found; ++across) {
      IntervalRequest req;
      for (Id sheet = 0; sheet < 3; ++sheet) req.sheets.push_back({sheet, sheet == across ? layers : 126});
      const FineMesh f = FineMesh::dice(hex, req);
      FineBatch b;
      BatchCursor probe(f);
      ASSERT_TRUE(probe.next(b));
      if (b.n != std::array<Id, 3>{126, 126, layers}) continue;
      found = true;
      EXPECT_EQ(b.num_elements(), 126 * 126 * std::min<Id>(4, layers)) << "slabs of 4 layers";
      EXPECT_EQ(sweep(f, 1).checksum, expected(f)) << layers << " layers";
    }
    EXPECT_TRUE(found) << "a sheet across the hex's k axis";
  }
}

// The threads' split of a store comes from its page index: no page read
// before a thread starts (a row read per probe used to load pages one at a
// time, a tenth of a short sweep), and each part within a few pages' work
// of an equal share. The work of a range is counted here by the batch API
// (nodes and elements it hands out), not by the split's own arithmetic.
TEST(Sweep, WorkSplitOfAStoreReadsNoPageAndIsBalanced) {
  std::mt19937_64 rng(20261127);
  test::BoxSpec spec;
  spec.a = 16, spec.b = 12, spec.c = 10;  // 1920 coarse hexes: 16 pages of element rows
  IntervalRequest r;
  r.global = 2;
  r.sheets = {{0, 7}, {4, 5}, {13, 6}};  // uneven work per element
  const FineMesh mem = FineMesh::dice(test::random_box(spec, rng), r);
  test::TempDir tmp;
  write_store(mem, tmp.path("m.dice.h5"));
  const FineMesh s = read_store(tmp.path("m.dice.h5"), StoreOptions{64 << 20, 4});
  const Id H = s.num_coarse_elements(), rpp = s.tables().elements.rows_per_page();
  ASSERT_GE(s.tables().elements.pages(), 5);
  auto work = [&](Id a, Id b) {
    BatchOptions o;
    o.coords = false, o.conn = false;
    BatchCursor c(s, a, b, o);
    FineBatch fb;
    Id w = 0;
    while (c.next(fb)) w += fb.num_nodes() + fb.num_elements();
    return w;
  };
  Id page_work = 0;  // the most work on one page of element rows
  for (Id p = 0; p * rpp < H; ++p) page_work = std::max(page_work, work(p * rpp, std::min(H, (p + 1) * rpp)));
  const Id total = work(0, H);
  ASSERT_EQ(total, s.num_nodes() + s.num_elements());
  ASSERT_LT(3 * page_work, total / 3) << "pages too large for the bound to say anything at 2 and 3 parts";
  for (unsigned parts : {2u, 3u, 4u, 16u}) {
    // A store just opened: the pages `work` read above are not resident.
    const FineMesh fresh = read_store(tmp.path("m.dice.h5"), StoreOptions{64 << 20, 4});
    store_cache(fresh)->reset_stats();
    const std::vector<Id> at = detail::split_work(fresh, parts, 0, H);
    EXPECT_EQ(store_cache(fresh)->stats().pages_read, 0u) << parts << " parts";
    ASSERT_EQ(at.size(), parts + 1);
    EXPECT_EQ(at.front(), 0);
    EXPECT_EQ(at.back(), H);
    for (unsigned p = 0; p < parts; ++p) {
      ASSERT_LE(at[p], at[p + 1]) << p;
      const double share = static_cast<double>(total) / parts;
      // A bound lies up to one page's work below its target or two above
      // (the page index's linear share, one row of the next page); with
      // more parts than that bound resolves, only the bounds' order counts.
      if (3.0 * static_cast<double>(page_work) >= share) continue;
      EXPECT_LE(std::abs(static_cast<double>(work(at[p], at[p + 1])) - share), 3.0 * static_cast<double>(page_work))
          << "part " << p << " of " << parts << " (" << at[p] << ".." << at[p + 1] << ")";
    }
    // In memory, from the rows themselves: each bound within one element's
    // work of its target (an element owns at most 8^3 nodes and 7^3 hexes).
    const std::vector<Id> exact = detail::split_work(mem, parts, 0, H);
    for (unsigned p = 0; p < parts; ++p) {
      const double share = static_cast<double>(total) / parts;
      EXPECT_LE(std::abs(static_cast<double>(work(exact[p], exact[p + 1])) - share), 2.0 * (8 * 8 * 8 + 7 * 7 * 7))
          << "in memory, part " << p << " of " << parts;
    }
  }
}

// One thread fails (its half of the store has a damaged page), the other
// finishes: the sweep reports the error at once, with or without a progress
// callback (it used to wait for the failed thread's work forever).
TEST(Sweep, AFailingThreadEndsTheSweepWithItsError) {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = 10, spec.b = 10, spec.c = 6;  // 600 coarse hexes: 5 pages of element rows
  IntervalRequest r;
  r.global = 2;
  test::TempDir tmp;
  const std::string store = tmp.path("box.dice.h5");
  write_store(FineMesh::dice(test::random_box(spec, rng), r), store);
  // Page 3 of 5: read by whichever thread takes the chunks over it (opening reads the last).
  const std::string bad = test::edited_copy(store, tmp.path("bad.dice.h5"), [](hid_t f) {
    test::forge_page(f, "topology/elements", 3, [](std::vector<std::uint8_t>& page) { page[8] ^= 0x10; }, false);
  });
  for (const bool with_progress : {false, true}) {
    const FineMesh s = read_store(bad);
    ASSERT_EQ((s.tables().elements.rows() + s.tables().elements.rows_per_page() - 1) / s.tables().elements.rows_per_page(), 5);
    try {
      sweep(s, 2, with_progress ? std::function<void(Id, Id)>([](Id, Id) {}) : nullptr);
      ADD_FAILURE() << "the damaged page went unnoticed";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Corrupt) << e.what();
      EXPECT_NE(std::string(e.what()).find("topology/elements page 3"), std::string::npos) << e.what();
    }
  }
}

// checksum_hex_grid is checksum_elements over the grid's hexes, written
// here from batch.hpp's layout and kHexCorner order, on grids whose rows
// are progressions (its shortcut: steps 1, -1, 0, a face row's stride,
// steps that wrap past 2^63), broken anywhere in a row (an end point: the
// line with an offset; inside: each term in full), or random; every n[0]
// from 1 (no interior) up, element rows of one grid on and off the
// shortcut side by side in one vector, and rows of over a thousand.
TEST(Sweep, GridChecksumEqualsTheTermsOfItsHexes) {
  std::mt19937_64 rng(17);
  const std::uint64_t* K = kChecksumKeys;
  for (int trial = 0; trial < 400; ++trial) {
    // The last trials: rows of over a thousand hexes.
    const bool wide = trial >= 396;
    const std::array<Id, 3> n{wide ? 1000 + 37 * (trial - 396) : 1 + trial % 7, wide ? 2 : 1 + (trial / 7) % 4, 3};
    const Id layers = wide ? 1 + trial % 2 : trial % 3, ni = n[0] + 1, pp = ni * (n[1] + 1);
    std::vector<Id> grid(static_cast<size_t>(pp * (layers + 1)));
    std::uniform_int_distribution<Id> big(0, Id{1} << 45);
    for (Id r = 0; r < (n[1] + 1) * (layers + 1); ++r) {
      Id* row = grid.data() + r * ni;
      const Id base = big(rng);
      // A progression (mod 2^64, as the ids' arithmetic in the terms).
      const Id steps[6] = {1, 1, -1, 0, n[0] + 1, static_cast<Id>(rng() | (std::uint64_t{1} << 62))};
      const auto step = static_cast<std::uint64_t>(steps[rng() % 6]);
      for (Id i = 0; i < ni; ++i) row[i] = static_cast<Id>(static_cast<std::uint64_t>(base) + step * static_cast<std::uint64_t>(i));
      switch (trial % 5 == 0 || wide ? 0 : rng() % 4) {  // every fifth grid, and the wide: the shortcut throughout
        case 0: break;
        case 1: row[rng() % ni] = big(rng); break;  // one point anywhere
        case 2: if (ni > 2) row[1 + rng() % (ni - 2)] += 1; break;  // an interior point off by one
        default: for (Id i = 0; i < ni; ++i) row[i] = big(rng);
      }
    }
    const Id first = big(rng);
    std::uint64_t want = 0;
    for (Id k = 0; k < layers; ++k)
      for (Id j = 0; j < n[1]; ++j)
        for (Id i = 0; i < n[0]; ++i) {
          std::uint64_t h = static_cast<std::uint64_t>(first + i + n[0] * (j + n[1] * k)) * K[4];
          for (int q = 0; q < 8; ++q) {
            const Id id = grid[static_cast<size_t>(i + kHexCorner[q][0] + ni * (j + kHexCorner[q][1]) +
                                                   pp * (k + kHexCorner[q][2]))];
            h += static_cast<std::uint64_t>(id) * K[5 + q];
          }
          want += mix(h);
        }
    ASSERT_EQ(checksum_hex_grid(first, n, layers, grid), want) << "trial " << trial;
  }
  EXPECT_NE(test::error_of([] { checksum_hex_grid(0, {2, 2, 2}, 1, std::vector<Id>(17)); }, ErrorKind::Usage)
                .find("17 ids for 1 layers of 2 x 2"),
            std::string::npos);
}
