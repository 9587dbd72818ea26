// The store out of core: counter-driven checks of the page cache behind a
// real store, concurrent readers, damaged pages and interrupted writers.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <thread>

#include <nlohmann/json.hpp>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/locate.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

struct Diced {
  FineMesh mem;
  std::string path;
};

// A real mesh diced in memory and written to a store in tmp.
Diced dice_to_store(const test::TempDir& tmp, const char* file, Id interval) {
  IntervalRequest r;
  r.global = interval;
  Diced d{FineMesh::dice(read_coarse_mesh(test::data_path(file)), r), tmp.path("m.dice.h5")};
  write_store(d.mem, d.path);
  return d;
}

std::uint64_t total_pages(const FineMesh& m) {
  auto pages = [](const auto& t) { return static_cast<std::uint64_t>((t.rows() + t.rows_per_page() - 1) / t.rows_per_page()); };
  const MeshTables& t = m.tables();
  // A straight mesh's blocks need nothing but the element rows and their
  // corner coordinates (rows.hpp): the vertex, edge and face tables stay unread.
  return pages(t.elements) + pages(t.corners);
}

void sweep(const FineMesh& m, std::uint64_t& checksum) {
  FineBlock b;
  for (Id h = 0; h < m.num_coarse_elements(); ++h) {
    m.fill_block(h, b);
    for (Id g = 0; g < b.num_points(); ++g)
      checksum += std::bit_cast<std::uint64_t>(b.x[g]) ^ (std::bit_cast<std::uint64_t>(b.y[g]) * 3) ^
                  (std::bit_cast<std::uint64_t>(b.z[g]) * 7) ^ static_cast<std::uint64_t>(b.node_id[g]);
    for (Id c : b.conn) checksum += static_cast<std::uint64_t>(c) * 11;
  }
}

}  // namespace

TEST(StorePaged, FullSweepReadsEveryPageOnceAndASecondSweepReadsNothing) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "vtkdata_disk_out_ref.ex2", 2);
  std::uint64_t c = 0;
  sweep(d.mem, c);
  for (const bool keep : {false, true}) {
    SCOPED_TRACE(keep ? "coarse tables kept resident" : "every page pinned");
    StoreOptions o{64ull << 20, 4};
    o.keep_coarse_tables = keep;
    const FineMesh s = read_store(d.path, o);
    auto cache = store_cache(s);
    ASSERT_TRUE(cache);
    cache->reset_stats();
    std::uint64_t a = 0, b = 0;
    sweep(s, a);
    const CacheStats first = cache->stats();
    // Opening read the last page of the elements (it checks the fine counts
    // against the last row); the sweep reads every other page once.
    EXPECT_EQ(first.pages_read + 1, total_pages(s)) << "every page of the element and corner tables exactly once";
    EXPECT_EQ(first.evictions, 0u);
    // The disk's tables are far below a quarter of 64 MiB: all kept, so
    // every row of the two tables the sweep read is held for good.
    const MeshTables& t = s.tables();
    const auto rows_bytes = static_cast<std::uint64_t>(t.elements.rows() * t.elements.width() * 8 +
                                                       t.corners.rows() * t.corners.width() * 8);
    if (keep) {
      EXPECT_GE(first.kept_bytes, rows_bytes);
      EXPECT_LE(first.kept_bytes, first.resident_bytes);
    } else {
      EXPECT_EQ(first.kept_bytes, 0u);
    }
    sweep(s, b);
    const CacheStats second = cache->stats();
    EXPECT_EQ(second.pages_read, first.pages_read) << "a second sweep with a large budget reads nothing";
    EXPECT_EQ(second.misses, first.misses);
    // Pinned pages count a hit per pin; kept pages are read without one.
    if (keep) {
      EXPECT_EQ(second.hits, first.hits);
    } else {
      EXPECT_GT(second.hits, first.hits);
    }
    EXPECT_EQ(a, c) << "the store sweep equals the in-memory sweep bit for bit";
    EXPECT_EQ(b, c);
    EXPECT_LE(second.peak_resident_bytes, cache->budget());
    EXPECT_EQ(cache->pinned_pages(), 0u) << "the cache's own pins on kept pages are not handles";
  }
}

