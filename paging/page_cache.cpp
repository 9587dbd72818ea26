// PageCache (include/dicer/cache.hpp): slots, CLOCK eviction, one-load-per-
// page waiting, sequential read-ahead.
//
// Why CLOCK. A hit must be cheap under the one mutex every reader shares.
// LRU would splice the page to the front of a list on every hit (pointer
// writes on shared cache lines, and a sharded LRU to make it scale); CLOCK
// sets one bit. Eviction walks a hand over a slot table: amortised O(1),
// O(slots) only when almost everything is pinned or referenced. LRU and
// CLOCK both flush a working set under a sweep larger than the budget, so
// scan resistance is done separately: a pin that continues a sequential
// stream (page p right after p-1) does not set the reference bit, so sweep
// pages are evicted on the first pass of the hand while the random-access
// working set keeps its second chance. (2Q/ARC would also resist scans but
// need ghost lists and allocation per miss; the sequential detector is
// needed for read-ahead anyway.)
//
// Victim order for a pin() (demand) admission:
//   1. CLOCK over slots that are resident, unpinned and not "prefetched"
//      (brought in by read-ahead and not pinned yet): referenced -> clear
//      the bit and move on; unreferenced -> evict. At most two turns.
//   2. Last resort: an unpinned prefetched page (it would have to be read
//      again, but that beats failing).
//   3. Nothing evictable: Error{Usage, "cache budget ... too small"}.
// Read-ahead admission evicts only unpinned, unreferenced, non-prefetched
// pages, and checks that enough of them exist before evicting any; otherwise
// the read-ahead is skipped (before the load when the array's largest page
// so far does not fit, or after it, discarding the page, if this page turned
// out larger). A read-ahead load that a pin() is waiting on is admitted as a
// demand load.
//
// Lazy eviction (STYLE.md #5): releasing a handle only decrements the pin
// count; a page leaves only when the hand reaches it with no pins. Slots
// live in a deque (stable addresses) so a Handle can point at its slot; a
// slot is reused only after it was evicted or its failed load was
// abandoned by every waiter.
//
// The hit path without the lock. A random query pins two or three pages
// (elements, corners, ...), and the lock, the bookkeeping under it and the
// second lock to release cost about a quarter of node(id) from a store. So
// a pin of a Ready page that neither starts nor continues a sequential
// stream, nor meets a prefetched page, takes no lock (fast_pin): it finds
// the slot in the array's page table (atomic pointers), raises the slot's
// pin count, and then checks that the slot still holds that page, Ready.
// Releasing a pin of a Ready page is one atomic decrement. What makes the
// unlocked increment safe is the kDetached bit of the pin count: a slot
// leaves the index (eviction, a failed load's end) only by a compare-and-
// swap of its count from 0 to kDetached, under the lock, so either the
// eviction wins (the fast pin sees the bit, takes its increment back and
// goes the locked way) or the pin wins (the swap fails and the hand moves
// on). A slot's key, data and state change only while it is detached or
// under the lock with pins that keep it from being detached, and the
// fast path reads them only after its increment: the pin it then holds
// keeps them as they were checked. Page tables replaced by
// set_array_pages() stay allocated until the cache goes, so an unlocked
// reader never follows a freed table.
//
// Kept arrays (keep_resident) go one step further: their pages never
// leave, so a reader needs no pin at all, only the page's address, which
// admit() publishes (release) in the array's directory after the cache's
// own pin is taken and the bytes are in place (in the kept arena, or in
// the page's buffer for pages resident before the array was kept). Even
// the unlocked pin's increment writes a line that every thread pinning
// that page shares; two threads querying one store ran 1.1-1.3x one
// thread with pins and 2x without (bench/README.md, stop 43).
#include "dicer/cache.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "dicer/error.hpp"

namespace dicer {

namespace {

enum class State : std::uint8_t { Free, Loading, Ready, Failed };
enum class Policy : std::uint8_t { Demand, ReadAhead };
constexpr std::uint64_t kReadAheadHeadroom = 4;

// Fixed-capacity FIFO of keys to read ahead: scheduling never allocates
// (it can happen on the hit path); when full, new requests are dropped.
template <class T>
class Ring {
 public:
  explicit Ring(std::size_t capacity) : items_(capacity) {}
  bool empty() const { return count_ == 0; }
  bool full() const { return count_ == items_.size(); }
  void push(const T& k) {
    items_[(head_ + count_) % items_.size()] = k;
    ++count_;
  }
  T pop() {
    T k = items_[head_];
    head_ = (head_ + 1) % items_.size();
    --count_;
    return k;
  }
  void clear() { head_ = count_ = 0; }

 private:
  std::vector<T> items_;
  std::size_t head_ = 0, count_ = 0;
};

// This thread's last pin of each of the last few arrays it pinned, by
// (cache, array), the least recent replaced: per thread, so that no other
// thread's pin in between hides a stream's start, and no unlocked hit
// writes a line that other threads read. Fully associative, so arrays
// read in turn (or one array id in two caches, as `dicer transfer` reads
// two stores) keep an entry each. Caches by a process-wide id (never 0),
// not by address: a new cache where a destroyed one was meets no entry.
class ThreadPins {
 public:
  struct Pin {
    std::uint64_t cache;
    std::uint32_t array;
    std::uint64_t page, used;
    // The stream this thread moved last in the array (the cache's Stream;
    // null: none) and its generation then: a replaced stream is no longer
    // this thread's.
    void* stream;
    std::uint64_t generation;
  };
  Pin* find(std::uint64_t cache, std::uint32_t array) {
    for (Pin& p : pins_)
      if (p.cache == cache && p.array == array) return &p;
    return nullptr;
  }
  // at: find()'s answer for (cache, array). Returns the entry.
  Pin* note(Pin* at, std::uint64_t cache, std::uint32_t array, std::uint64_t page) {
    if (at == nullptr) {
      at = &pins_[0];
      for (Pin& p : pins_)
        if (p.used < at->used) at = &p;
      *at = {cache, array, page, ++clock_, nullptr, 0};
      return at;
    }
    at->page = page, at->used = ++clock_;
    return at;
  }

