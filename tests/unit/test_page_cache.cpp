// PageCache (include/dicer/cache.hpp) against its own contract, with a
// synthetic loader: page bytes are a hash of (array, page, offset) and page
// sizes vary between 256 and 1024 bytes. Every check is on counters and
// contents, never on timing (the load-time counters only from below, by
// sleeps); waits for other threads poll the cache's counters. The
// concurrent tests also run under ThreadSanitizer (scripts/run_tsan.sh).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <thread>
#include <type_traits>
#include <vector>

#include "dicer/cache.hpp"
#include "dicer/error.hpp"

using namespace dicer;

namespace {

std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

constexpr std::size_t kMinPage = 256, kMaxPage = 1024;

std::uint64_t page_seed(PageKey k) { return mix((std::uint64_t{k.array} << 48) ^ k.page); }
std::size_t page_bytes(PageKey k) { return kMinPage + page_seed(k) % (kMaxPage - kMinPage + 1); }
std::uint8_t byte_at(PageKey k, std::size_t i) { return static_cast<std::uint8_t>(mix(page_seed(k) + i) >> 56); }

// The store's side of the contract: pages of `arrays` arrays of `pages`
// pages each. Loading a page beyond the end throws, as the real loader may.
// Counts loads per page.
class SyntheticPages {
 public:
  SyntheticPages(std::uint32_t arrays, std::uint64_t pages) : pages_(pages), loads_(arrays * pages) {}

  PageCache::Loader loader() {
    return [this](PageKey k, PageBytes& out) -> std::uint64_t {
      if (k.page >= pages_) throw Error(ErrorKind::BadInput, "synthetic: page beyond the end");
      loads_[k.array * pages_ + k.page].fetch_add(1);
      out.resize(page_bytes(k));
      for (std::size_t i = 0; i < out.size(); ++i) out[i] = byte_at(k, i);
      return out.size() / 2 + 1;  // "compressed" size
    };
  }
  int loads(PageKey k) const { return loads_[k.array * pages_ + k.page].load(); }
  std::uint64_t total_loads() const {
    std::uint64_t n = 0;
    for (const auto& c : loads_) n += c.load();
    return n;
  }
  void declare(PageCache& cache, std::uint32_t arrays) const {
    for (std::uint32_t a = 0; a < arrays; ++a) cache.set_array_pages(a, pages_);
  }

 private:
  std::uint64_t pages_;
  std::vector<std::atomic<int>> loads_;
};

bool content_ok(const PageCache::Handle& h) {
  if (h.empty() || h.size() != page_bytes(h.key())) return false;
  for (std::size_t i = 0; i < h.size(); ++i)
    if (h.data()[i] != byte_at(h.key(), i)) return false;
  return true;
}

PageCache::Options opts(std::uint64_t budget, unsigned read_ahead, bool background) {
  PageCache::Options o;
  o.budget_bytes = budget;
  o.read_ahead_pages = read_ahead;
  o.background_read_ahead = background;
  return o;
}

// Waits (without timing) until `pred` holds: other threads make progress.
template <class Pred>
void spin_until(Pred pred) {
  while (!pred()) std::this_thread::yield();
}

ErrorKind kind_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.kind();
  }
  ADD_FAILURE() << "no dicer::Error thrown";
  return ErrorKind::Usage;
}

struct SweepCase {
  unsigned read_ahead;
  bool background;
};

}  // namespace

TEST(PageCache, HandleIsMoveOnly) {
  static_assert(!std::is_copy_constructible_v<PageCache::Handle>);
  static_assert(!std::is_copy_assignable_v<PageCache::Handle>);
  static_assert(std::is_nothrow_move_constructible_v<PageCache::Handle>);
  static_assert(std::is_nothrow_move_assignable_v<PageCache::Handle>);
}

TEST(PageCache, HandleMoveLeavesEmptyAndReleasesOnce) {
  SyntheticPages pages(1, 10);
  const PageKey k0{0, 0}, k1{0, 1};
  // Room for either page but not both: whether k0 is still pinned is visible.
  PageCache cache(pages.loader(), opts(page_bytes(k0) + page_bytes(k1) - 1, 0, false));

  PageCache::Handle a = cache.pin(k0);
  ASSERT_TRUE(content_ok(a));
  PageCache::Handle b = std::move(a);
  EXPECT_TRUE(a.empty());
  EXPECT_FALSE(a);
  EXPECT_EQ(a.data(), nullptr);
  EXPECT_EQ(a.size(), 0u);
  EXPECT_TRUE(content_ok(b));
  EXPECT_EQ(cache.pinned_pages(), 1u);

  PageCache::Handle c;
  EXPECT_TRUE(c.empty());
  c = std::move(b);
  EXPECT_TRUE(b.empty());
  PageCache::Handle& alias = c;
  c = std::move(alias);  // self-move keeps the pin
  EXPECT_TRUE(content_ok(c));
  EXPECT_EQ(cache.pinned_pages(), 1u);

  a.reset();  // empty handles release nothing
  b.reset();
  b.reset();
  EXPECT_EQ(cache.pinned_pages(), 1u);
  EXPECT_EQ(kind_of([&] { cache.pin(k1); }), ErrorKind::Usage);  // k0 still pinned

  c.reset();
  c.reset();  // second release is a no-op
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(cache.pinned_pages(), 0u);
  PageCache::Handle d = cache.pin(k1);  // k0 can go now
  EXPECT_TRUE(content_ok(d));
  EXPECT_EQ(cache.stats().evictions, 1u);

  // Move-assigning onto a handle that holds a pin releases that pin.
  PageCache big(pages.loader(), opts(1 << 20, 0, false));
  PageCache::Handle x = big.pin(k0), y = big.pin(k1);
  EXPECT_EQ(big.pinned_pages(), 2u);
  x = std::move(y);
  EXPECT_EQ(big.pinned_pages(), 1u);
  EXPECT_EQ(x.key(), k1);
  EXPECT_TRUE(content_ok(x));
}

class PageCacheSweep : public ::testing::TestWithParam<SweepCase> {};

