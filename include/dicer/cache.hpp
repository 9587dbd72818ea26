#pragma once
// PageCache: a bounded, thread-safe cache of decoded pages in front of the
// store. It knows nothing about HDF5: pages come from a Loader function
// (the store's reader supplies one that reads and decodes a chunk).
//
// What it holds. A page is identified by PageKey{array, page}. The cache
// keeps decoded pages up to a byte budget and hands them out as pinned,
// move-only Handles (STYLE.md #5): a pinned page is never evicted, and its
// bytes stay at the same address until the last handle on it is released.
//
// Invariants.
//  1. Byte budget. resident_bytes = the sum of the decoded sizes (size(), not
//     capacity()) of the pages resident in the cache. It never exceeds
//     budget(): a page is admitted only after enough unpinned pages were
//     evicted, and if that is impossible (every resident page is pinned, or
//     the page alone is larger than the budget) pin() throws
//     Error{Usage, "cache budget ... too small: ..."} instead. Bytes of a
//     page being loaded (at most one buffer per loading thread plus one for
//     the read-ahead worker) are not counted until the page is admitted.
//  2. One load per page. While a page is resident or being loaded it is never
//     loaded again: concurrent pins of the same missing page wait for the
//     one load in flight (also when that load is the read-ahead worker's).
//  3. Failed loads store nothing. If the loader throws, the exception is
//     rethrown to the pinning thread and to every thread waiting on that
//     load; nothing is cached for the key, so a later pin() retries.
//
// Eviction: CLOCK (second chance) over a slot table, lazy and checked
// against pins. Releasing a handle only decrements the pin count; pages are
// evicted when room is needed, and the clock hand skips pinned pages and
// pages still loading. See page_cache.cpp for why CLOCK (cost per hit,
// behaviour under sweeps) and the exact victim order.
//
// Read-ahead: a thread's pin() of page p of an array right after its own
// pin of page p-1 starts or continues that thread's sequential stream in
// the array (each thread that sweeps a part of an array has one; up to 256
// per array, the least recently moved replaced). When a pin continues a
// stream and p was a miss or a page that read-ahead brought in, the next
// Options::read_ahead_pages pages of that array are scheduled (topped up
// half a window at a time). With
// background_read_ahead one worker thread loads them (bounded queue; the
// destructor stops and joins it); otherwise the pinning thread loads them
// before pin() returns. Read-ahead only runs for arrays whose page count
// was given by set_array_pages() and never past it, and only while the
// budget (less the kept pages) holds 4 x read_ahead_pages x (one stream
// per array pinned, plus each array's further streams that read now) of
// the largest page seen: a smaller budget would let each stream's
// read-ahead evict the others' pages in use. Read-ahead never evicts
// pinned pages, pages with their reference bit set, or other read-ahead
// pages not yet pinned; if that leaves no room it is skipped (a hot
// working set is not flushed by a speculative read).
// Pages that a sequential stream pins do not get their reference bit set
// (scan resistance), so a sweep evicts its own past pages first. In a
// single sweep whose budget holds at least read_ahead_pages + 3 pages, every
// page is read exactly once (tests/unit/test_page_cache.cpp).
//
// Kept arrays: keep_resident(array) holds an array's pages for good once
// admitted and publishes their addresses, so a reader of a small, hot
// array (a store's coarse tables) finds a page with one load and no pin.
//
// Cost. Hit: O(1), no allocation. A hit on a Ready page of a declared
// array (id below 4096) that is not the calling thread's pin of the page
// after its own last pin of that array (a stream's start or next page) and
// was not brought in by read-ahead takes no lock: a page-table load, a
// look at the thread's own last pins, and one atomic increment on the
// page's slot (page_cache.cpp says why that is safe against eviction). Other hits take the mutex and one
// page-table load (a hash lookup for an array never declared or with an id
// of 4096 or more); when a hit extends a read-ahead window it also does
// read_ahead_pages lookups and, without a background worker, the loads.
// Miss: one loader call made without the lock, plus amortised O(1) clock
// steps (O(resident pages) in the worst case, e.g. when almost everything
// is pinned). Handle release: one atomic decrement, no lock.
//
// Thread safety. All member functions may be called concurrently. The
// loader is called without the cache's lock, from the pinning thread and
// from the read-ahead worker, possibly concurrently for different keys: it
// must be thread-safe (serialise inside it if the file library is not). The
// loader must not call back into the same cache. Every Handle must be
// released before the PageCache is destroyed.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