 private:
  Pin pins_[16];  // a store's arrays, or two stores' (transfer) when nothing is kept
  std::uint64_t clock_;
};
thread_local ThreadPins thread_pins;  // zero-initialised: no entry matches a cache

// CacheStats' times: a clock read costs ~20 ns, a page load ~40 us.
std::uint64_t now_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count());
}
std::atomic<std::uint64_t> next_cache_id{1};

// Where kept pages live (keep_resident): 2 MiB-aligned chunks that the
// kernel may back with transparent huge pages (madvise; the system
// setting decides), bump-allocated and freed only with the cache. Kept
// pages are read at random and never leave: packed into huge pages, a
// table's pages take a TLB entry per 2 MiB instead of one per 4 KiB of
// the heap's 64 KiB buffers, and random queries on a store ran 0.87-0.92
// of the time (bench/README.md, stop 43). Not page bytes: up to 63 bytes
// of rounding per page, the tail of each chunk a page did not fit in
// (under a page), and the last chunk's unused rest (under 2 MiB).
class KeptArena {
 public:
  static constexpr std::size_t kChunk = std::size_t{2} << 20;
  KeptArena() = default;
  KeptArena(const KeptArena&) = delete;
  KeptArena& operator=(const KeptArena&) = delete;
  ~KeptArena() {
    for (void* c : chunks_) std::free(c);
  }
  // n bytes, 64-byte aligned; nullptr when no memory is to be had (the
  // page then stays in its own buffer).
  std::uint8_t* allocate(std::size_t n) {
    n = (n + 63) & ~std::size_t{63};
    if (n > left_) {
      const std::size_t size = (n + kChunk - 1) / kChunk * kChunk;
      if (chunks_.size() == chunks_.capacity()) {
        try {
          chunks_.reserve(2 * chunks_.size() + 4);
        } catch (const std::bad_alloc&) {
          return nullptr;
        }
      }
      void* c = std::aligned_alloc(kChunk, size);
      if (c == nullptr) return nullptr;
#ifdef MADV_HUGEPAGE
      ::madvise(c, size, MADV_HUGEPAGE);  // advice: failure leaves 4 KiB pages
#endif
      chunks_.push_back(c);
      next_ = static_cast<std::uint8_t*>(c), left_ = size;
    }
    std::uint8_t* at = next_;
    next_ += n, left_ -= n;
    return at;
  }

 private:
  std::vector<void*> chunks_;
  std::uint8_t* next_ = nullptr;
  std::size_t left_ = 0;
};

std::string key_text(PageKey k) {
  return "(array " + std::to_string(k.array) + ", page " + std::to_string(k.page) + ")";
}

}  // namespace

// A slot's pin word. Low 32 bits: the pin count, with kDetached set while
// the slot is out of the index (free, or being evicted or freed): an
// unlocked pin that meets it backs off. High 32 bits: the unlocked hits
// on the slot not yet folded into CacheStats::hits, a signed count (a pin
// that loses a race takes its hit back, maybe after a fold), so that an
// unlocked pin counts its hit in the same increment.
constexpr std::uint64_t kDetached = std::uint64_t{1} << 31;
constexpr std::uint64_t kPinMask = 0xffffffffu;
constexpr std::uint64_t kHit = std::uint64_t{1} << 32;
inline std::int64_t hits_of(std::uint64_t word) { return static_cast<std::int32_t>(word >> 32); }

// One cache line: an unlocked pin's increment, its hit count and the
// checks between them touch no other line.
struct alignas(64) PageCache::Entry {
  PageKey key{};                   // changes only while detached
  PageBytes data;                  // decoded bytes (empty when they lie in the kept arena); fixed while pinned and Ready
  std::exception_ptr error;        // State::Failed: what waiters rethrow
  // Handles + threads waiting for the load + the loading pin() itself, and
  // kDetached while out of the index (low half); unlocked hits (high
  // half). Unlocked pins (fast_pin) raise it for a moment before they
  // check the slot.
  std::atomic<std::uint64_t> pins{kDetached};
  std::atomic<State> state{State::Free};
  std::atomic<bool> referenced{false};  // CLOCK second-chance bit
  std::atomic<bool> prefetched{false};  // loaded by read-ahead and not pinned since
  bool kept = false;                    // holds the cache's own pin for good (keep_resident); under the lock
  // A kept page copied into the kept arena: its size (its bytes are its
  // array's directory entry); 0: the bytes are `data`. Set before Ready.
  std::uint32_t arena_bytes = 0;
  std::size_t size() const { return arena_bytes != 0 ? arena_bytes : data.size(); }
  // Pins other than the cache's own on a kept page.
  std::uint64_t handles() const { return count() - (kept ? 1 : 0); }
  std::uint64_t count() const { return pins.load(std::memory_order_relaxed) & kPinMask & ~kDetached; }
  // The unlocked hits counted so far, taken out of the word (with the lock).
  std::int64_t take_hits() {
    const std::uint64_t w = pins.load(std::memory_order_relaxed);
    pins.fetch_sub(w & ~kPinMask, std::memory_order_relaxed);
    return hits_of(w);
  }
};

// A mutex that spins a little before it sleeps. The cache's critical
// sections are a hash lookup long (~50 ns); with a plain std::mutex, two
// threads pinning pages at random (point location, id queries) put each
// other to sleep in the kernel, microseconds per wake-up, and two threads
// ran slower than one. glibc's adaptive mutex does the same but is not
// reachable through std::mutex.
class SpinMutex {
 public:
  void lock() {
    for (int i = 0; i < 128; ++i) {
      if (m_.try_lock()) return;
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    }
    m_.lock();
  }
  bool try_lock() { return m_.try_lock(); }
  void unlock() { m_.unlock(); }

 private:
  std::mutex m_;
};
using Lock = std::unique_lock<SpinMutex>;