TEST(StorePaged, ASmallBudgetIsNeverExceededAndGivesTheSameBits) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "cardinal_cylinders.exo", 2);
  const FineMesh s = read_store(d.path, StoreOptions{1ull << 20, 2});
  auto cache = store_cache(s);
  const std::uint64_t data_bytes = total_pages(s) * 65536;
  ASSERT_GT(data_bytes, 2 * cache->budget()) << "the test needs a store larger than the budget";
  std::uint64_t a = 0, c = 0;
  sweep(s, a);
  sweep(d.mem, c);
  EXPECT_EQ(a, c);
  // Random queries too.
  std::mt19937_64 rng(3);
  MeshCursor cur;
  for (int q = 0; q < 300; ++q) {
    const Id id = std::uniform_int_distribution<Id>(0, s.num_nodes() - 1)(rng);
    ASSERT_EQ(s.node(id, cur), d.mem.node(id));
    const Id e = std::uniform_int_distribution<Id>(0, s.num_elements() - 1)(rng);
    ASSERT_EQ(s.element(e, cur).nodes, d.mem.element(e).nodes);
  }
  const CacheStats st = cache->stats();
  EXPECT_LE(st.peak_resident_bytes, cache->budget());
  EXPECT_GT(st.evictions, 0u) << "the budget forced evictions";
}

// Four threads query s at random (node, element, point location, whole
// blocks), each with its own cursor; returns the answers that differ from
// mem's.
namespace {
int concurrent_mismatches(const FineMesh& s, const FineMesh& mem, std::uint64_t seed) {
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (std::uint64_t th = 0; th < 4; ++th)
    threads.emplace_back([&, th] {
      std::mt19937_64 rng(seed + th);
      MeshCursor cur;
      FineBlock b;
      for (int q = 0; q < 300; ++q) {
        const Id id = std::uniform_int_distribution<Id>(0, s.num_nodes() - 1)(rng);
        if (!(s.node(id, cur) == mem.node(id))) ++mismatches;
        const Id e = std::uniform_int_distribution<Id>(0, s.num_elements() - 1)(rng);
        if (s.element(e, cur).nodes != mem.element(e).nodes) ++mismatches;
        const Vec3 p = mem.node(id);
        if (locate_point(s, {p.x, p.y, p.z}).element != locate_point(mem, {p.x, p.y, p.z}).element) ++mismatches;
        if (q % 10 == 0) {
          s.fill_block(std::uniform_int_distribution<Id>(0, s.num_coarse_elements() - 1)(rng), b);
          for (Id g = 0; g < b.num_points(); g += 7)
            if (!(Vec3{b.x[g], b.y[g], b.z[g]} == mem.node(b.node_id[g]))) ++mismatches;
        }
      }
    });
  for (auto& th : threads) th.join();
  return mismatches.load();
}
}  // namespace

TEST(StorePaged, ConcurrentReadersShareOneCacheAndAgreeBitForBit) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "vtkdata_mug.e", 3);
  const FineMesh s = read_store(d.path, StoreOptions{4ull << 20, 4});
  EXPECT_EQ(concurrent_mismatches(s, d.mem, 100), 0);
  EXPECT_LE(store_cache(s)->stats().peak_resident_bytes, store_cache(s)->budget());
}