TEST_P(PageCacheSweep, SweepSmallerThanDataReadsEveryPageOnce) {
  constexpr std::uint64_t n = 300;
  const SweepCase c = GetParam();
  for (int round = 0; round < (c.background ? 10 : 1); ++round) {  // background: vary the interleaving
    SyntheticPages pages(1, n);
    CacheStats s;
    {
      PageCache cache(pages.loader(), opts(16 * kMaxPage, c.read_ahead, c.background));
      pages.declare(cache, 1);
      for (std::uint64_t p = 0; p < n; ++p) {
        PageCache::Handle h = cache.pin({0, p});
        ASSERT_TRUE(content_ok(h)) << p;
      }
      s = cache.stats();
      EXPECT_EQ(s.pages_read, n);
      EXPECT_EQ(s.hits + s.misses, n);
      EXPECT_GT(s.evictions, 0u);
      EXPECT_LE(s.peak_resident_bytes, cache.budget());
      if (c.read_ahead > 0 && !c.background) {  // deterministic: pages 0 and 1 miss, the rest was read ahead
        EXPECT_EQ(s.misses, 2u);
        EXPECT_EQ(s.hits, n - 2);
      }
    }  // joins the worker: nothing can be read after this
    EXPECT_EQ(pages.total_loads(), n);
    for (std::uint64_t p = 0; p < n; ++p) ASSERT_EQ(pages.loads({0, p}), 1) << "page " << p;
  }
}

TEST_P(PageCacheSweep, SecondSweepWithLargeBudgetReadsNothing) {
  constexpr std::uint64_t n = 300;
  const SweepCase c = GetParam();
  SyntheticPages pages(1, n);
  PageCache cache(pages.loader(), opts(n * kMaxPage, c.read_ahead, c.background));
  pages.declare(cache, 1);
  for (std::uint64_t p = 0; p < n; ++p) ASSERT_TRUE(content_ok(cache.pin({0, p})));
  EXPECT_EQ(cache.stats().pages_read, n);
  cache.reset_stats();
  CacheStats s = cache.stats();
  EXPECT_EQ(s.pages_read, 0u);
  EXPECT_EQ(s.peak_resident_bytes, s.resident_bytes);
  EXPECT_GT(s.resident_bytes, 0u);
  for (std::uint64_t p = 0; p < n; ++p) ASSERT_TRUE(content_ok(cache.pin({0, p})));
  s = cache.stats();
  EXPECT_EQ(s.pages_read, 0u);
  EXPECT_EQ(s.bytes_read, 0u);
  EXPECT_EQ(s.hits, n);
  EXPECT_EQ(s.misses, 0u);
  EXPECT_EQ(s.evictions, 0u);
  EXPECT_EQ(pages.total_loads(), n);
}

INSTANTIATE_TEST_SUITE_P(PageCache, PageCacheSweep,
                         ::testing::Values(SweepCase{0, false}, SweepCase{4, false}, SweepCase{4, true},
                                           SweepCase{8, true}),
                         [](const auto& info) {
                           return "ReadAhead" + std::to_string(info.param.read_ahead) +
                                  (info.param.background ? "Background" : "Inline");
                         });

TEST(PageCache, CountsBytesAsTheLoaderReports) {
  SyntheticPages pages(1, 20);
  PageCache cache(pages.loader(), opts(1 << 20, 0, false));
  std::uint64_t decoded = 0, compressed = 0;
  for (std::uint64_t p = 0; p < 20; ++p) {
    cache.pin({0, p});
    decoded += page_bytes({0, p});
    compressed += page_bytes({0, p}) / 2 + 1;
  }
  const CacheStats s = cache.stats();
  EXPECT_EQ(s.bytes_decompressed, decoded);
  EXPECT_EQ(s.bytes_read, compressed);
  EXPECT_EQ(s.resident_bytes, decoded);
  EXPECT_EQ(s.peak_resident_bytes, decoded);
}

TEST(PageCache, EvictedPagesReloadCorrectly) {
  SyntheticPages pages(2, 100);
  PageCache cache(pages.loader(), opts(4 * kMaxPage, 0, false));
  const PageKey a{0, 7};
  EXPECT_TRUE(content_ok(cache.pin(a)));
  for (std::uint64_t p = 0; p < 100; ++p) EXPECT_TRUE(content_ok(cache.pin({1, p})));
  EXPECT_GT(cache.stats().evictions, 0u);
  EXPECT_EQ(pages.loads(a), 1);
  PageCache::Handle h = cache.pin(a);  // evicted: read again, same bytes
  EXPECT_TRUE(content_ok(h));
  EXPECT_EQ(pages.loads(a), 2);
  EXPECT_EQ(cache.stats().pages_read, 102u);
  EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
}

TEST(PageCache, PinnedPagesAreNeverEvicted) {
  for (bool background : {false, true}) {
    SyntheticPages pages(2, 200);
    PageCache cache(pages.loader(), opts(12 * kMaxPage, 4, background));
    pages.declare(cache, 2);
    std::vector<PageCache::Handle> held;
    std::vector<const std::uint8_t*> where;
    for (std::uint64_t p = 0; p < 5; ++p) {
      held.push_back(cache.pin({0, p * 3}));
      where.push_back(held.back().data());
    }
    std::mt19937_64 rng(7);
    for (int i = 0; i < 2000; ++i) {  // sweeps and random pins on the other array: heavy pressure
      const std::uint64_t p = i < 400 ? static_cast<std::uint64_t>(i % 200) : rng() % 200;
      ASSERT_TRUE(content_ok(cache.pin({1, p})));
    }
    EXPECT_GT(cache.stats().evictions, 100u);
    EXPECT_EQ(cache.pinned_pages(), 5u);
    for (std::size_t i = 0; i < held.size(); ++i) {
      EXPECT_EQ(held[i].data(), where[i]);
      EXPECT_TRUE(content_ok(held[i]));
      PageCache::Handle again = cache.pin(held[i].key());  // a hit, not a reload
      EXPECT_EQ(again.data(), where[i]);
      EXPECT_EQ(pages.loads(held[i].key()), 1);
    }
    EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
  }
}