struct PageCache::Impl {
  // The queue holds a window per stream: a sweep on many threads has
  // several streams in each of a few arrays.
  Impl(Loader l, Options o) : loader(std::move(l)), opt(o), queue(std::max<std::size_t>(256, 16 * std::size_t{o.read_ahead_pages})) {}

  Loader loader;
  Options opt;

  mutable SpinMutex mu;
  std::condition_variable_any load_done;  // some Loading entry left that state
  std::condition_variable_any work;       // worker: queue not empty or stop

  // An array's Loading and Ready entries by page: a pin finds its page
  // with one load, not a hash probe, and fast_pin without the lock.
  struct PageTable {
    explicit PageTable(std::uint64_t n) : size(n), slot(new std::atomic<Entry*>[n]) {
      for (std::uint64_t p = 0; p < n; ++p) slot[p].store(nullptr, std::memory_order_relaxed);
    }
    std::uint64_t size;
    std::unique_ptr<std::atomic<Entry*>[]> slot;
  };
  static constexpr std::uint64_t kNoPin = ~std::uint64_t{0};
  // A pin of `page` after one of `last` continues a sequential stream.
  static bool continues_stream(std::uint64_t last, std::uint64_t page) { return last != kNoPin && last + 1 == page; }
  // A sequential reader of one array. Each thread that sweeps a part of an
  // array is one: with a single last page per array, two threads' pins
  // interleaved and neither was ever seen as a stream (a 2-thread sweep of
  // the 1e9 box read 9,286 of its 10,922 pages as misses, no read-ahead).
  // A stream starts when a thread pins the page after its own last pin of
  // the array (ThreadPins). All fields are the locked path's.
  struct Stream {
    std::uint64_t last = kNoPin;  // the page it pinned last
    std::uint64_t ra_next = 0;    // the first page its window has not scheduled yet
    std::uint64_t used = 0;       // stream_clock when it last moved: the least recent is replaced
    std::uint64_t run = 0;        // its pins so far (extra_live_streams)
    std::uint64_t generation = 0; // replacements so far: a queued page names the stream it was read for
  };
  // Per array: a sweep's threads (`--threads` goes to 1024; beyond this
  // many, the least recently moved is replaced).
  static constexpr std::size_t kStreams = 256;
  struct ArrayInfo {
    std::uint64_t pages = 0;  // pages of the array (set_array_pages)
    std::atomic<bool> pinned{false};  // pinned at least once (counted in `streams`)
    // Grows to kStreams; a deque, so the Stream* that queued pages and
    // threads' pins hold stay valid.
    std::deque<Stream> stream;
    // The stream that read ahead of `page`'s window (its last page below
    // `page`, at most `window` pages before it), or nullptr.
    Stream* stream_before(std::uint64_t page, std::uint64_t window) {
      Stream* best = nullptr;
      for (Stream& s : stream)
        if (s.last != kNoPin && s.last < page && page - s.last <= window && (best == nullptr || s.last > best->last))
          best = &s;
      return best;
    }
    std::uint64_t max_page_bytes = 0;  // largest decoded page admitted so far (read-ahead's size estimate)
    std::vector<bool> read;            // pages loaded since the last reset_stats (1 bit each)
    // The declared pages' table (the map holds the rest); every table this
    // array had, the current one last, stays until the cache goes.
    std::atomic<PageTable*> table{nullptr};
    std::vector<std::unique_ptr<PageTable>> tables;
    // keep_resident(): each admitted page's bytes by page (nullptr: not
    // yet), `pages` entries; null while the array is not kept.
    std::unique_ptr<std::atomic<const std::uint8_t*>[]> kept;
  };

  std::unordered_map<PageKey, Entry*, PageKeyHash> map;  // Loading and Ready entries of undeclared pages
  std::deque<Entry> slots;                               // stable addresses; index order = clock order
  std::vector<Entry*> free_slots;
  std::size_t hand = 0;
  std::unordered_map<std::uint32_t, ArrayInfo> arrays;  // node-based: the pointers in `direct` stay valid
  // arrays[a] for the small ids stores use (a < kDirect), by index
  // (nullptr: never declared); read without the lock by fast_pin.
  static constexpr std::uint32_t kDirect = 4096;
  std::unique_ptr<std::atomic<ArrayInfo*>[]> direct{new std::atomic<ArrayInfo*>[kDirect]()};
  std::unordered_set<std::uint64_t> read_undeclared;  // the same for arrays without a page count (rare)
  // Counts a load: pages_read, and distinct_pages_read the first time this
  // page is loaded since the last reset (a bitmap per declared array).
  void count_load(PageKey key) {
    ++st.pages_read;
    ArrayInfo* ai = array_info(key.array);
    bool fresh;
    if (ai && key.page < ai->read.size()) {
      fresh = !ai->read[key.page];
      ai->read[key.page] = true;
    } else {
      fresh = read_undeclared.insert((std::uint64_t{key.array} << 40) ^ key.page).second;
    }
    st.distinct_pages_read += fresh;
  }
  std::uint64_t streams = 0;         // arrays pinned at least once: possible sequential streams
  std::uint64_t max_page_bytes = 0;  // largest decoded page admitted, any array
  // A page queued for read-ahead, and the stream it is read for (skipped
  // once that stream is past it or replaced).
  struct Queued {
    PageKey key;
    Stream* stream;
    std::uint64_t generation;
  };
  Ring<Queued> queue;
  std::uint64_t stream_clock = 0;         // Stream::used
  std::vector<ArrayInfo*> stream_arrays;  // the arrays with streams (extra_live_streams)
  std::uint64_t streams_in_use = 0;       // their streams, summed
  const std::uint64_t id = next_cache_id.fetch_add(1, std::memory_order_relaxed);  // ThreadPins' key
  // Streams beyond one per array that read ahead now: at least two pins,
  // the last among the last 4 x (streams in use) stream pins, min 16 (each
  // live stream of a sweep on many threads moves about once per that many
  // pins, so 4x leaves room for uneven threads; one that stopped, or a
  // random query's pins of p then p + 1, holds no window, and a stopped
  // sweep's streams stop counting after a few pins of the next).
  std::uint64_t extra_live_streams() const {
    const std::uint64_t ticks = std::max<std::uint64_t>(16, 4 * streams_in_use);
    std::uint64_t n = 0;
    for (const ArrayInfo* a : stream_arrays) {
      std::uint64_t live = 0;
      for (const Stream& s : a->stream) live += s.run >= 2 && stream_clock - s.used < ticks;
      n += live > 1 ? live - 1 : 0;
    }
    return n;
  }
  KeptArena arena;  // kept pages' bytes (admit)
  CacheStats st;
  bool stop = false;
  std::thread worker;