// read_store's kept coarse tables (store.hpp): the same bits whichever
// tables are kept, and the kept pages within a quarter of the budget. The
// disk's coarse tables decode to about 10 MiB, so a 32 MiB budget (a
// quarter: 8 MiB) keeps some of them and not all, 64 MiB keeps all, and
// below 32 MiB none. Four threads query at once (also under
// ThreadSanitizer): kept pages are read without pins.
TEST(StorePaged, ConcurrentQueriesWithKeptCoarseTablesGiveTheSameBits) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "vtkdata_disk_out_ref.ex2", 2);
  struct Case {
    std::uint64_t mib;
    bool keep;
  };
  for (const Case c : {Case{31, true}, Case{32, true}, Case{64, true}, Case{64, false}}) {
    SCOPED_TRACE(std::to_string(c.mib) + " MiB, keep " + std::to_string(c.keep));
    StoreOptions o{c.mib << 20, 4};
    o.keep_coarse_tables = c.keep;
    const FineMesh s = read_store(d.path, o);
    const MeshTables& t = s.tables();
    const bool all = t.elements.kept_resident() && t.corners.kept_resident() && t.bounds.kept_resident() &&
                     t.edges.kept_resident() && t.faces.kept_resident() && t.vertex_nodes.kept_resident() &&
                     t.vertex_owner.kept_resident();
    const bool any = t.elements.kept_resident() || t.corners.kept_resident() || t.bounds.kept_resident() ||
                     t.edges.kept_resident() || t.faces.kept_resident() || t.vertex_nodes.kept_resident() ||
                     t.vertex_owner.kept_resident();
    if (!c.keep || c.mib < 32) {
      EXPECT_FALSE(any);
    } else if (c.mib == 32) {
      EXPECT_TRUE(any && !all) << "a quarter of 32 MiB holds some of the tables";
    } else {
      EXPECT_TRUE(all);
    }
    EXPECT_EQ(concurrent_mismatches(s, d.mem, 300), 0);
    const CacheStats st = store_cache(s)->stats();
    EXPECT_LE(st.kept_bytes, (c.mib << 20) / 4);
    EXPECT_EQ(st.kept_bytes > 0, any);
    EXPECT_LE(st.peak_resident_bytes, c.mib << 20);
  }
}