TEST(PageCache, BudgetTooSmallForThePinsThrowsUsage) {
  SyntheticPages pages(1, 100);
  PageCache cache(pages.loader(), opts(3 * kMaxPage, 0, false));
  std::vector<PageCache::Handle> held;
  std::uint64_t p = 0;
  std::string message;
  try {
    for (; p < 100; ++p) held.push_back(cache.pin({0, p}));
    FAIL() << "100 pinned pages fit a 3-page budget";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    message = e.what();
  }
  EXPECT_NE(message.find("too small"), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(held.size()) + " pages pinned"), std::string::npos) << message;
  EXPECT_GE(held.size(), 3u);
  EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
  for (const auto& h : held) EXPECT_TRUE(content_ok(h));
  // The page that did not fit is not cached: after releasing, it is read again.
  const int before = pages.loads({0, p});
  held.clear();
  EXPECT_TRUE(content_ok(cache.pin({0, p})));
  EXPECT_EQ(pages.loads({0, p}), before + 1);
  EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
}

TEST(PageCache, PageLargerThanTheBudgetThrowsUsage) {
  SyntheticPages pages(1, 4);
  PageCache cache(pages.loader(), opts(kMinPage - 1, 0, false));
  try {
    cache.pin({0, 0});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    EXPECT_NE(std::string(e.what()).find("too small"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cache.stats().resident_bytes, 0u);
  EXPECT_EQ(kind_of([&] { PageCache bad(pages.loader(), opts(0, 0, false)); }), ErrorKind::Usage);
  EXPECT_EQ(kind_of([&] { PageCache bad(nullptr, opts(1024, 0, false)); }), ErrorKind::Usage);
}

TEST(PageCache, PinBeyondTheArrayIsUsageAndReadAheadStopsAtTheEnd) {
  for (bool background : {false, true}) {
    SyntheticPages pages(1, 10);  // its loader throws beyond page 9
    CacheStats s;
    {
      PageCache cache(pages.loader(), opts(1 << 20, 8, background));
      pages.declare(cache, 1);
      EXPECT_EQ(kind_of([&] { cache.pin({0, 10}); }), ErrorKind::Usage);
      for (std::uint64_t p = 0; p < 10; ++p) EXPECT_TRUE(content_ok(cache.pin({0, p})));
      s = cache.stats();
    }
    EXPECT_EQ(s.pages_read, 10u);
    EXPECT_EQ(pages.total_loads(), 10u);
  }
}

namespace {

// A loader that blocks until opened, then fails or succeeds as told.
class GatedLoader {
 public:
  PageCache::Loader loader() {
    return [this](PageKey k, PageBytes& out) -> std::uint64_t {
      calls.fetch_add(1);
      {
        std::unique_lock lock(mu_);
        cv_.wait(lock, [&] { return open_; });
      }
      if (fail.load()) throw Error(ErrorKind::Corrupt, "synthetic: checksum mismatch");
      out.resize(page_bytes(k));
      for (std::size_t i = 0; i < out.size(); ++i) out[i] = byte_at(k, i);
      return out.size();
    };
  }
  void open() {
    std::lock_guard lock(mu_);
    open_ = true;
    cv_.notify_all();
  }
  std::atomic<int> calls{0};
  std::atomic<bool> fail{false};

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool open_ = false;
};

}  // namespace

TEST(PageCache, ConcurrentMissesOfOnePageCallTheLoaderOnce) {
  constexpr int kThreads = 6;
  GatedLoader gate;
  PageCache cache(gate.loader(), opts(1 << 20, 0, false));
  const PageKey key{3, 42};
  std::vector<PageCache::Handle> got(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) threads.emplace_back([&, t] { got[t] = cache.pin(key); });
  spin_until([&] {  // every thread is in pin(): one loads, the others wait for it
    const CacheStats s = cache.stats();
    return s.hits + s.misses == kThreads;
  });
  gate.open();
  for (auto& t : threads) t.join();
  EXPECT_EQ(gate.calls.load(), 1);
  const CacheStats s = cache.stats();
  EXPECT_EQ(s.misses, 1u);
  EXPECT_EQ(s.hits, kThreads - 1u);
  EXPECT_EQ(s.pages_read, 1u);
  for (const auto& h : got) {
    EXPECT_TRUE(content_ok(h));
    EXPECT_EQ(h.data(), got[0].data());
  }
  EXPECT_EQ(cache.pinned_pages(), 1u);
}

TEST(PageCache, ConcurrentLoaderErrorReachesEveryWaiterAndALaterPinRetries) {
  constexpr int kThreads = 5;
  GatedLoader gate;
  gate.fail = true;
  PageCache cache(gate.loader(), opts(1 << 20, 0, false));
  const PageKey key{1, 9};
  std::atomic<int> corrupt{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&] {
      try {
        cache.pin(key);
      } catch (const Error& e) {
        if (e.kind() == ErrorKind::Corrupt && std::string(e.what()).find("checksum") != std::string::npos)
          corrupt.fetch_add(1);
      }
    });
  spin_until([&] {
    const CacheStats s = cache.stats();
    return s.hits + s.misses == kThreads;
  });
  gate.open();
  for (auto& t : threads) t.join();
  EXPECT_EQ(corrupt.load(), kThreads);
  EXPECT_EQ(gate.calls.load(), 1);
  CacheStats s = cache.stats();
  EXPECT_EQ(s.pages_read, 0u);
  EXPECT_EQ(s.resident_bytes, 0u);

  EXPECT_EQ(kind_of([&] { cache.pin(key); }), ErrorKind::Corrupt);  // nothing was cached: tries again
  EXPECT_EQ(gate.calls.load(), 2);
  gate.fail = false;
  PageCache::Handle h = cache.pin(key);
  EXPECT_TRUE(content_ok(h));
  EXPECT_EQ(gate.calls.load(), 3);
  EXPECT_EQ(cache.stats().pages_read, 1u);
}

// CacheStats' times against sleeps that bound them from below (no upper
// bound: the machine may be slow, never faster than a sleep). A waiter's
// clock starts under the lock that also counts its hit, so once the hits
// show, every waiter's wait covers the sleep before the gate opens.
TEST(PageCache, LoadAndWaitTimesCoverTheLoadsAndTheWaits) {
  constexpr int kThreads = 3;
  constexpr std::uint64_t kGateNs = 30'000'000;
  GatedLoader gate;
  PageCache cache(gate.loader(), opts(1 << 20, 0, false));
  const PageKey key{2, 5};
  {
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) threads.emplace_back([&] { cache.pin(key); });
    spin_until([&] {
      const CacheStats s = cache.stats();
      return s.hits + s.misses == kThreads;
    });
    std::this_thread::sleep_for(std::chrono::nanoseconds(kGateNs));
    gate.open();
    for (auto& t : threads) t.join();
  }
  CacheStats s = cache.stats();
  ASSERT_EQ(s.misses, 1u);
  EXPECT_GE(s.load_ns, kGateNs);
  EXPECT_EQ(s.demand_load_ns, s.load_ns);  // the one load was the miss's
  EXPECT_GE(s.load_wait_ns, (kThreads - 1) * kGateNs);
  // A hit on the resident page loads and waits for nothing.
  const std::uint64_t load = s.load_ns, wait = s.load_wait_ns;
  cache.pin(key);
  s = cache.stats();
  EXPECT_EQ(s.load_ns, load);
  EXPECT_EQ(s.load_wait_ns, wait);
  cache.reset_stats();
  s = cache.stats();
  EXPECT_EQ(s.load_ns + s.demand_load_ns + s.load_wait_ns, 0u);

  // Failed loads count too.
  GatedLoader failing;
  failing.fail = true;
  PageCache bad(failing.loader(), opts(1 << 20, 0, false));
  std::thread t([&] { EXPECT_EQ(kind_of([&] { bad.pin(key); }), ErrorKind::Corrupt); });
  spin_until([&] { return failing.calls.load() == 1; });
  std::this_thread::sleep_for(std::chrono::nanoseconds(kGateNs));
  failing.open();
  t.join();
  EXPECT_GE(bad.stats().load_ns, kGateNs);
  EXPECT_EQ(bad.stats().pages_read, 0u);
}