  ArrayInfo* array_info(std::uint32_t a) {
    if (a < kDirect) return direct[a].load(std::memory_order_relaxed);  // nullptr: never declared
    auto it = arrays.find(a);
    return it == arrays.end() ? nullptr : &it->second;
  }

  // The slot of page p in ai's table, nullptr if the table does not hold p.
  static std::atomic<Entry*>* table_slot(const ArrayInfo* ai, std::uint64_t p) {
    PageTable* t = ai ? ai->table.load(std::memory_order_relaxed) : nullptr;
    return t && p < t->size ? &t->slot[p] : nullptr;
  }
  // The Loading or Ready entry of key (nullptr: none); ai: its array's info.
  Entry* find(const ArrayInfo* ai, PageKey key) const {
    if (auto* slot = table_slot(ai, key.page)) return slot->load(std::memory_order_relaxed);
    auto it = map.find(key);
    return it == map.end() ? nullptr : it->second;
  }
  Entry* find(PageKey key) { return find(array_info(key.array), key); }
  void index(Entry* e) {
    if (auto* slot = table_slot(array_info(e->key.array), e->key.page)) slot->store(e, std::memory_order_release);
    else map.emplace(e->key, e);
  }
  void unindex(PageKey key) {
    if (auto* slot = table_slot(array_info(key.array), key.page)) slot->store(nullptr, std::memory_order_relaxed);
    else map.erase(key);
  }

  // A slot with no pins leaves the index's reach: false if a pin (an
  // unlocked one, a moment ago) holds it.
  static bool detach(Entry* e) {
    std::uint64_t w = e->pins.load(std::memory_order_relaxed);
    while ((w & kPinMask) == 0)  // no pins, not detached; the hit count may move under us
      if (e->pins.compare_exchange_weak(w, w | kDetached, std::memory_order_acq_rel)) return true;
    return false;
  }

  // The hit path without the lock (see the top of this file): e pinned, or
  // nullptr when the locked path must run (a miss, a load in flight, a
  // stream's pin, a prefetched page, a race lost).
  Entry* fast_pin(PageKey key) {
    if (key.array >= kDirect) return nullptr;
    ArrayInfo* ai = direct[key.array].load(std::memory_order_acquire);
    if (ai == nullptr) return nullptr;
    const PageTable* t = ai->table.load(std::memory_order_acquire);
    if (t == nullptr || key.page >= t->size) return nullptr;
    Entry* e = t->slot[key.page].load(std::memory_order_acquire);
    if (e == nullptr || e->state.load(std::memory_order_acquire) != State::Ready) return nullptr;
    // The stream bookkeeping is the locked path's: a first pin, and this
    // thread's pin of the page after its last. (A stream is one thread's,
    // and only that thread moves it. Random queries start spurious
    // streams, so a test of every stream here sent a quarter of random
    // hits to the lock.)
    ThreadPins::Pin* const tp = thread_pins.find(id, key.array);
    if (!ai->pinned.load(std::memory_order_relaxed) || (tp != nullptr && continues_stream(tp->page, key.page)))
      return nullptr;
    // One increment pins and counts the hit; a lost race takes both back.
    if (e->pins.fetch_add(1 + kHit, std::memory_order_acq_rel) & kDetached) {
      e->pins.fetch_sub(1 + kHit, std::memory_order_relaxed);
      return nullptr;
    }
    // Pinned: e stays where it is. Is it still key's page, Ready, not prefetched?
    if (e->state.load(std::memory_order_acquire) != State::Ready) {
      Lock lock(mu);
      e->pins.fetch_sub(kHit, std::memory_order_relaxed);
      release_pin(e);  // a load in flight or failed: the locked release
      return nullptr;
    }
    if (!(e->key == key) || e->prefetched.load(std::memory_order_relaxed)) {
      e->pins.fetch_sub(1 + kHit, std::memory_order_release);
      return nullptr;
    }
    thread_pins.note(tp, id, key.array, key.page);
    if (!e->referenced.load(std::memory_order_relaxed)) e->referenced.store(true, std::memory_order_relaxed);
    return e;
  }

  Entry* new_entry(PageKey key) {
    Entry* e;
    if (!free_slots.empty()) {
      e = free_slots.back();
      free_slots.pop_back();
    } else {
      e = &slots.emplace_back();
    }
    // Detached (free): nothing pins it but unlocked pins backing off.
    e->key = key;
    e->state.store(State::Loading, std::memory_order_relaxed);
    e->referenced.store(false, std::memory_order_relaxed);
    e->prefetched.store(false, std::memory_order_relaxed);
    e->kept = false;
    e->arena_bytes = 0;
    e->error = nullptr;
    e->pins.fetch_and(~kDetached, std::memory_order_release);  // the key above before any pin can see the slot
    index(e);
    return e;
  }

  // e is detached (detach() succeeded) and out of the index.
  void free_entry(Entry* e) {
    assert(e->pins.load() & kDetached);
    assert(!e->kept);
    PageBytes().swap(e->data);
    e->error = nullptr;
    e->state.store(State::Free, std::memory_order_relaxed);
    st.hits += static_cast<std::uint64_t>(e->take_hits());
    free_slots.push_back(e);
  }