namespace dicer {

struct PageKey {
  std::uint32_t array = 0;  // which paged array (the store assigns ids)
  std::uint64_t page = 0;   // page index within that array, 0-based
  friend bool operator==(const PageKey&, const PageKey&) = default;
};

struct PageKeyHash {
  std::size_t operator()(const PageKey& k) const noexcept {
    std::uint64_t x = k.page * 0x9E3779B97F4A7C15ull ^ (std::uint64_t{k.array} + 0x632BE59BD9B4E019ull);
    x ^= x >> 29;
    x *= 0xBF58476D1CE4E5B9ull;
    x ^= x >> 32;
    return static_cast<std::size_t>(x);
  }
};

struct CacheStats {
  std::uint64_t pages_read = 0;          // loader calls that succeeded (pins and read-ahead)
  std::uint64_t distinct_pages_read = 0; // different pages among them: pages_read / this = read amplification
  std::uint64_t bytes_read = 0;          // bytes read from the file, as the loader reports (compressed size)
  std::uint64_t bytes_decompressed = 0;  // decoded bytes the loader produced
  std::uint64_t hits = 0;                // pin() calls that found the page resident or already being loaded
  std::uint64_t misses = 0;              // pin() calls that had to call the loader themselves
  std::uint64_t evictions = 0;           // pages dropped to make room
  std::uint64_t resident_bytes = 0;      // decoded bytes resident now (<= budget)
  std::uint64_t peak_resident_bytes = 0; // maximum of resident_bytes since construction or reset_stats()
  std::uint64_t kept_bytes = 0;          // of resident_bytes: pages kept for good (keep_resident)
  // Where a cold run's time went (steady-clock nanoseconds, all threads
  // summed, failed loads included): how much of it a store's reads and
  // decoding cost, and how much of that the threads that asked for pages
  // paid themselves rather than the read-ahead thread.
  std::uint64_t load_ns = 0;         // in the loader, every call
  std::uint64_t demand_load_ns = 0;  // of load_ns: misses, loaded by the pin that needed the page
  std::uint64_t load_wait_ns = 0;    // pins waiting for a page another thread was loading
};

class SpinMutex;  // the cache's lock (page_cache.cpp)

// An allocator whose resize() leaves new bytes as they are: a loader writes
// every byte of its page, and zero-filling 64 KiB first cost a memset per
// page load (bench/README.md, stop 41). The standard containers have no
// resize without initialisation (C++23's resize_and_overwrite is string's
// alone); Boost.Container's default_init is the same idea.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
  friend bool operator==(const DefaultInitAllocator&, const DefaultInitAllocator&) { return true; }
};
// A decoded page's bytes (PageCache::Loader).
using PageBytes = std::vector<std::uint8_t, DefaultInitAllocator<std::uint8_t>>;

class PageCache {
  struct Entry;  // one slot of the cache (page_cache.cpp)
  struct Impl;

 public:
  // Reads and decodes one page into out (resized to the decoded size; a
  // resize leaves the new bytes unset, so write every one); returns the
  // number of bytes read from the file. May throw dicer::Error (e.g.
  // Corrupt); the cache then stores nothing for that key and rethrows to
  // every waiter. Give out exactly its size (out arrives empty): the budget
  // counts size(), so capacity slack would be uncounted memory.
  using Loader = std::function<std::uint64_t(PageKey key, PageBytes& out)>;

  struct Options {
    std::uint64_t budget_bytes = 64ull << 20;  // decoded bytes resident, at most
    unsigned read_ahead_pages = 4;             // 0 disables read-ahead
    bool background_read_ahead = true;         // one worker thread; false: the pinning thread reads ahead
  };

  // Throws Error{Usage} if loader is empty or budget_bytes is 0.
  PageCache(Loader loader, Options options);
  ~PageCache();  // stops and joins the read-ahead worker (a load in progress finishes first)
  PageCache(const PageCache&) = delete;
  PageCache& operator=(const PageCache&) = delete;

  // A pinned page. Move-only; a moved-from or default-constructed handle is
  // empty (data() == nullptr, size() == 0) and releases nothing, so a pin is
  // released exactly once: by reset() or by the destructor of the handle
  // that holds it. data() stays valid and unchanged while the handle holds
  // the pin. Must not outlive its PageCache.
  class Handle {
   public:
    Handle() = default;
    Handle(Handle&& other) noexcept;
    Handle& operator=(Handle&& other) noexcept;  // releases the pin this handle held, if any
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    ~Handle() { reset(); }