// The read-ahead's loads count in load_ns but not in demand_load_ns.
TEST(PageCache, ReadAheadLoadsAreNotTheMissesTime) {
  constexpr std::uint64_t kLoadNs = 1'000'000, kPages = 24;
  SyntheticPages src(1, kPages);
  auto slow = [inner = src.loader(), kLoadNs](PageKey k, PageBytes& out) {
    std::this_thread::sleep_for(std::chrono::nanoseconds(kLoadNs));
    return inner(k, out);
  };
  PageCache cache(slow, opts(1 << 20, 4, false));  // read-ahead on the pinning thread
  src.declare(cache, 1);
  for (std::uint64_t p = 0; p < kPages; ++p) cache.pin({0, p});
  const CacheStats s = cache.stats();
  ASSERT_EQ(s.pages_read, kPages);
  ASSERT_LT(s.misses, kPages);  // read-ahead loaded the rest
  EXPECT_GE(s.demand_load_ns, s.misses * kLoadNs);
  EXPECT_GE(s.load_ns - s.demand_load_ns, (kPages - s.misses) * kLoadNs);
  EXPECT_EQ(s.load_wait_ns, 0u);  // one thread: nothing in flight to wait for
}

TEST(PageCache, RandomAccessNeverExceedsTheBudget) {
  for (std::uint64_t budget : {3 * kMaxPage, 7 * kMaxPage + 13, 40 * kMaxPage}) {
    for (int mode = 0; mode < 3; ++mode) {  // no read-ahead, inline, background
      SyntheticPages pages(3, 120);
      PageCache cache(pages.loader(), opts(budget, mode == 0 ? 0 : 4, mode == 2));
      pages.declare(cache, 3);
      std::mt19937_64 rng(budget * 3 + mode);
      PageCache::Handle held[2];  // up to 2 pins held across the next pins
      PageKey k{0, 0};
      for (int i = 0; i < 3000; ++i) {
        if (rng() % 4 == 0) {  // a short sequential run, to trigger read-ahead
          k.page = k.page + 1 < 120 ? k.page + 1 : 0;
        } else {
          k = {static_cast<std::uint32_t>(rng() % 3), rng() % 120};
        }
        PageCache::Handle h = cache.pin(k);
        ASSERT_TRUE(content_ok(h));
        if (rng() % 3 == 0) held[rng() % 2] = std::move(h);
      }
      const CacheStats s = cache.stats();
      EXPECT_LE(s.peak_resident_bytes, budget);
      EXPECT_LE(s.resident_bytes, budget);
      EXPECT_EQ(s.hits + s.misses, 3000u);
      EXPECT_GT(s.evictions, 0u);
    }
  }
}

