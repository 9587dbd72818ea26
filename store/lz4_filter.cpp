#include "lz4_filter.hpp"

#include <libdeflate.h>

#include <lz4.h>

#include <algorithm>
#include <bit>
#include <climits>
#include <cstring>
#include <mutex>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "dicer/error.hpp"

namespace dicer::store {
namespace {

constexpr std::size_t kHeaderBytes = 12;   // 8-byte original size + 4-byte block size
constexpr std::size_t kBlockHeader = 4;    // 4-byte stored size before each block
constexpr std::size_t kChecksumBytes = 4;  // Fletcher32 appended by the next filter
constexpr std::uint64_t kMaxPage = std::uint64_t{1} << 62;

std::uint64_t get_be64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}
std::uint32_t get_be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}
void put_be64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 7; i >= 0; --i, v >>= 8) p[i] = static_cast<std::uint8_t>(v);
}
void put_be32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 3; i >= 0; --i, v >>= 8) p[i] = static_cast<std::uint8_t>(v);
}
// HDF5's fletcher32 filter appends the checksum with UINT32ENCODE: least
// significant byte first (checked by the Hdf5Interop tests against H5Dwrite).
void put_checksum(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i, v >>= 8) p[i] = static_cast<std::uint8_t>(v);
}
std::uint32_t get_checksum(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
         (std::uint32_t{p[3]} << 24);
}

std::string hex32(std::uint32_t v) {
  static const char* digits = "0123456789abcdef";
  std::string s = "0x";
  for (int i = 28; i >= 0; i -= 4) s += digits[(v >> i) & 15];
  return s;
}

// ---- encoder ---------------------------------------------------------------

std::uint64_t effective_block(std::uint64_t n, std::uint32_t block_size) {
  return std::min<std::uint64_t>(block_size == 0 ? kLz4DefaultBlockSize : block_size, n);
}

// Capacity the encoder needs for n input bytes (LZ4 layout only, no checksum).
std::uint64_t encoded_bound(std::uint64_t n, std::uint32_t block_size) {
  const std::uint64_t blk = effective_block(n, block_size);
  if (n == 0) return kHeaderBytes;
  const std::uint64_t blocks = (n - 1) / blk + 1;
  // blk <= 2^32 - 1 and LZ4_MAX_INPUT_SIZE ~ 2^31: a block over it is stored raw.
  const std::uint64_t bound =
      blk <= LZ4_MAX_INPUT_SIZE ? static_cast<std::uint64_t>(LZ4_compressBound(static_cast<int>(blk))) : blk;
  return kHeaderBytes + blocks * (kBlockHeader + std::max(bound, blk));
}

// Writes the LZ4 layout of src[0, n) into dst (capacity encoded_bound(n, block_size));
// returns the bytes written. Cannot fail: a block LZ4 does not shrink is stored raw.
std::size_t lz4_encode(const std::uint8_t* src, std::size_t n, std::uint32_t block_size, std::uint8_t* dst) {
  const std::uint64_t blk = effective_block(n, block_size);
  put_be64(dst, n);
  put_be32(dst + 8, static_cast<std::uint32_t>(blk));
  std::size_t out = kHeaderBytes;
  for (std::size_t done = 0; done < n;) {
    const std::size_t len = static_cast<std::size_t>(std::min<std::uint64_t>(blk, n - done));
    std::uint8_t* body = dst + out + kBlockHeader;
    int c = 0;
    if (len <= LZ4_MAX_INPUT_SIZE) {
      const int cap = LZ4_compressBound(static_cast<int>(len));
      c = LZ4_compress_default(reinterpret_cast<const char*>(src + done), reinterpret_cast<char*>(body),
                               static_cast<int>(len), cap);
    }
    std::size_t stored = static_cast<std::size_t>(c);
    if (c <= 0 || stored >= len) {  // no gain: store raw, as the plugin does
      std::memcpy(body, src + done, len);
      stored = len;
    }
    put_be32(dst + out, static_cast<std::uint32_t>(stored));
    out += kBlockHeader + stored;
    done += len;
  }
  return out;
}