  // A stream of ai whose last page is `page`: a new one, or the least
  // recently moved one replaced.
  Stream& start_stream(ArrayInfo& ai, std::uint64_t page) {
    Stream* s;
    if (ai.stream.size() < kStreams) {
      if (ai.stream.empty()) stream_arrays.reserve(stream_arrays.size() + 1);  // no throw after the stream is in
      s = &ai.stream.emplace_back();
      if (ai.stream.size() == 1) stream_arrays.push_back(&ai);
      ++streams_in_use;
    } else {
      s = &ai.stream[0];
      for (Stream& t : ai.stream)
        if (t.used < s->used) s = &t;
      ++s->generation;
    }
    s->last = page;
    s->ra_next = 0;
    s->run = 0;
    return *s;
  }

  // False: a pin came first (the hand moves on).
  bool evict(Entry* e) {
    assert(e->state == State::Ready);
    if (!detach(e)) return false;
    st.resident_bytes -= e->data.size();
    ++st.evictions;
    unindex(e->key);
    free_entry(e);
    return true;
  }

  // The load of e failed (or could not be admitted): waiters get err.
  void fail(Entry* e, std::exception_ptr err) {
    e->error = std::move(err);
    e->state.store(State::Failed, std::memory_order_release);
    unindex(e->key);
    load_done.notify_all();
    if (detach(e)) free_entry(e);
  }

  // With the lock: a pin that may hold a Failed or Loading slot.
  void release_pin(Entry* e) {
    assert(e->count() > 0);
    if ((e->pins.fetch_sub(1, std::memory_order_acq_rel) & kPinMask & ~kDetached) == 1 &&
        e->state.load(std::memory_order_relaxed) == State::Failed && detach(e))
      free_entry(e);
  }

  bool demand_evictable(const Entry& e) const { return e.state == State::Ready && e.count() == 0; }
  bool readahead_evictable(const Entry& e) const {
    return e.state == State::Ready && e.count() == 0 && !e.prefetched && !e.referenced;
  }

  Entry* advance() {
    Entry* e = &slots[hand];
    if (++hand == slots.size()) hand = 0;
    return e;
  }

  Entry* demand_victim() {
    const std::size_t n = slots.size();
    for (std::size_t step = 0; step < 2 * n; ++step) {
      Entry* e = advance();
      if (!demand_evictable(*e) || e->prefetched) continue;
      if (e->referenced.load(std::memory_order_relaxed)) {
        e->referenced.store(false, std::memory_order_relaxed);
        continue;
      }
      return e;
    }
    for (std::size_t step = 0; step < n; ++step) {
      Entry* e = advance();
      if (demand_evictable(*e)) return e;
    }
    return nullptr;
  }

  Entry* readahead_victim() {
    for (std::size_t step = 0, n = slots.size(); step < n; ++step) {
      Entry* e = advance();
      if (readahead_evictable(*e)) return e;
    }
    return nullptr;
  }

  // Can `bytes` be admitted by read-ahead's rules? O(slots) in the worst case.
  bool readahead_room(std::uint64_t bytes) const {
    if (bytes > opt.budget_bytes) return false;
    std::uint64_t room = opt.budget_bytes - st.resident_bytes;
    for (auto it = slots.begin(); room < bytes && it != slots.end(); ++it)
      if (readahead_evictable(*it)) room += it->data.size();
    return room >= bytes;
  }

  // Makes room for buf under `policy` and publishes it in e. False: nothing
  // was admitted (for read-ahead, nothing was evicted either).
  bool admit(Entry* e, PageBytes&& buf, Policy policy) {
    const std::uint64_t size = buf.size();
    if (size > opt.budget_bytes) return false;
    if (policy == Policy::ReadAhead && !readahead_room(size)) return false;
    // A victim an unlocked pin takes first is passed over; the bound keeps
    // a cache whose pages are pinned as fast as the hand finds them from
    // spinning (it fails like a full one).
    for (std::size_t lost = 0; st.resident_bytes + size > opt.budget_bytes;) {
      Entry* victim = policy == Policy::Demand ? demand_victim() : readahead_victim();
      if (victim == nullptr) return false;
      if (!evict(victim) && ++lost > 4 * slots.size()) return false;
    }
    ArrayInfo* ai = array_info(e->key.array);
    std::uint8_t* at = ai && ai->kept && size > 0 && size <= UINT32_MAX ? arena.allocate(size) : nullptr;
    if (at != nullptr) {
      // A kept page's bytes go to the arena, the page's buffer back to
      // the heap at once.
      std::memcpy(at, buf.data(), size);
      PageBytes().swap(buf);
      e->arena_bytes = static_cast<std::uint32_t>(size);
    } else {
      e->data = std::move(buf);
    }
    // Published before Ready: a handle on an arena page finds its bytes in
    // the directory. (No room in the arena: kept where it is.)
    if (ai && ai->kept) keep(*ai, e, at != nullptr ? at : e->data.data());
    e->state.store(State::Ready, std::memory_order_release);
    st.resident_bytes += size;
    if (st.resident_bytes > st.peak_resident_bytes) st.peak_resident_bytes = st.resident_bytes;
    if (ai && size > ai->max_page_bytes) ai->max_page_bytes = size;
    max_page_bytes = std::max(max_page_bytes, size);
    load_done.notify_all();
    return true;
  }

  // e's bytes, for a handle on it (e Ready and pinned). An arena page's
  // array is declared and kept: its info and directory never go.
  const std::uint8_t* bytes(const Entry* e) {
    return e->arena_bytes != 0 ? array_info(e->key.array)->kept[e->key.page].load(std::memory_order_acquire)
                               : e->data.data();
  }

  // e (of ai's array, its bytes at `at`, in place) takes the cache's own
  // pin and is published in ai's directory. The pin comes first: no
  // evict() can detach e after it, so the bytes a reader finds there stay.
  void keep(ArrayInfo& ai, Entry* e, const std::uint8_t* at) {
    if (e->kept) return;
    e->pins.fetch_add(1, std::memory_order_relaxed);
    e->kept = true;
    st.kept_bytes += e->size();
    ai.kept[e->key.page].store(at, std::memory_order_release);
  }