TEST(PageCache, ConcurrentReadersRandomPins) {
  constexpr int kThreads = 8, kPins = 1500;
  constexpr std::uint32_t kArrays = 3;
  constexpr std::uint64_t kPages = 150;
  for (bool background : {false, true}) {
    SyntheticPages pages(kArrays, kPages);
    // 8 threads x 2 held pins + the page being admitted always fit.
    PageCache cache(pages.loader(), opts(20 * kMaxPage, 4, background));
    pages.declare(cache, kArrays);
    std::atomic<int> bad{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
      threads.emplace_back([&, t] {
        std::mt19937_64 rng(1000 + t);
        PageCache::Handle held[2];
        PageKey k{0, 0};
        for (int i = 0; i < kPins; ++i) {
          if (rng() % 3 == 0) {
            k.page = k.page + 1 < kPages ? k.page + 1 : 0;
          } else {
            k = {static_cast<std::uint32_t>(rng() % kArrays), rng() % kPages};
          }
          PageCache::Handle h = cache.pin(k);
          if (!content_ok(h)) bad.fetch_add(1);
          if (rng() % 2 == 0) held[rng() % 2] = std::move(h);
          if (!held[0].empty() && !content_ok(held[0])) bad.fetch_add(1);
        }
      });
    for (auto& th : threads) th.join();
    EXPECT_EQ(bad.load(), 0);
    const CacheStats s = cache.stats();
    EXPECT_EQ(s.hits + s.misses, std::uint64_t{kThreads} * kPins);
    EXPECT_LE(s.peak_resident_bytes, cache.budget());
    EXPECT_GT(s.evictions, 0u);
    EXPECT_EQ(cache.pinned_pages(), 0u);
    EXPECT_GE(s.pages_read, s.misses);
  }
}

// The unlocked hit path (page_cache.cpp, fast_pin) against evictions and
// failed loads: threads move two handles each from page to page through
// pin_into, as table cursors do, over a hot set that mostly stays resident
// (unlocked hits) and a cold set that keeps the hand evicting, while every
// fifth page fails every other load (slots going Failed and back to the
// free list under the racing increments). Every pin that returns must hold
// its own page's bytes, every failure be the loader's, and at the end
// nothing is pinned and every call was counted once, as a hit or a miss.
TEST(PageCache, ConcurrentUnlockedHitsRaceEvictionsAndFailedLoads) {
  constexpr int kThreads = 6, kPins = 4000;
  constexpr std::uint64_t kPages = 120, kHot = 12;
  std::vector<std::atomic<int>> attempts(kPages);
  auto loader = [&](PageKey k, PageBytes& out) -> std::uint64_t {
    if (k.page % 5 == 2 && attempts[k.page].fetch_add(1) % 2 == 0)
      throw Error(ErrorKind::BadInput, "synthetic: a failing read");
    out.resize(page_bytes(k));
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = byte_at(k, i);
    return out.size();
  };
  for (bool background : {false, true}) {
    // The hot set and every thread's two handles fit, with room to evict.
    PageCache cache(loader, opts((kHot + 2 * kThreads + 8) * kMaxPage, 2, background));
    cache.set_array_pages(0, kPages);
    std::atomic<int> bad{0}, failed{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
      threads.emplace_back([&, t] {
        std::mt19937_64 rng(77 + t);
        PageCache::Handle h[2];
        for (int i = 0; i < kPins; ++i) {
          const std::uint64_t page = rng() % 4 != 0 ? rng() % kHot : kHot + rng() % (kPages - kHot);
          PageCache::Handle& into = h[rng() % 2];
          try {
            cache.pin_into(into, {0, page});
            if (!content_ok(into) || into.key().page != page) bad.fetch_add(1);
          } catch (const Error& e) {
            if (e.kind() != ErrorKind::BadInput || !into.empty()) bad.fetch_add(1);
            failed.fetch_add(1);
          }
          if (!h[0].empty() && !content_ok(h[0])) bad.fetch_add(1);
        }
      });
    for (auto& th : threads) th.join();
    EXPECT_EQ(bad.load(), 0);
    EXPECT_GT(failed.load(), 0);
    const CacheStats s = cache.stats();
    EXPECT_EQ(s.hits + s.misses, std::uint64_t{kThreads} * kPins);
    EXPECT_GT(s.hits, s.misses);  // the hot set hits, most of it unlocked
    EXPECT_GT(s.evictions, 0u);
    EXPECT_LE(s.peak_resident_bytes, cache.budget());
    EXPECT_EQ(cache.pinned_pages(), 0u);
  }
}

TEST(PageCache, ConcurrentSweepsReadEachPageOnce) {
  constexpr int kThreads = 4;
  constexpr std::uint64_t kPages = 200;
  for (bool background : {false, true}) {
    SyntheticPages pages(kThreads, kPages);
    {
      PageCache cache(pages.loader(), opts(40 * kMaxPage, 4, background));
      pages.declare(cache, kThreads);
      std::atomic<int> bad{0};
      std::vector<std::thread> threads;
      for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
          for (std::uint64_t p = 0; p < kPages; ++p)
            if (!content_ok(cache.pin({static_cast<std::uint32_t>(t), p}))) bad.fetch_add(1);
        });
      for (auto& th : threads) th.join();
      EXPECT_EQ(bad.load(), 0);
      EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
      EXPECT_GT(cache.stats().evictions, 0u);
    }
    for (std::uint32_t a = 0; a < kThreads; ++a)
      for (std::uint64_t p = 0; p < kPages; ++p) ASSERT_EQ(pages.loads({a, p}), 1) << a << "/" << p;
  }
}

// Threads that sweep parts of one array side by side each get read-ahead:
// pins taken in strict turns (thread 0's page, thread 1's, ...) so that
// every pin of a thread follows another thread's pin of the same array.
namespace {
// `threads` threads, thread t pinning pages t part .. (t + 1) part - 1 of
// `array`, in strict turns (thread 0's next page, thread 1's, ...): every
// pin of a thread follows another thread's pin of the array. Returns the
// pins whose bytes were wrong.
int sweep_parts_in_turns(PageCache& cache, std::uint32_t array, int threads, std::uint64_t part) {
  std::atomic<std::uint64_t> turn{0};
  std::atomic<int> bad{0};
  std::vector<std::thread> ts;
  for (int t = 0; t < threads; ++t)
    ts.emplace_back([&, t] {
      for (std::uint64_t i = 0; i < part; ++i) {
        while (turn.load(std::memory_order_acquire) != i * threads + static_cast<std::uint64_t>(t))
          std::this_thread::yield();
        if (!content_ok(cache.pin({array, static_cast<std::uint64_t>(t) * part + i}))) bad.fetch_add(1);
        turn.fetch_add(1, std::memory_order_release);
      }
    });
  for (auto& th : ts) th.join();
  return bad.load();
}
}  // namespace