    const std::uint8_t* data() const noexcept { return data_; }
    std::size_t size() const noexcept { return size_; }
    std::span<const std::uint8_t> bytes() const noexcept { return {data_, size_}; }
    PageKey key() const noexcept { return key_; }
    bool empty() const noexcept { return entry_ == nullptr; }
    explicit operator bool() const noexcept { return entry_ != nullptr; }
    // Releases the pin now; no-op on an empty handle (inline: a MeshCursor
    // destroys 16 handles, mostly empty, per random query).
    void reset() noexcept {
      if (entry_ != nullptr) release();
    }

   private:
    friend class PageCache;
    void release() noexcept;
    Handle(PageCache* cache, Entry* entry, const std::uint8_t* data, std::size_t size, PageKey key) noexcept
        : cache_(cache), entry_(entry), data_(data), size_(size), key_(key) {}
    PageCache* cache_ = nullptr;
    Entry* entry_ = nullptr;  // the pinned slot; nullptr: empty
    const std::uint8_t* data_ = nullptr;
    std::size_t size_ = 0;
    PageKey key_{};
  };

  // Returns the page pinned. Hit: O(1), no allocation. Miss: calls the
  // loader (without the lock) or waits for the load already in flight.
  // Throws Error{Usage} for a page at or beyond the count given to
  // set_array_pages(), and when the budget cannot admit the page (see
  // invariant 1); rethrows what the loader threw (invariant 3).
  Handle pin(PageKey key);
  // pin(key) into h, releasing the pin h held first (as h = {} then h =
  // pin(key)), without the handle moves: a cursor moving to another page
  // does both (tables.hpp). h may hold another cache's pin (released
  // there). On a throw h is left empty.
  void pin_into(Handle& h, PageKey key);

  // Declares how many pages `array` has: pin() beyond is Error{Usage} and
  // read-ahead never goes there. Arrays never declared can be pinned
  // without a bound check but are never read ahead. Error{Usage} for an
  // array kept resident (its count is fixed from then on).
  void set_array_pages(std::uint32_t array, std::uint64_t pages);

  // Keeps the pages of declared array `array` resident from the moment
  // each is admitted (those resident now at once): the cache holds a pin
  // of its own on them that it never releases, so they are never evicted
  // and their bytes never move. Returns the array's page directory:
  // entry p (p < its page count) is nullptr until page p is admitted and
  // then its bytes, for as long as the cache lives; read it with an
  // acquire load. A reader that finds a page there needs no pin, and so
  // no atomic read-modify-write on a line that other threads' pins write
  // too (stores keep their small coarse tables this way: store.hpp).
  // Such reads are not counted in CacheStats::hits. A page admitted after
  // this call is copied, before anyone can see it, into 2 MiB-aligned
  // chunks that the kernel may back with transparent huge pages (a TLB
  // entry per 2 MiB of a table read at random); memory beyond the pages'
  // bytes: the last chunk's unused rest (under 2 MiB), and per chunk and
  // page a little rounding (under a page per chunk, 63 bytes per page).
  // Kept pages are pinned pages: they count toward the budget for good,
  // so keep only arrays well inside it; pin() fails as invariant 1 says
  // when they and the other pins leave no room. CacheStats::kept_bytes
  // says how much is held. Idempotent; Error{Usage} for an array never
  // declared. O(declared pages).
  const std::atomic<const std::uint8_t*>* keep_resident(std::uint32_t array);

  CacheStats stats() const;
  // Distinct pages of one declared array loaded since the last reset
  // (0 for an array never declared). O(its pages / 64).
  std::uint64_t distinct_pages_read(std::uint32_t array) const;
  // All counters to 0, except resident_bytes and kept_bytes (states, not
  // counters) and peak_resident_bytes (set to the current resident_bytes);
  // distinct pages count afresh.
  // Memory: 8 bytes and one bit per page of each declared array (its page
  // table and read bitmap).
  void reset_stats();
  std::uint64_t budget() const noexcept { return budget_; }
  // Resident pages with at least one handle on them now, not counting the
  // cache's own pin on kept pages (O(resident pages); diagnostics and tests).
  std::uint64_t pinned_pages() const;

 private:
  void unpin(Entry* entry) noexcept;
  Handle pin_locked(std::unique_lock<SpinMutex>& lock, PageKey key);  // pin() with the lock held
  std::uint64_t budget_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dicer

template <>
struct std::hash<dicer::PageKey> : dicer::PageKeyHash {};