// ---- decoder ---------------------------------------------------------------

struct Layout {
  std::uint64_t orig = 0;   // original (decoded) size from the header
  std::uint64_t block = 0;  // block length, clamped to orig as the plugin does
};

// Reads the header and walks every block header without touching any output,
// so nothing is allocated before the layout is known to be self-consistent.
// Returns an empty string when p[0, n) is a well-formed layout, else what is wrong.
// Every loop iteration consumes >= 4 input bytes, so the walk is O(n).
std::string check_layout(const std::uint8_t* p, std::size_t n, Layout& l) {
  if (n < kHeaderBytes)
    return "LZ4 page truncated: " + std::to_string(n) + " bytes, the header alone needs " +
           std::to_string(kHeaderBytes);
  l.orig = get_be64(p);
  const std::uint32_t bs = get_be32(p + 8);
  if (l.orig > 0 && bs == 0) return "LZ4 header gives block size 0 for " + std::to_string(l.orig) + " bytes";
  l.block = std::min<std::uint64_t>(bs, l.orig);
  std::size_t pos = kHeaderBytes;
  std::uint64_t done = 0;
  for (std::uint64_t k = 0; done < l.orig; ++k) {
    const std::uint64_t len = std::min(l.block, l.orig - done);
    if (n - pos < kBlockHeader)
      return "LZ4 page truncated: block " + std::to_string(k) + " header at byte " + std::to_string(pos) +
             " is past the end (" + std::to_string(n) + " bytes); the header claims " + std::to_string(l.orig) +
             " bytes";
    const std::uint32_t c = get_be32(p + pos);
    pos += kBlockHeader;
    if (c > n - pos)
      return "LZ4 block " + std::to_string(k) + " claims " + std::to_string(c) + " stored bytes, only " +
             std::to_string(n - pos) + " remain";
    if (c != len) {
      // LZ4 cannot expand a byte into more than 255 bytes.
      if (c == 0 || len > 256 * std::uint64_t{c} + 64 || len > INT_MAX || c > INT_MAX)
        return "LZ4 block " + std::to_string(k) + " claims " + std::to_string(len) + " bytes from " +
               std::to_string(c) + " stored bytes";
    }
    pos += c;
    done += len;
  }
  if (pos != n) return std::to_string(n - pos) + " trailing bytes after the last LZ4 block";
  return {};
}

// Decodes a layout check_layout accepted into dst (exactly l.orig bytes).
std::string lz4_decode(const std::uint8_t* p, const Layout& l, std::uint8_t* dst) {
  std::size_t pos = kHeaderBytes;
  std::uint64_t done = 0;
  for (std::uint64_t k = 0; done < l.orig; ++k) {
    const std::uint64_t len = std::min(l.block, l.orig - done);
    const std::uint32_t c = get_be32(p + pos);
    pos += kBlockHeader;
    if (c == len) {
      std::memcpy(dst + done, p + pos, static_cast<std::size_t>(len));
    } else {
      const int r = LZ4_decompress_safe(reinterpret_cast<const char*>(p + pos), reinterpret_cast<char*>(dst + done),
                                        static_cast<int>(c), static_cast<int>(len));
      if (r < 0) return "LZ4 block " + std::to_string(k) + " is not valid LZ4 data";
      if (static_cast<std::uint64_t>(r) != len)
        return "LZ4 block " + std::to_string(k) + " decompresses to " + std::to_string(r) + " bytes, expected " +
               std::to_string(len);
    }
    pos += c;
    done += len;
  }
  return {};
}

// ---- the HDF5 filter callback ------------------------------------------------