// Each thread misses its first page (no stream yet) and its second (the
// stream starts there), then finds every page read ahead. With one last
// page per array, no thread's pins were ever seen as a stream: every pin
// was a miss.
// Forty threads likewise: each keeps its own stream (an array holds up to
// 256).
TEST(PageCache, ThreadsSweepingOneArrayEachReadAhead) {
  for (const auto& [threads, part] : {std::pair<int, std::uint64_t>{4, 40}, {40, 10}}) {
    SCOPED_TRACE(threads);
    const std::uint64_t n = static_cast<std::uint64_t>(threads) * part;
    SyntheticPages pages(1, n);
    PageCache cache(pages.loader(), opts(1000 * kMaxPage, 4, false));  // inline read-ahead: deterministic
    pages.declare(cache, 1);
    EXPECT_EQ(sweep_parts_in_turns(cache, 0, threads, part), 0);
    const CacheStats s = cache.stats();
    EXPECT_EQ(s.misses, 2u * threads);
    EXPECT_EQ(s.hits, threads * (part - 2));
    // A part's window near its end reaches the first pages of the next
    // part, which that part's thread pinned long before: still resident,
    // they are not scheduled again.
    EXPECT_EQ(pages.total_loads(), n);
  }
}

// One thread reading two streams in turn: two arrays whose ids are 8
// apart, or the same array id in two caches (`dicer transfer` reads a
// fine and a coarse store so). Each is a stream of its own: two misses
// each, the rest read ahead.
TEST(PageCache, OneThreadsStreamsAreTrackedPerCacheAndArray) {
  constexpr std::uint64_t kPages = 200;
  {
    SyntheticPages pages(10, kPages);
    PageCache cache(pages.loader(), opts(400 * kMaxPage, 4, false));
    pages.declare(cache, 10);
    for (std::uint64_t p = 0; p < kPages; ++p) {
      ASSERT_TRUE(content_ok(cache.pin({1, p})));
      ASSERT_TRUE(content_ok(cache.pin({9, p})));
    }
    EXPECT_EQ(cache.stats().misses, 4u);
  }
  SyntheticPages a(4, kPages), b(4, kPages);
  PageCache ca(a.loader(), opts(400 * kMaxPage, 4, false)), cb(b.loader(), opts(400 * kMaxPage, 4, false));
  a.declare(ca, 4), b.declare(cb, 4);
  for (std::uint64_t p = 0; p < kPages; ++p) {
    ASSERT_TRUE(content_ok(ca.pin({3, p})));
    ASSERT_TRUE(content_ok(cb.pin({3, p})));
  }
  EXPECT_EQ(ca.stats().misses, 2u);
  EXPECT_EQ(cb.stats().misses, 2u);
}

// A sweep on four threads ends; a sweep of another array on one thread
// follows, under a budget that holds the windows of two streams but not
// of five. The four stopped streams stop counting after a few pins of the
// new one (4 x the streams in use: 20 here): read-ahead resumes within
// its first pages, not after hundreds.
TEST(PageCache, AStoppedSweepsStreamsLeaveReadAheadItsRoomSoon) {
  constexpr int kThreads = 4;
  constexpr std::uint64_t kPart = 30, kPages = 200;
  SyntheticPages pages(2, kPages);
  PageCache cache(pages.loader(), opts(48 * kMaxPage, 4, false));
  pages.declare(cache, 2);
  EXPECT_EQ(sweep_parts_in_turns(cache, 0, kThreads, kPart), 0);
  cache.reset_stats();
  for (std::uint64_t p = 0; p < kPages; ++p) ASSERT_TRUE(content_ok(cache.pin({1, p})));
  EXPECT_LE(cache.stats().misses, 2u + 4u * (kThreads + 1));
  for (std::uint64_t p = 0; p < kPages; ++p) EXPECT_EQ(pages.loads({1, p}), 1) << "page " << p;
}

// Read-ahead's headroom counts the streams that read now. Random queries
// that pin a page and then the next start streams that never go on, and a
// sweep that looks back a page and goes on is one stream, not two: after
// either, a sweep of another array under a budget that holds only a few
// streams' windows still reads ahead (two misses).
TEST(PageCache, StreamsThatStoppedLeaveReadAheadItsRoom) {
  {
    SyntheticPages pages(4, 1000);
    PageCache cache(pages.loader(), opts(600 * kMaxPage, 4, false));
    pages.declare(cache, 4);
    std::mt19937_64 rng(1);
    for (int i = 0; i < 30000; ++i) {
      const auto a = static_cast<std::uint32_t>(rng() % 3);
      const std::uint64_t p = rng() % 99;
      cache.pin({a, p});
      if (rng() % 8 == 0) cache.pin({a, p + 1});
    }
    cache.reset_stats();
    for (std::uint64_t p = 0; p < 1000; ++p) ASSERT_TRUE(content_ok(cache.pin({3, p})));
    EXPECT_EQ(cache.stats().misses, 2u);
  }
  SyntheticPages pages(2, 400);
  PageCache cache(pages.loader(), opts(64 * kMaxPage, 4, false));
  pages.declare(cache, 2);
  for (std::uint64_t p = 1; p < 60; ++p) {
    cache.pin({0, p});
    cache.pin({0, p - 1});
    cache.pin({0, p});
  }
  cache.reset_stats();
  for (std::uint64_t p = 0; p < 400; ++p) ASSERT_TRUE(content_ok(cache.pin({1, p})));
  EXPECT_EQ(cache.stats().misses, 2u);
  for (std::uint64_t p = 0; p < 400; ++p) EXPECT_EQ(pages.loads({1, p}), 1) << "page " << p;
}