  std::exception_ptr budget_error(PageKey key, std::uint64_t size) const {
    std::string msg = "page cache: cache budget " + std::to_string(opt.budget_bytes) + " bytes too small: ";
    if (size > opt.budget_bytes) {
      msg += "page " + key_text(key) + " alone decodes to " + std::to_string(size) + " bytes";
    } else {
      std::uint64_t pinned = 0, pinned_bytes = 0;
      for (const Entry& s : slots)
        if (s.state == State::Ready && s.count() > 0) ++pinned, pinned_bytes += s.size();
      msg += std::to_string(pinned) + " pages pinned (" + std::to_string(pinned_bytes) + " of " +
             std::to_string(st.resident_bytes) + " resident bytes";
      if (st.kept_bytes > 0) msg += ", " + std::to_string(st.kept_bytes) + " of them kept resident";
      msg += ") and page " + key_text(key) + " needs " + std::to_string(size) +
             " more; release handles or raise the budget";
    }
    return std::make_exception_ptr(Error(ErrorKind::Usage, msg));
  }

  // pin() of page p continues stream s: queue the pages after p that s's
  // window has not scheduled yet.
  void schedule(ArrayInfo& ai, Stream& s, PageKey key) {
    const std::uint64_t r = opt.read_ahead_pages;
    if (r == 0 || key.page + 1 >= ai.pages) return;
    // A kept array's stream reads the pages read ahead without pins, so no
    // pin of one extends the window: its next miss does (pin_locked). A
    // window 4x as long makes that one miss per 4r + 1 pages; its pages
    // never leave and are the kept array's, which fits its share.
    const std::uint64_t window = ai.kept ? 4 * r : r;
    const std::uint64_t last = (ai.pages - 1 - key.page > window) ? key.page + window : ai.pages - 1;
    std::uint64_t first = key.page + 1;
    if (s.ra_next > first && s.ra_next <= last + 1) first = s.ra_next;
    // A window more than half ahead of the stream waits, and is then topped
    // up half a window at a time: each top-up wakes the worker once. (A
    // wake per page was ~4% of a one-thread sweep of the 1e9 box in perf:
    // the futex wake of the worker on the other core.) Kept arrays' windows
    // are extended by misses alone, already one per window.
    if (!ai.kept && first - key.page - 1 > window / 2) return;
    // Only when the budget holds every stream's window kReadAheadHeadroom
    // times over: below that, read-ahead pages evict pages the streams
    // still need and a sweep reads its pages many times (bench/README.md,
    // bench_cache: 189x at a 1% budget with ~10 streams, 5.4x without).
    // (Kept pages never leave: the rest of the budget is what streams share.)
    const std::uint64_t room = (opt.budget_bytes - st.kept_bytes) / kReadAheadHeadroom, one = r * max_page_bytes;
    if (room < one * streams || room < one * (streams + extra_live_streams())) return;  // the cheap test first
    bool pushed = false;
    for (std::uint64_t q = first; q <= last && !queue.full(); ++q) {
      const PageKey k{key.array, q};
      if (find(&ai, k) == nullptr) queue.push({k, &s, s.generation}), pushed = true;
    }
    s.ra_next = last + 1;
    if (pushed && worker.joinable()) work.notify_one();
  }

  // The loader, unlocked, its time (also when it throws) in `ns`.
  std::uint64_t timed_load(PageKey key, PageBytes& buf, std::uint64_t& ns) {
    struct Clock {
      std::uint64_t& ns;
      const std::uint64_t t0 = now_ns();
      ~Clock() { ns = now_ns() - t0; }
    } clock{ns};
    return loader(key, buf);
  }
  // With the lock: a load's time into CacheStats (demand: a miss's own).
  void count_load_time(std::uint64_t ns, bool demand) {
    st.load_ns += ns;
    if (demand) st.demand_load_ns += ns;
  }

  // Reads one queued page ahead. Called with `lock` held; drops it around
  // the loader call. Never throws (a failed read-ahead only informs waiters).
  void prefetch_one(Lock& lock, const Queued& q) noexcept {
    const PageKey key = q.key;
    try {
      ArrayInfo* ai = array_info(key.array);
      if (ai == nullptr || key.page >= ai->pages) return;
      // The stream it was read for is past it, or gone.
      if (q.stream->generation != q.generation || (q.stream->last != kNoPin && key.page <= q.stream->last)) return;
      if (find(ai, key) != nullptr) return;
      if (!readahead_room(ai->max_page_bytes)) return;  // cache full of pages not to evict: skip
      Entry* e = new_entry(key);
      e->prefetched.store(true, std::memory_order_relaxed);
      lock.unlock();
      PageBytes buf;
      std::uint64_t nread = 0;
      std::exception_ptr err;
      std::uint64_t ns = 0;
      try {
        nread = timed_load(key, buf, ns);
      } catch (...) {
        err = std::current_exception();
      }
      lock.lock();
      count_load_time(ns, false);
      if (err) return fail(e, err);
      count_load(key);
      st.bytes_read += nread;
      st.bytes_decompressed += buf.size();
      const std::uint64_t size = buf.size();
      // A pin() waiting on this load turns it into a demand load.
      const bool waited = e->count() > 0;
      if (!admit(e, std::move(buf), waited ? Policy::Demand : Policy::ReadAhead))
        fail(e, waited ? budget_error(key, size) : nullptr);
    } catch (...) {
      // Only bad_alloc can get here (bookkeeping); read-ahead is optional.
      if (!lock.owns_lock()) lock.lock();
    }
  }

  // Synchronous read-ahead (no worker): the pinning thread does the queue.
  void drain(Lock& lock) noexcept {
    while (!queue.empty()) prefetch_one(lock, queue.pop());
  }

  void worker_loop() {
    Lock lock(mu);
    for (;;) {
      work.wait(lock, [&] { return stop || !queue.empty(); });
      if (stop) return;
      prefetch_one(lock, queue.pop());
    }
  }
};