// Returns the new data size, or 0 on failure (HDF5 then fails the I/O).
// Never throws: an exception must not cross the C library.
size_t lz4_filter(unsigned int flags, size_t cd_nelmts, const unsigned int cd_values[], size_t nbytes,
                  size_t* buf_size, void** buf) noexcept {
  try {
    const auto* in = static_cast<const std::uint8_t*>(*buf);
    void* out = nullptr;
    std::size_t out_size = 0;
    if (flags & H5Z_FLAG_REVERSE) {
      Layout l;
      if (!check_layout(in, nbytes, l).empty() || l.orig == 0 || l.orig > SIZE_MAX) return 0;
      out = H5allocate_memory(static_cast<std::size_t>(l.orig), false);
      if (!out) return 0;
      if (!lz4_decode(in, l, static_cast<std::uint8_t*>(out)).empty()) {
        H5free_memory(out);
        return 0;
      }
      out_size = static_cast<std::size_t>(l.orig);
      *buf_size = out_size;
    } else {
      if (nbytes == 0 || nbytes > kMaxPage) return 0;
      const std::uint32_t block = cd_nelmts > 0 && cd_values[0] > 0 ? cd_values[0] : kLz4DefaultBlockSize;
      const std::uint64_t cap = encoded_bound(nbytes, block);
      out = H5allocate_memory(static_cast<std::size_t>(cap), false);
      if (!out) return 0;
      out_size = lz4_encode(in, nbytes, block, static_cast<std::uint8_t*>(out));
      *buf_size = static_cast<std::size_t>(cap);
    }
    H5free_memory(*buf);
    *buf = out;
    return out_size;
  } catch (...) {
    return 0;
  }
}

const H5Z_class2_t kLz4Class = {
    H5Z_CLASS_T_VERS,
    static_cast<H5Z_filter_t>(kLz4FilterId),
    1,  // encoder present
    1,  // decoder present
    "HDF5 lz4 filter (dicer in-process, H5Zlz4 layout)",
    nullptr,  // can_apply
    nullptr,  // set_local
    lz4_filter,
};

}  // namespace

void register_lz4_filter() {
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  if (H5Zregister(&kLz4Class) < 0) throw Error(ErrorKind::Io, "HDF5: cannot register the LZ4 filter 32004");
}

void add_page_filters(hid_t dcpl) {
  register_lz4_filter();
  if (H5Pset_filter(dcpl, static_cast<H5Z_filter_t>(kLz4FilterId), H5Z_FLAG_MANDATORY, 0, nullptr) < 0)
    throw Error(ErrorKind::Io, "HDF5: cannot add the LZ4 filter 32004 to a dataset creation property list");
  if (H5Pset_fletcher32(dcpl) < 0)
    throw Error(ErrorKind::Io, "HDF5: cannot add the Fletcher32 filter to a dataset creation property list");
}