// A declared array's pages are found through its page table, others (and
// ids past the table's range) through the hash map; declaring or
// re-declaring a page count moves resident pages between the two. Any
// lookup that lost a page would load it again: the loads are counted.
TEST(PageCache, ResidentPagesStayFoundAcrossDeclarations) {
  std::map<std::pair<std::uint32_t, std::uint64_t>, int> loads;
  PageCache cache(
      [&](PageKey k, PageBytes& out) -> std::uint64_t {
        ++loads[{k.array, k.page}];
        out.resize(page_bytes(k));
        for (std::size_t i = 0; i < out.size(); ++i) out[i] = byte_at(k, i);
        return out.size();
      },
      opts(1 << 20, 0, false));
  const std::uint32_t arrays[] = {0, 3, 4095, 4096, 1u << 31};
  auto pin_all = [&](std::uint64_t pages) {
    for (std::uint32_t a : arrays)
      for (std::uint64_t p = 0; p < pages; ++p) {
        const PageCache::Handle h = cache.pin({a, p});
        EXPECT_TRUE(content_ok(h)) << a << " " << p;
      }
  };
  pin_all(6);                                              // undeclared: the map
  for (std::uint32_t a : arrays) cache.set_array_pages(a, 4);  // pages 0-3 move to the tables, 4-5 stay
  pin_all(4);
  const PageCache::Handle held = cache.pin({4096, 2});  // pinned while re-declared
  for (std::uint32_t a : arrays) cache.set_array_pages(a, 8);
  pin_all(6);
  EXPECT_TRUE(content_ok(held));
  for (std::uint32_t a : arrays) cache.set_array_pages(a, 2);  // pages 2-5 back to the map, held among them
  for (std::uint32_t a : arrays) EXPECT_EQ(kind_of([&] { cache.pin({a, 2}); }), ErrorKind::Usage);
  pin_all(2);
  for (std::uint32_t a : arrays) cache.set_array_pages(a, 8);
  pin_all(6);
  for (std::uint32_t a : arrays) {
    for (std::uint64_t p = 0; p < 6; ++p) EXPECT_EQ((loads[{a, p}]), 1) << "array " << a << " page " << p;
    EXPECT_EQ(kind_of([&] { cache.pin({a, 8}); }), ErrorKind::Usage);
  }
  EXPECT_EQ(cache.stats().evictions, 0u);
}

// pin_into(h, key) is h = {} then h = pin(key): the old pin goes first (a
// one-page budget moves from page to page through one handle, where pin()
// while still holding it fails), the page's bytes arrive, and a failing
// load leaves h empty with nothing pinned.
TEST(PageCache, PinIntoReleasesTheOldPinFirst) {
  SyntheticPages pages(1, 10);
  PageCache cache(pages.loader(), opts(kMaxPage, 0, false));
  pages.declare(cache, 1);
  PageCache::Handle h;
  for (std::uint64_t p = 0; p < 10; ++p) {
    cache.pin_into(h, {0, p});
    ASSERT_TRUE(content_ok(h)) << "page " << p;
    EXPECT_EQ(h.key().page, p);
    EXPECT_EQ(cache.pinned_pages(), 1u);
  }
  EXPECT_EQ(kind_of([&] { PageCache::Handle other = cache.pin({0, 0}); }), ErrorKind::Usage);  // h holds the budget
  cache.pin_into(h, {0, 9});  // a hit on its own page
  EXPECT_TRUE(content_ok(h));
  EXPECT_EQ(cache.pinned_pages(), 1u);
  SyntheticPages failing(1, 3);  // page 5 is beyond its end: the loader throws
  PageCache small(failing.loader(), opts(4 * kMaxPage, 0, false));
  PageCache::Handle g;
  small.pin_into(g, {0, 1});
  EXPECT_EQ(kind_of([&] { small.pin_into(g, {0, 5}); }), ErrorKind::BadInput);
  EXPECT_TRUE(g.empty());
  EXPECT_EQ(small.pinned_pages(), 0u);
}

namespace {
// The bytes of a kept page as its directory shows them: page_bytes(k)
// long, as the synthetic loader wrote them.
bool kept_ok(const std::atomic<const std::uint8_t*>* dir, PageKey k) {
  const std::uint8_t* p = dir[k.page].load(std::memory_order_acquire);
  if (p == nullptr) return false;
  for (std::size_t i = 0; i < page_bytes(k); ++i)
    if (p[i] != byte_at(k, i)) return false;
  return true;
}
}  // namespace

TEST(PageCache, KeptPagesStayAtTheirAddressUnderPressureAndNeedNoPin) {
  for (bool background : {false, true}) {
    SyntheticPages pages(2, 200);
    PageCache cache(pages.loader(), opts(12 * kMaxPage, 4, background));
    pages.declare(cache, 2);
    // A page resident before keep_resident is kept at once; one pinned
    // later, when it is admitted; the rest stay unread.
    const std::uint8_t* first = cache.pin({0, 0}).data();
    const auto* dir = cache.keep_resident(0);
    EXPECT_EQ(cache.keep_resident(0), dir) << "idempotent";
    EXPECT_EQ(dir[0].load(), first);
    EXPECT_EQ(dir[1].load(), nullptr);
    cache.pin({0, 3});
    EXPECT_NE(dir[3].load(), nullptr);
    EXPECT_EQ(dir[2].load(), nullptr) << "nothing is read for a kept array in advance";
    const std::uint8_t* third = dir[3].load();
    EXPECT_EQ(cache.stats().kept_bytes, page_bytes({0, 0}) + page_bytes({0, 3}));
    EXPECT_EQ(cache.pinned_pages(), 0u) << "the cache's own pins are not handles";
    std::mt19937_64 rng(11);
    for (int i = 0; i < 2000; ++i) {  // sweeps and random pins on the other array: heavy pressure
      const std::uint64_t p = i < 400 ? static_cast<std::uint64_t>(i % 200) : rng() % 200;
      ASSERT_TRUE(content_ok(cache.pin({1, p})));
    }
    EXPECT_GT(cache.stats().evictions, 100u);
    EXPECT_EQ(dir[0].load(), first);
    EXPECT_EQ(dir[3].load(), third);
    EXPECT_TRUE(kept_ok(dir, {0, 0}));
    EXPECT_TRUE(kept_ok(dir, {0, 3}));
    EXPECT_EQ(pages.loads({0, 0}), 1);
    EXPECT_EQ(pages.loads({0, 3}), 1);
    // A pin of a kept page is still a hit on the same bytes.
    EXPECT_EQ(cache.pin({0, 3}).data(), third);
    EXPECT_EQ(pages.loads({0, 3}), 1);
    const CacheStats s = cache.stats();
    EXPECT_LE(s.peak_resident_bytes, cache.budget());
    EXPECT_LE(s.kept_bytes, s.resident_bytes);
    cache.reset_stats();
    EXPECT_EQ(cache.stats().kept_bytes, s.kept_bytes) << "kept_bytes is a state, not a counter";
  }
}