PageCache::PageCache(Loader loader, Options options) : budget_(options.budget_bytes) {
  static_assert(sizeof(Entry) == 64, "a slot is one cache line");
  if (!loader) throw Error(ErrorKind::Usage, "page cache: no loader given");
  if (options.budget_bytes == 0) throw Error(ErrorKind::Usage, "page cache: cache budget 0 bytes too small");
  impl_ = std::make_unique<Impl>(std::move(loader), options);
  impl_->map.reserve(1024);
  if (options.background_read_ahead && options.read_ahead_pages > 0)
    impl_->worker = std::thread([m = impl_.get()] { m->worker_loop(); });
}

PageCache::~PageCache() {
  {
    std::lock_guard<SpinMutex> lock(impl_->mu);
    impl_->stop = true;
    impl_->queue.clear();
  }
  impl_->work.notify_all();
  if (impl_->worker.joinable()) impl_->worker.join();
#ifndef NDEBUG
  for (const Entry& e : impl_->slots) assert(e.handles() == 0 && "a PageCache::Handle outlived its cache");
#endif
}

PageCache::Handle PageCache::pin(PageKey key) {
  if (Entry* e = impl_->fast_pin(key)) return Handle(this, e, impl_->bytes(e), e->size(), key);
  Lock lock(impl_->mu);
  return pin_locked(lock, key);
}

void PageCache::pin_into(Handle& h, PageKey key) {
  h.reset();  // the old pin first (unlocked: a handle's page is Ready)
  if (Entry* e = impl_->fast_pin(key)) {
    h = Handle(this, e, impl_->bytes(e), e->size(), key);
    return;
  }
  Lock lock(impl_->mu);
  h = pin_locked(lock, key);
}

PageCache::Handle PageCache::pin_locked(std::unique_lock<SpinMutex>& lock, PageKey key) {
  Impl& m = *impl_;
  Impl::ArrayInfo* ai = m.array_info(key.array);
  if (ai != nullptr && key.page >= ai->pages)
    throw Error(ErrorKind::Usage, "page cache: page " + key_text(key) + " is beyond the end of the array (" +
                                      std::to_string(ai->pages) + " pages)");
  Impl::Stream* stream = nullptr;  // the sequential stream this pin continues, if any
  if (ai != nullptr) {
    ThreadPins::Pin* const tp = thread_pins.find(m.id, key.array);
    if (tp != nullptr && Impl::continues_stream(tp->page, key.page)) {
      // Only this thread's pin of the page after its own last moves a
      // stream, and only its own: the one it moved last here goes on (also
      // after a look back: it is at this page), else one starts. (Any pin
      // after any stream's last moving it let random queries keep old
      // streams going, and read-ahead's headroom counted them.)
      auto* own = static_cast<Impl::Stream*>(tp->stream);
      if (own != nullptr && own->generation == tp->generation &&
          (Impl::continues_stream(own->last, key.page) || own->last == key.page))
        stream = own;
      else
        stream = &m.start_stream(*ai, key.page - 1);
    }
    // A stream over a kept array reads the pages read-ahead brought in
    // through the directory, without pins (tables.hpp): a kept page before
    // this one continues it too, or each window would end in misses.
    if (stream == nullptr && ai->kept && key.page > 0 &&
        ai->kept[key.page - 1].load(std::memory_order_relaxed) != nullptr) {
      stream = ai->stream_before(key.page, 4 * std::uint64_t{m.opt.read_ahead_pages} + 1);
      if (stream == nullptr) stream = &m.start_stream(*ai, key.page - 1);
    }
    if (!ai->pinned.load(std::memory_order_relaxed)) ++m.streams, ai->pinned.store(true, std::memory_order_relaxed);
    ThreadPins::Pin* const mine = thread_pins.note(tp, m.id, key.array, key.page);
    if (stream != nullptr) {
      stream->last = key.page, stream->used = ++m.stream_clock, ++stream->run;
      mine->stream = stream, mine->generation = stream->generation;
    }
  }
  const bool sequential = stream != nullptr;
  const bool sync_read_ahead = !m.worker.joinable();

  if (Entry* e = m.find(ai, key)) {  // hit, or the load is in flight
    ++m.st.hits;
    e->pins.fetch_add(1, std::memory_order_relaxed);  // indexed, so not detached
    if (!sequential) e->referenced.store(true, std::memory_order_relaxed);
    const bool extends_window = sequential && e->prefetched.load(std::memory_order_relaxed);
    e->prefetched.store(false, std::memory_order_relaxed);
    if (extends_window) m.schedule(*ai, *stream, key);
    if (e->state == State::Loading) {
      const std::uint64_t t0 = now_ns();
      m.load_done.wait(lock, [e] { return e->state != State::Loading; });
      m.st.load_wait_ns += now_ns() - t0;
      if (e->state == State::Failed) {
        std::exception_ptr err = e->error;
        m.release_pin(e);
        std::rethrow_exception(err);
      }
    }
    if (sync_read_ahead) m.drain(lock);
    return Handle(this, e, impl_->bytes(e), e->size(), key);
  }

  // Miss: this thread loads the page; others pinning it meanwhile wait.
  ++m.st.misses;
  Entry* e = m.new_entry(key);
  e->pins.fetch_add(1, std::memory_order_relaxed);
  e->referenced.store(!sequential, std::memory_order_relaxed);
  if (sequential) m.schedule(*ai, *stream, key);
  lock.unlock();
  PageBytes buf;
  std::uint64_t nread = 0;
  std::uint64_t ns = 0;
  try {
    nread = m.timed_load(key, buf, ns);
  } catch (...) {
    lock.lock();
    m.count_load_time(ns, true);
    m.fail(e, std::current_exception());
    m.release_pin(e);
    throw;
  }
  lock.lock();
  m.count_load_time(ns, true);
  m.count_load(key);
  m.st.bytes_read += nread;
  m.st.bytes_decompressed += buf.size();
  const std::uint64_t size = buf.size();
  if (!m.admit(e, std::move(buf), Policy::Demand)) {
    std::exception_ptr err = m.budget_error(key, size);
    m.fail(e, err);
    m.release_pin(e);
    std::rethrow_exception(err);
  }
  if (sync_read_ahead) m.drain(lock);
  return Handle(this, e, impl_->bytes(e), e->size(), key);
}