// HDF5 sums word by word (sum1 += w, sum2 += sum1) and folds both with
// end-around carry every 360 words: a chain of dependent adds, 2 bytes a
// cycle at best, which every page load paid over its stored bytes (13% of a
// cold random query, bench/README.md stop 41). The same sums a block at a
// time: lane j adds words j, j + 16, ... (acc) and, before each step, its
// running total into pacc, so that over a block of T steps of 16 words
//   sum1 += sum acc,  sum2 += 16 T sum1_before + 16 sum pacc + sum_j (16 - j) acc_j.
// 32-bit lanes hold T <= 256 steps (pacc <= 256^2 / 2 * 65535 < 2^32);
// the block's totals are then reduced mod 65535 in 64 bits.
// HDF5's folds keep each sum congruent mod 65535, never reach 0 from a
// nonzero value and end at most 0xffff, so its result is the residue in
// [1, 65535] (0xffff for a nonzero multiple), 0 only when every word is 0;
// tests/unit/test_lz4_filter.cpp checks the bits against HDF5's loop.
// Vector types, not a loop for the vectoriser: GCC lowers them to the
// baseline's SSE2 (this is no clone; 2-4x the scalar loop there).
std::uint32_t fletcher32(const std::uint8_t* data, std::size_t n) {
  typedef std::uint16_t U16x16 __attribute__((vector_size(32)));
  typedef std::uint32_t U32x16 __attribute__((vector_size(64)));
  constexpr std::size_t kWords = 16, kSteps = 256;
  std::uint64_t s1 = 0, s2 = 0;  // mod 65535
  bool nonzero = false;
  std::size_t words = n / 2;
  while (words >= kWords) {
    const std::size_t steps = std::min(words / kWords, kSteps);
    U32x16 acc = {}, pacc = {};
    for (std::size_t t = 0; t < steps; ++t, data += 2 * kWords) {
      U16x16 v;
      std::memcpy(&v, data, sizeof v);
      if constexpr (std::endian::native == std::endian::little) v = (v << 8) | (v >> 8);  // big-endian words
      pacc += acc;
      acc += __builtin_convertvector(v, U32x16);
    }
    std::uint64_t a = 0, p = 0, w = 0;
    for (std::size_t j = 0; j < kWords; ++j) a += acc[j], p += pacc[j], w += (kWords - j) * std::uint64_t{acc[j]};
    nonzero |= a != 0;
    s2 = (s2 + kWords * steps * s1 + kWords * p + w) % 65535;
    s1 = (s1 + a) % 65535;
    words -= steps * kWords;
  }
  auto word = [&](std::uint32_t v) {  // the last 15 words at most, one at a time (no overflow)
    nonzero |= v != 0;
    s1 += v, s2 += s1;
  };
  for (; words > 0; --words, data += 2) word((std::uint32_t{data[0]} << 8) | data[1]);
  if (n % 2) word(std::uint32_t{data[0]} << 8);
  if (!nonzero) return 0;
  const auto residue = [](std::uint64_t x) { return static_cast<std::uint32_t>(x % 65535 == 0 ? 65535 : x % 65535); };
  return (residue(s2) << 16) | residue(s1);
}

std::vector<std::uint8_t> encode_page(std::span<const std::uint8_t> raw) {
  if (raw.size() > kMaxPage)
    throw Error(ErrorKind::Usage, "encode_page: a page of " + std::to_string(raw.size()) + " bytes is too large");
  const std::uint64_t cap = encoded_bound(raw.size(), kLz4DefaultBlockSize);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(cap) + kChecksumBytes);
  const std::size_t n = lz4_encode(raw.data(), raw.size(), kLz4DefaultBlockSize, out.data());
  put_checksum(out.data() + n, fletcher32(out.data(), n));
  out.resize(n + kChecksumBytes);
  return out;
}

void decode_page_into(std::span<const std::uint8_t> stored, std::span<std::uint8_t> out, const std::string& what) {
  const auto fail = [&](const std::string& msg) { throw Error(ErrorKind::Corrupt, what + ": " + msg); };
  if (stored.size() < kChecksumBytes + kHeaderBytes)
    fail("page truncated: " + std::to_string(stored.size()) + " stored bytes, at least " +
         std::to_string(kChecksumBytes + kHeaderBytes) + " needed");
  const std::size_t n = stored.size() - kChecksumBytes;
  const std::uint32_t want = get_checksum(stored.data() + n), got = fletcher32(stored.data(), n);
  if (want != got) fail("page checksum mismatch (stored " + hex32(want) + ", computed " + hex32(got) + ")");
  if (get_be64(stored.data()) != out.size())
    fail("LZ4 header claims " + std::to_string(get_be64(stored.data())) + " bytes, the page holds " +
         std::to_string(out.size()));
  Layout l;
  if (std::string err = check_layout(stored.data(), n, l); !err.empty()) fail(err);
  if (std::string err = lz4_decode(stored.data(), l, out.data()); !err.empty()) fail(err);
}

void decode_page(std::span<const std::uint8_t> stored, std::vector<std::uint8_t>& out, std::size_t expected_size,
                 const std::string& what) {
  // A buffer of the page's size already is not zero-filled again (every
  // byte is written); a failure leaves it empty.
  try {
    out.resize(expected_size);  // the caller's size, never the header's
    decode_page_into(stored, out, what);
  } catch (...) {
    out.clear();
    throw;
  }
}

void shuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::vector<std::uint8_t>& out) {
  out.resize(in.size());
  const std::size_t count = elem ? in.size() / elem : 0;
  for (std::size_t i = 0; i < count; ++i)
    for (std::size_t j = 0; j < elem; ++j) out[j * count + i] = in[i * elem + j];
  std::copy(in.begin() + static_cast<std::ptrdiff_t>(count * elem), in.end(), out.begin() + static_cast<std::ptrdiff_t>(count * elem));
}

namespace {
#if defined(__SSE2__)
// Unshuffle of 8-byte elements, 16 at a time: the 8 x 16 byte transpose in
// three unpack stages (bytes, then pairs, then quads; the step blosc takes).
// SSE2 is part of x86-64, so no dispatch. Every page of the store's 8-byte
// integer tables passes through here on each load (about 4% of a sweep as
// a scalar loop). Returns the elements done.
std::size_t unshuffle8_sse2(const std::uint8_t* in, std::size_t count, std::uint8_t* out) {
  std::size_t i = 0;
  for (; i + 16 <= count; i += 16) {
    __m128i s[8], a[8], b[8];
    for (int j = 0; j < 8; ++j) s[j] = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + j * count + i));
    // a[2p + h]: byte planes 2p, 2p + 1 of elements 8h .. 8h + 7.
    for (int p = 0; p < 4; ++p)
      a[2 * p] = _mm_unpacklo_epi8(s[2 * p], s[2 * p + 1]), a[2 * p + 1] = _mm_unpackhi_epi8(s[2 * p], s[2 * p + 1]);
    // b[4h + 2c + g]: bytes 4c .. 4c + 3 of elements 8h + 4g .. 8h + 4g + 3.
    for (int h = 0; h < 2; ++h)
      for (int c = 0; c < 2; ++c) {
        b[4 * h + 2 * c] = _mm_unpacklo_epi16(a[4 * c + h], a[4 * c + 2 + h]);
        b[4 * h + 2 * c + 1] = _mm_unpackhi_epi16(a[4 * c + h], a[4 * c + 2 + h]);
      }
    // Elements 4q .. 4q + 3 (h = q / 2, g = q % 2): two at a time, low and high quads interleaved.
    for (int q = 0; q < 4; ++q) {
      const __m128i lo = b[4 * (q / 2) + q % 2], hi = b[4 * (q / 2) + 2 + q % 2];
      std::uint8_t* o = out + (i + 4 * q) * 8;
      _mm_storeu_si128(reinterpret_cast<__m128i*>(o), _mm_unpacklo_epi32(lo, hi));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(o + 16), _mm_unpackhi_epi32(lo, hi));
    }
  }
  return i;
}
#endif
}  // namespace

void unshuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::uint8_t* out) {
  const std::size_t count = elem ? in.size() / elem : 0;
  std::size_t done = 0;
#if defined(__SSE2__)
  if (elem == 8) done = unshuffle8_sse2(in.data(), count, out);
#endif
  for (std::size_t i = done; i < count; ++i)
    for (std::size_t j = 0; j < elem; ++j) out[i * elem + j] = in[j * count + i];
  std::copy(in.begin() + static_cast<std::ptrdiff_t>(count * elem), in.end(), out + count * elem);
}

void unshuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::vector<std::uint8_t>& out) {
  out.resize(in.size());
  unshuffle_bytes(in, elem, out.data());
}

std::uint32_t page_crc(std::span<const std::uint8_t> bytes) {
  // libdeflate's CRC-32 (zlib's and gzip's) folds with carry-less
  // multiplies: 3.4x zlib 1.2.13's tables on a 64 KiB page (bench_store
  // BM_PageDecode/2), and every page load computes one.
  return libdeflate_crc32(0, bytes.data(), bytes.size());
}

}  // namespace dicer::store