TEST(PageCache, ReadAheadPagesOfAKeptArrayAreKept) {
  SyntheticPages pages(1, 50);
  PageCache cache(pages.loader(), opts(200 * kMaxPage, 4, false));  // read-ahead on the pinning thread
  pages.declare(cache, 1);
  const auto* dir = cache.keep_resident(0);
  cache.pin({0, 0});
  // A stream: pages 2..17 are read ahead before pin() returns (a kept
  // array's window is 4 x read_ahead_pages).
  cache.pin({0, 1});
  for (std::uint64_t p = 2; p <= 17; ++p) EXPECT_TRUE(kept_ok(dir, {0, p})) << "page " << p;
  EXPECT_EQ(dir[18].load(), nullptr);
  for (std::uint64_t p = 0; p <= 17; ++p) EXPECT_EQ(pages.loads({0, p}), 1);
}

// A sweep over a kept array as a table reads it: through the directory
// where a page is published, a pin where not. The pages read ahead are
// read without pins, so the cache never sees them pinned; the next miss
// still continues the stream (its previous page is kept), and read-ahead
// keeps going: a handful of misses, not one or two per window.
TEST(PageCache, ASweepThroughTheDirectoryKeepsReadingAhead) {
  for (bool background : {false, true}) {
    constexpr std::uint64_t kPages = 120;
    SyntheticPages pages(1, kPages);
    PageCache cache(pages.loader(), opts(400 * kMaxPage, 4, background));
    pages.declare(cache, 1);
    const auto* dir = cache.keep_resident(0);
    for (std::uint64_t p = 0; p < kPages; ++p) {
      if (dir[p].load(std::memory_order_acquire) == nullptr) cache.pin({0, p});
      ASSERT_TRUE(kept_ok(dir, {0, p})) << "page " << p;
    }
    const CacheStats s = cache.stats();
    EXPECT_EQ(pages.total_loads(), kPages) << "every page once";
    // Inline read-ahead: a miss per window of 16 pages and the next (8 in
    // all). Without the kept page counting as the stream's previous pin,
    // each window of 4 ended in two misses (40). A background worker
    // races this loop, which does nothing between pages: no bound there.
    if (!background) {
      EXPECT_LE(s.misses, 9u);
    }
  }
}

TEST(PageCache, KeptPagesCountAgainstTheBudgetAndKeepingIsUsageChecked) {
  SyntheticPages pages(2, 20);
  PageCache cache(pages.loader(), opts(4 * kMaxPage, 0, false));
  pages.declare(cache, 2);
  const auto* dir = cache.keep_resident(0);
  // Kept pages fill the budget: they are pinned for good, so a page that
  // does not fit beside them is refused, naming them.
  std::string message;
  std::uint64_t p = 0;
  try {
    for (; p < 20; ++p) cache.pin({0, p});
    FAIL() << "20 kept pages fit a 4-page budget";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage);
    message = e.what();
  }
  EXPECT_NE(message.find("too small"), std::string::npos) << message;
  EXPECT_NE(message.find("kept resident"), std::string::npos) << message;
  EXPECT_GE(p, 3u);
  for (std::uint64_t q = 0; q < p; ++q) EXPECT_TRUE(kept_ok(dir, {0, q}));
  EXPECT_EQ(dir[p].load(), nullptr) << "the page that did not fit is not published";
  EXPECT_LE(cache.stats().peak_resident_bytes, cache.budget());
  EXPECT_EQ(cache.pinned_pages(), 0u);
  // An array never declared cannot be kept; a kept array's count is fixed.
  EXPECT_EQ(kind_of([&] { cache.keep_resident(7); }), ErrorKind::Usage);
  EXPECT_EQ(kind_of([&] { cache.set_array_pages(0, 30); }), ErrorKind::Usage);
  EXPECT_TRUE(kept_ok(dir, {0, 0})) << "the refused declaration changed nothing";
}

// Readers of a kept array's directory (no pins) beside threads that pin
// and evict pages of another array, and first loads of kept pages
// racing each other: every page a reader finds is whole, it never moves,
// and each kept page is loaded once. Runs under ThreadSanitizer.
TEST(PageCache, ConcurrentKeptReadersBesideEvictions) {
  constexpr int kThreads = 4, kReads = 3000;
  constexpr std::uint64_t kKept = 16, kOther = 120;
  for (bool background : {false, true}) {
    SyntheticPages pages(2, kOther);
    PageCache cache(pages.loader(), opts((kKept + 2 * kThreads + 10) * kMaxPage, 2, background));
    pages.declare(cache, 2);
    const auto* dir = cache.keep_resident(0);
    std::vector<std::atomic<const std::uint8_t*>> seen(kKept);
    std::atomic<int> bad{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
      threads.emplace_back([&, t] {
        std::mt19937_64 rng(5 + t);
        PageCache::Handle h;
        for (int i = 0; i < kReads; ++i) {
          const std::uint64_t p = rng() % kKept;
          const std::uint8_t* at = dir[p].load(std::memory_order_acquire);
          if (at == nullptr) {  // first read: the pinned way, which keeps it
            PageCache::Handle k = cache.pin({0, p});
            at = dir[p].load(std::memory_order_acquire);
            if (at != k.data()) bad.fetch_add(1);
          }
          const std::uint8_t* was = nullptr;
          if (!seen[p].compare_exchange_strong(was, at) && was != at) bad.fetch_add(1);
          if (!kept_ok(dir, {0, p})) bad.fetch_add(1);
          cache.pin_into(h, {1, rng() % kOther});  // pressure on the other array
          if (!content_ok(h)) bad.fetch_add(1);
        }
      });
    for (auto& th : threads) th.join();
    EXPECT_EQ(bad.load(), 0);
    const CacheStats s = cache.stats();
    EXPECT_GT(s.evictions, 0u);
    EXPECT_LE(s.peak_resident_bytes, cache.budget());
    for (std::uint64_t p = 0; p < kKept; ++p) EXPECT_EQ(pages.loads({0, p}), 1) << "kept page " << p;
    EXPECT_EQ(cache.pinned_pages(), 0u);
  }
}