void PageCache::set_array_pages(std::uint32_t array, std::uint64_t pages) {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  Impl& m = *impl_;
  // Everything that allocates first: a bad_alloc leaves the cache as it was.
  std::vector<bool> read(static_cast<std::size_t>(pages), false);
  auto table = std::make_unique<Impl::PageTable>(pages);
  if (const Impl::ArrayInfo* kept = m.array_info(array); kept && kept->kept)
    throw Error(ErrorKind::Usage, "page cache: array " + std::to_string(array) +
                                      " is kept resident; its page count cannot change");
  const auto [it, fresh] = m.arrays.try_emplace(array);
  Impl::ArrayInfo& ai = it->second;
  std::vector<Entry*> mine;
  try {
    std::size_t held = 0;
    const Impl::PageTable* old = ai.table.load(std::memory_order_relaxed);
    for (std::uint64_t p = 0; old && p < old->size; ++p) held += old->slot[p].load(std::memory_order_relaxed) != nullptr;
    for (const auto& [key, e] : m.map) held += key.array == array;
    mine.reserve(held);
    m.map.reserve(m.map.size() + held);  // room for pages past a smaller count: no rehash below
    ai.tables.reserve(ai.tables.size() + 1);
  } catch (...) {
    if (fresh) m.arrays.erase(it);
    throw;
  }
  if (array < Impl::kDirect) m.direct[array].store(&ai, std::memory_order_release);
  if (const Impl::PageTable* old = ai.table.load(std::memory_order_relaxed))
    for (std::uint64_t p = 0; p < old->size; ++p)
      if (Entry* e = old->slot[p].load(std::memory_order_relaxed)) mine.push_back(e);
  for (const auto& [key, e] : m.map)
    if (key.array == array) mine.push_back(e);
  // Then the re-indexing. Only resident pages past a smaller new count
  // allocate (a map node each), which no store does: a store declares
  // each array once, before its first pin. The old table stays (an
  // unlocked pin may be reading it) but empty, so its readers lock.
  for (Entry* e : mine) m.unindex(e->key);
  ai.pages = pages;
  for (Impl::Stream& st : ai.stream) st.ra_next = 0;
  ai.read.swap(read);
  ai.tables.push_back(std::move(table));
  ai.table.store(ai.tables.back().get(), std::memory_order_release);
  for (Entry* e : mine) m.index(e);
}

const std::atomic<const std::uint8_t*>* PageCache::keep_resident(std::uint32_t array) {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  Impl& m = *impl_;
  Impl::ArrayInfo* ai = m.array_info(array);
  if (ai == nullptr)
    throw Error(ErrorKind::Usage, "page cache: keep_resident of array " + std::to_string(array) +
                                      ", whose page count was never declared");
  if (!ai->kept) {
    ai->kept.reset(new std::atomic<const std::uint8_t*>[ai->pages]);
    for (std::uint64_t p = 0; p < ai->pages; ++p) ai->kept[p].store(nullptr, std::memory_order_relaxed);
    // Pages resident now; those still loading are kept when admitted.
    if (const Impl::PageTable* t = ai->table.load(std::memory_order_relaxed))
      for (std::uint64_t p = 0; p < t->size; ++p)
        if (Entry* e = t->slot[p].load(std::memory_order_relaxed); e && e->state == State::Ready)
          m.keep(*ai, e, e->data.data());
  }
  return ai->kept.get();
}

CacheStats PageCache::stats() const {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  CacheStats s = impl_->st;
  for (const Entry& e : impl_->slots) s.hits += static_cast<std::uint64_t>(hits_of(e.pins.load(std::memory_order_relaxed)));
  return s;
}

std::uint64_t PageCache::distinct_pages_read(std::uint32_t array) const {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  const auto it = impl_->arrays.find(array);
  return it == impl_->arrays.end() ? 0 : static_cast<std::uint64_t>(std::count(it->second.read.begin(), it->second.read.end(), true));
}

void PageCache::reset_stats() {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  const std::uint64_t resident = impl_->st.resident_bytes, kept = impl_->st.kept_bytes;
  impl_->st = CacheStats{};
  impl_->st.resident_bytes = resident;
  impl_->st.kept_bytes = kept;
  for (Entry& e : impl_->slots) e.take_hits();
  for (auto& [a, ai] : impl_->arrays) std::fill(ai.read.begin(), ai.read.end(), false);
  impl_->read_undeclared.clear();
  impl_->st.peak_resident_bytes = resident;
}

std::uint64_t PageCache::pinned_pages() const {
  std::lock_guard<SpinMutex> lock(impl_->mu);
  std::uint64_t n = 0;
  for (const Entry& e : impl_->slots) n += (e.state == State::Ready && e.handles() > 0) ? 1 : 0;
  return n;
}

void PageCache::unpin(Entry* e) noexcept {
  // A handle's page is Ready and stays so while pinned (only a detached
  // slot changes state), so its release needs no lock; lazy: the page
  // stays until the clock hand needs its room.
  assert(e->state.load(std::memory_order_relaxed) == State::Ready);
  e->pins.fetch_sub(1, std::memory_order_release);
}

PageCache::Handle::Handle(Handle&& other) noexcept
    : cache_(std::exchange(other.cache_, nullptr)),
      entry_(std::exchange(other.entry_, nullptr)),
      data_(std::exchange(other.data_, nullptr)),
      size_(std::exchange(other.size_, 0)),
      key_(other.key_) {}

PageCache::Handle& PageCache::Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    reset();
    cache_ = std::exchange(other.cache_, nullptr);
    entry_ = std::exchange(other.entry_, nullptr);
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    key_ = other.key_;
  }
  return *this;
}

void PageCache::Handle::release() noexcept {
  cache_->unpin(std::exchange(entry_, nullptr));
  cache_ = nullptr;
  data_ = nullptr;
  size_ = 0;
}

}  // namespace dicer