TEST(StorePaged, AFlippedByteInAPageIsACorruptErrorNamingDatasetAndPage) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "cardinal_sphere.e", 2);
  // Where is page 0 of topology/elements in the file?
  haddr_t addr = 0;
  hsize_t size = 0;
  {
    hid_t f = H5Fopen(d.path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t ds = H5Dopen2(f, "topology/elements", H5P_DEFAULT);
    hsize_t offset[2] = {0, 0};
    unsigned mask = 0;
    ASSERT_GE(H5Dget_chunk_info_by_coord(ds, offset, &mask, &addr, &size), 0);
    H5Dclose(ds);
    H5Fclose(f);
  }
  ASSERT_GT(size, 16u);
  std::string bytes = test::read_file(d.path);
  bytes[addr + size / 2] ^= 0x20;
  const std::string bad = tmp.path("bad.dice.h5");
  test::write_file(bad, bytes);
  const FineMesh s = read_store(bad);  // opening reads no element page
  try {
    s.element(0);
    FAIL() << "a damaged page was read without error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Corrupt);
    EXPECT_NE(std::string(e.what()).find("dataset topology/elements page 0"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
  // The CLI says the same in one line, exit code 8.
  const auto r = test::run_cli({"query", bad, "--element", "0"});
  EXPECT_EQ(r.exit_code, 8);
  EXPECT_NE(r.err.find("topology/elements page 0"), std::string::npos) << r.err;
}

TEST(StorePaged, AKilledWriterNeverDamagesTheExistingStore) {
  test::TempDir tmp;
  const std::string out = tmp.path("part.dice.h5");
  const std::string mesh = test::data_path("cardinal_cylinders.exo");
  ASSERT_EQ(test::run_cli({"dice", mesh, "--interval", "2", "-o", out}).exit_code, 0);
  const std::string before = test::read_file(out);
  int killed_while_writing = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const pid_t pid = test::spawn_cli({"dice", mesh, "--interval", "7", "-o", out});
    // Even trials: kill as soon as the temporary file appears (mid-write).
    // Odd trials: kill at a random moment, whatever the writer is doing.
    const auto start = std::chrono::steady_clock::now();
    const auto limit = trial % 2 == 0 ? std::chrono::milliseconds(10000) : std::chrono::milliseconds(20 * trial);
    bool saw_tmp = false;
    while (std::chrono::steady_clock::now() - start < limit && !(trial % 2 == 0 && saw_tmp)) {
      for (const auto& e : std::filesystem::directory_iterator(tmp.dir()))
        if (e.path().filename().string().find(".tmp-") != std::string::npos) saw_tmp = true;
    }
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    if (WIFSIGNALED(status) && saw_tmp) ++killed_while_writing;
    // Whatever moment it died at, the store under the final name is the old
    // one, or (killed after the rename) a complete new one: never a mix.
    const std::string now = test::read_file(out);
    if (now != before) {
      const auto info = test::run_cli({"info", out, "--json"});
      ASSERT_EQ(info.exit_code, 0) << "trial " << trial << ": " << info.err;
      EXPECT_NE(info.out.find("\"fine_elements\":" + std::to_string(9128LL * 343)), std::string::npos)
          << "trial " << trial << ": neither the old store nor the complete new one";
    }
    EXPECT_EQ(test::run_cli({"verify", out, "--quiet"}).exit_code, 0) << "trial " << trial;
  }
  EXPECT_GT(killed_while_writing, 0) << "no trial caught the writer mid-write";
}

TEST(StorePaged, FootprintAndStatsOnTheCommandLine) {
  test::TempDir tmp;
  const std::string store = tmp.path("s.dice.h5");
  ASSERT_EQ(test::run_cli({"dice", test::data_path("cardinal_sphere.e"), "--interval", "6", "-o", store}).exit_code, 0);
  const auto r = test::run_cli({"footprint", store, "--json", "--exact"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const long long nodes = j["fine_nodes"], elems = j["fine_elements"];
  EXPECT_EQ(elems, 256LL * 216);
  // Explicit raw size: float64 xyz per node + 8 int64 per hex, by definition.
  EXPECT_EQ(j["explicit_raw_bytes"].get<long long>(), 24 * nodes + 64 * elems);
  EXPECT_EQ(j["store_bytes"].get<long long>(), static_cast<long long>(std::filesystem::file_size(store)));
  EXPECT_LT(j["explicit_lz4_bytes"].get<long long>(), j["explicit_raw_bytes"].get<long long>());
  EXPECT_GT(j["ratio_raw"].get<double>(), 10.0);  // the point of the product, even at interval 6
  EXPECT_EQ(j["lz4_sampled_fraction"].get<double>(), 1.0);
  // --stats reports the cache counters; a tiny budget is refused clearly.
  const auto q = test::run_cli({"query", store, "--nodes", "0:100", "--stats", "--cache-mb", "1"});
  EXPECT_EQ(q.exit_code, 0) << q.err;
  EXPECT_NE(q.err.find("pages read"), std::string::npos) << q.err;
  EXPECT_NE(q.err.find("peak resident"), std::string::npos) << q.err;
  // A fresh process loads pages, so it has load time to report (the
  // counters themselves: PageCache.LoadAndWaitTimesCoverTheLoadsAndTheWaits).
  EXPECT_TRUE(std::regex_search(q.err, std::regex("page loads: [0-9.]+ (ns|us|ms|s) in the loader \\([0-9.]+ (ns|us|ms|s) a page\\)")))
      << q.err;
  EXPECT_EQ(test::run_cli({"info", store, "--cache-mb", "0"}).exit_code, 2);
  // The default budget keeps the coarse tables a query reads (read_store);
  // --no-keep-tables keeps none, and the nodes printed are the same.
  const auto kept = test::run_cli({"query", store, "--nodes", "0:100", "--stats"});
  const auto none = test::run_cli({"query", store, "--nodes", "0:100", "--stats", "--no-keep-tables"});
  ASSERT_EQ(kept.exit_code, 0) << kept.err;
  ASSERT_EQ(none.exit_code, 0) << none.err;
  EXPECT_EQ(kept.err.find("(0 B kept resident)"), std::string::npos) << kept.err;
  EXPECT_NE(none.err.find("(0 B kept resident)"), std::string::npos) << none.err;
  EXPECT_EQ(kept.out, none.out);
  EXPECT_FALSE(kept.out.empty());
}

// Issue "store v6", item 2: a store several times larger than the cache
// budget is swept and exported whole reading each page at most 1.1 times
// (owner order: a coarse element's rows sit in the pages of its own, and a
// straight element needs only its element row and corners), and random
// queries never hold more than the budget.
TEST(StorePaged, SweepAndExportOfAStoreFourTimesTheBudgetReadEachPageOnce) {
  test::TempDir tmp;
  std::mt19937_64 rng(4242);
  test::BoxSpec spec;
  spec.a = spec.b = spec.c = 26;
  spec.renumber = false;
  CoarseMesh coarse = test::random_box(spec, rng);
  // Sets, so the export's set handling is part of the pass: every element's
  // bottom side, and the vertices of the lower half.
  SideSet ss{7, "bottoms", {}, {}};
  for (Id e = 0; e < coarse.num_elements(); ++e) ss.element.push_back(e), ss.side.push_back(4);
  coarse.side_sets.push_back(ss);
  NodeSet ns{3, "lower", {}};
  for (Id v = 0; v < coarse.num_vertices(); ++v)
    if (coarse.z[v] < 0.5 * spec.c) ns.vertex.push_back(v);
  coarse.node_sets.push_back(ns);
  IntervalRequest r;
  r.global = 2;
  const FineMesh mem = FineMesh::dice(coarse, r);
  const std::string path = tmp.path("big.dice.h5");
  write_store(mem, path);
  const std::uint64_t budget = 1ull << 20;
  ASSERT_GE(std::filesystem::file_size(path), 4 * budget) << "the store must be at least 4x the budget";

  const FineMesh s = read_store(path, StoreOptions{budget, 4});
  auto cache = store_cache(s);
  cache->reset_stats();
  const SweepResult sw = sweep(s, 2);
  const CacheStats a = cache->stats();
  EXPECT_EQ(sw.checksum, sweep(mem, 1).checksum);
  ASSERT_GT(a.distinct_pages_read, 0u);
  EXPECT_LE(static_cast<double>(a.pages_read) / static_cast<double>(a.distinct_pages_read), 1.1)
      << a.pages_read << " pages read, " << a.distinct_pages_read << " distinct";
  EXPECT_GT(a.evictions, 0u) << "the budget must be too small to hold the store";
  EXPECT_LE(a.peak_resident_bytes, budget);

  cache->reset_stats();
  const StoreSets sets = read_store_sets(path);
  ExportChunk c(s, plan_chunks(s, 1)[0]);
  c.prepare(MeshSets{sets.side_sets, sets.node_sets});
  const CacheStats b = cache->stats();
  EXPECT_EQ(c.num_elements(), s.num_elements());
  EXPECT_EQ(c.num_nodes(), s.num_nodes());
  ASSERT_EQ(c.side_sets().size(), 1u);
  EXPECT_EQ(static_cast<Id>(c.side_sets()[0].element.size()), 4 * coarse.num_elements());
  // prepare() makes three passes in store order (the chunk's element rows,
  // its nodes, its elements: ChunkStream), each reading its pages once.
  EXPECT_LE(static_cast<double>(b.pages_read) / static_cast<double>(b.distinct_pages_read), 3 * 1.1)
      << b.pages_read << " pages read, " << b.distinct_pages_read << " distinct";
  EXPECT_LE(b.peak_resident_bytes, budget);

  // Random queries: anything, anywhere, within the budget.
  cache->reset_stats();
  std::uniform_int_distribution<Id> node(0, s.num_nodes() - 1), elem(0, s.num_elements() - 1);
  MeshCursor cur;
  for (int q = 0; q < 3000; ++q) {
    const Id id = node(rng);
    const Vec3 p = s.node(id, cur), m = mem.node(id);
    ASSERT_TRUE(p == m) << "node " << id;
    const Id e = elem(rng);
    ASSERT_EQ(s.element(e, cur).nodes, mem.element(e).nodes) << "element " << e;
  }
  EXPECT_LE(cache->stats().peak_resident_bytes, budget);
}

// A cursor belongs to no one mesh: one MeshCursor and one FineBlock serve
// two stores in turn (the same coarse mesh at intervals 2 and 3, so their
// tables share page numbers with different contents), and a moved-from
// cursor is reused, each answer equal to the in-memory mesh's. A cursor
// that knew only its page numbers handed one store's rows to the other.
TEST(StorePaged, OneCursorServesTwoStoresInTurn) {
  test::TempDir tmp2, tmp3;
  const Diced d2 = dice_to_store(tmp2, "vtkdata_mug.e", 2), d3 = dice_to_store(tmp3, "vtkdata_mug.e", 3);
  const FineMesh s2 = read_store(d2.path, StoreOptions{4ull << 20, 2}), s3 = read_store(d3.path, StoreOptions{4ull << 20, 2});
  ASSERT_NE(s2.num_nodes(), s3.num_nodes());
  std::mt19937_64 rng(11);
  MeshCursor cur;
  FineBlock b;
  for (int q = 0; q < 400; ++q) {
    const bool three = q % 2 == 1;
    const FineMesh& s = three ? s3 : s2;
    const FineMesh& mem = three ? d3.mem : d2.mem;
    const Id id = std::uniform_int_distribution<Id>(0, s2.num_nodes() - 1)(rng);  // in both
    ASSERT_EQ(s.node(id, cur), mem.node(id)) << "query " << q;
    const Id e = std::uniform_int_distribution<Id>(0, s2.num_elements() - 1)(rng);
    ASSERT_EQ(s.element(e, cur).nodes, mem.element(e).nodes) << "query " << q;
    const Id h = std::uniform_int_distribution<Id>(0, s.num_coarse_elements() - 1)(rng);
    s.fill_block(h, b);
    for (Id g = 0; g < b.num_points(); g += 5)
      ASSERT_EQ((Vec3{b.x[g], b.y[g], b.z[g]}), mem.node(b.node_id[g])) << "query " << q;
    if (q % 50 == 49) {
      MeshCursor moved = std::move(cur);  // cur is left holding no page
      ASSERT_EQ(s.node(id, moved), mem.node(id));
    }
  }
}

// A store's element pages carry node_first and element_first again after
// their rows, densely (Table::derived), for the id -> element searches.
// Each derived value must equal its row's, on every page, and a search at
// either side of every element's first id must land on the element the
// rows say (the last whose first id is <= the id). Twice: uniform
// intervals, and one sheet at 40 intervals in a mesh at 1, where rows hold
// very different counts (the interpolation's first probes land rows off,
// and an element owning no node repeats its successor's first id). The
// in-memory twin's dense columns and guided searches (tables.hpp IdGuide)
// must agree too.
TEST(StorePaged, ElementPagesCarryTheSearchColumnsAndSearchesLandOnTheRowsElement) {
  const CoarseMesh coarse = read_coarse_mesh(test::data_path("vtkdata_disk_out_ref.ex2"));
  IntervalRequest uniform, skewed;
  uniform.global = 2;
  skewed.global = 1;
  skewed.sheets = {{0, 40}};
  for (const IntervalRequest& r : {uniform, skewed}) {
    test::TempDir tmp;
    const FineMesh m = FineMesh::dice(coarse, r);
    write_store(m, tmp.path("m.dice.h5"));
    const FineMesh s = read_store(tmp.path("m.dice.h5"), StoreOptions{4ull << 20, 0});
    const MeshTables& t = s.tables();
    const MeshTables& mem = m.tables();
    ASSERT_GT(t.elements.pages(), 10);
    // The searches below go by the page guides (numbering.hpp
    // build_page_guide); the skewed store has buckets in which two or
    // more pages start (the guide's step past the first).
    ASSERT_FALSE(t.node_page_guide.row.empty());
    ASSERT_FALSE(t.element_page_guide.row.empty());
    if (&r == &skewed) {
      int wide = 0;
      for (const IdGuide* g : {&t.node_page_guide, &t.element_page_guide})
        for (size_t b = 0; b + 1 < g->row.size(); ++b) wide += g->row[b + 1] - g->row[b] >= 2;
      EXPECT_GT(wide, 0);
    }
    const std::vector<int> cols = element_search_columns(s.mode());
    ASSERT_EQ(cols.size(), 2u);
    ASSERT_EQ(t.elements.derived_columns(), cols);
    MeshCursor cur, mcur;
    const Id nh = s.num_coarse_elements();
    std::vector<std::int64_t> first[2];
    for (Id h = 0; h < nh; ++h)
      for (int k = 0; k < 2; ++k) {
        const std::int64_t truth = mem.elements.row(h, mcur.elements)[cols[k]];
        const std::int64_t* v = t.elements.derived(h, k, cur.elements);
        ASSERT_NE(v, nullptr);
        ASSERT_EQ(*v, truth) << "row " << h << " column " << k;
        ASSERT_EQ(t.elements.row(h, cur.elements)[cols[k]], truth) << "row " << h;
        const std::int64_t* d = mem.elements.derived(h, k, mcur.elements);  // in memory: one dense column each
        ASSERT_NE(d, nullptr);
        ASSERT_EQ(*d, truth) << "in memory, row " << h << " column " << k;
        first[k].push_back(truth);
      }
    // At interval 1 an element may own no node: the last of equal firsts.
    auto last_at_or_below = [&](int k, std::int64_t id) {
      return static_cast<Id>(std::upper_bound(first[k].begin(), first[k].end(), id) - first[k].begin()) - 1;
    };
    for (Id h = 0; h < nh; ++h)
      for (const std::int64_t at : {first[0][h], first[0][h] - 1})
        if (at >= 0) {
          ASSERT_EQ(owner_element(t, at, cur), last_at_or_below(0, at)) << "node " << at;
          ASSERT_EQ(owner_element(mem, at, mcur), last_at_or_below(0, at)) << "node " << at << " in memory";
        }
    for (Id h = 0; h < nh; ++h) {
      std::array<Id, 3> ijk{};
      ASSERT_EQ(locate_element(t, first[1][h], ijk, cur), h);  // every element holds fine elements
      EXPECT_EQ(ijk, (std::array<Id, 3>{0, 0, 0}));
      ASSERT_EQ(locate_element(mem, first[1][h], ijk, mcur), h);
      if (h > 0) {
        ASSERT_EQ(locate_element(t, first[1][h] - 1, ijk, cur), h - 1);
        ASSERT_EQ(locate_element(mem, first[1][h] - 1, ijk, mcur), h - 1);
      }
    }
    ASSERT_EQ(owner_element(t, s.num_nodes() - 1, cur), last_at_or_below(0, s.num_nodes() - 1));
    ASSERT_EQ(s.node(s.num_nodes() / 3, cur), m.node(s.num_nodes() / 3));
  }
}

// Stores opened, read and dropped on several threads at once: every HDF5
// call, the closes of the last owner's file and datasets included, under the
// one HDF5 lock (a close on one thread while another opened crashed HDF5).
TEST(StorePaged, StoresOpenedAndDroppedOnThreadsAtOnce) {
  test::TempDir tmp;
  const Diced d = dice_to_store(tmp, "cardinal_prism.exo", 1);
  const Id nodes = d.mem.num_nodes();
  const size_t side_sets = read_store_sets(d.path).side_sets.size();
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (int th = 0; th < 3; ++th)
    threads.emplace_back([&] {
      for (int k = 0; k < 40; ++k) {
        const FineMesh s = read_store(d.path, StoreOptions{4ull << 20, k % 2 == 0 ? 4u : 0u});
        if (s.num_nodes() != nodes || read_store_sets(s, d.path).side_sets.size() != side_sets ||
            store_summary(d.path).format_version != kStoreFormatVersion)
          ++wrong;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
}
