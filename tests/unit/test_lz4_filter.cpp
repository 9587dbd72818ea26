// The page codec on its own: LZ4 (HDF5 filter 32004 layout) + Fletcher32.
// Round trips, hand-built multi-block pages, and hostile pages: every flipped
// byte, every truncation and every lying size field must give Error{Corrupt}.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <lz4.h>

#include <cstring>
#include <random>
#include <thread>

#include "dicer/error.hpp"
#include "lz4_filter.hpp"
#include "test_support.hpp"

using namespace dicer;
using namespace dicer::store;
using Bytes = std::vector<std::uint8_t>;

namespace {

const std::string kWhat = "test.dice.h5: dataset /coarse/x page 17";

Bytes random_bytes(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Bytes b(n);
  for (auto& x : b) x = static_cast<std::uint8_t>(rng());
  return b;
}

// A page that compresses like real store data: slowly varying doubles.
Bytes smooth_doubles(std::size_t count) {
  std::vector<double> v(count);
  for (std::size_t i = 0; i < count; ++i) v[i] = 0.125 * static_cast<double>(i / 3) + (i % 3 == 0 ? 1.0 : 0.0);
  Bytes b(count * sizeof(double));
  std::memcpy(b.data(), v.data(), b.size());
  return b;
}

void put_be(Bytes& b, std::uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// Appends the Fletcher32 trailer (little-endian, as HDF5's filter stores it).
Bytes seal(Bytes b) {
  const std::uint32_t f = fletcher32(b.data(), b.size());
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(f >> (8 * i)));
  return b;
}

Bytes lz4_block(const std::uint8_t* src, int n) {
  Bytes out(static_cast<std::size_t>(LZ4_compressBound(n)));
  const int c = LZ4_compress_default(reinterpret_cast<const char*>(src), reinterpret_cast<char*>(out.data()), n,
                                     static_cast<int>(out.size()));
  out.resize(static_cast<std::size_t>(c));
  return out;
}

void expect_corrupt(std::span<const std::uint8_t> stored, std::size_t expected, const std::string& why) {
  Bytes out;
  try {
    decode_page(stored, out, expected, kWhat);
    ADD_FAILURE() << why << ": decode_page accepted the page";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Corrupt) << why << ": " << e.what();
    EXPECT_NE(std::string(e.what()).find(kWhat), std::string::npos) << why << ": " << e.what();
  }
  EXPECT_LE(out.capacity(), expected + 64) << why;
}

Bytes round_trip(const Bytes& raw) {
  const Bytes stored = encode_page(raw);
  Bytes out{1, 2, 3};
  decode_page(stored, out, raw.size(), kWhat);
  return out;
}

}  // namespace

TEST(Lz4Filter, RoundTripsEveryKindOfPage) {
  const Bytes pages[] = {random_bytes(65536, 1), Bytes(65536, 0), smooth_doubles(8192), random_bytes(12345, 2),
                         Bytes{}, Bytes{0x5a}, Bytes{1, 2}, random_bytes(17, 3)};
  for (const Bytes& raw : pages) EXPECT_EQ(round_trip(raw), raw) << raw.size();
}

TEST(Lz4Filter, LayoutMatchesThePlugin) {
  // Zero page: one LZ4 block, big-endian header fields.
  const Bytes zeros(65536, 0);
  const Bytes z = encode_page(zeros);
  ASSERT_GE(z.size(), 20u);
  Bytes header(z.begin(), z.begin() + 12);
  Bytes want;
  put_be(want, 65536, 8);
  put_be(want, 65536, 4);  // the 1 GiB default block size clamped to the page
  EXPECT_EQ(header, want);
  EXPECT_LT(z.size(), 400u);
  std::printf("[ info ] 64 KiB zero page -> %zu bytes; 64 KiB smooth doubles -> %zu bytes\n", z.size(),
              encode_page(smooth_doubles(8192)).size());

  // Incompressible page: stored raw, compressed size == block size.
  const Bytes noise = random_bytes(4096, 9);
  const Bytes n = encode_page(noise);
  ASSERT_EQ(n.size(), 12u + 4u + 4096u + 4u);
  EXPECT_EQ((n[12] << 24) | (n[13] << 16) | (n[14] << 8) | n[15], 4096);
  EXPECT_TRUE(std::equal(noise.begin(), noise.end(), n.begin() + 16));

  // Empty page: header only (original size 0, block size 0), then the checksum.
  EXPECT_EQ(encode_page({}).size(), 16u);
  // The trailer is HDF5's Fletcher32, least significant byte first.
  const std::uint32_t f = fletcher32(n.data(), n.size() - 4);
  EXPECT_EQ(n[n.size() - 4], f & 0xff);
  EXPECT_EQ(n[n.size() - 1], f >> 24);
}

TEST(Lz4Filter, Fletcher32MatchesModularDefinition) {
  // HDF5's Fletcher32: big-endian 16-bit words, an odd last byte is the high
  // byte of a word; both sums mod 65535 (0xffff and 0 are the same residue).
  std::mt19937_64 rng(7);
  for (std::size_t n : {0u, 1u, 2u, 3u, 719u, 720u, 721u, 722u, 5000u, 65537u}) {
    const Bytes b = n % 5 == 0 ? Bytes(n, 0xff) : random_bytes(n, rng());
    std::uint64_t s1 = 0, s2 = 0;
    for (std::size_t i = 0; i < n; i += 2) {
      const std::uint64_t w = (std::uint64_t{b[i]} << 8) | (i + 1 < n ? b[i + 1] : 0);
      s1 = (s1 + w) % 65535;
      s2 = (s2 + s1) % 65535;
    }
    const std::uint32_t f = fletcher32(b.data(), n);
    EXPECT_EQ((f & 0xffff) % 65535, s1) << n;
    EXPECT_EQ((f >> 16) % 65535, s2) << n;
  }
}

// HDF5's own loop (H5_checksum_fletcher32: word by word, both sums folded
// every 360 words and twice at the end), the bits fletcher32 must give:
// its block sums reach them another way (lz4_filter.cpp).
std::uint32_t hdf5_fletcher32(const std::uint8_t* data, std::size_t n) {
  std::uint32_t sum1 = 0, sum2 = 0;
  for (std::size_t words = n / 2; words > 0;) {
    std::size_t run = std::min<std::size_t>(words, 360);
    words -= run;
    for (; run > 0; --run, data += 2) sum1 += (std::uint32_t{data[0]} << 8) | data[1], sum2 += sum1;
    sum1 = (sum1 & 0xffff) + (sum1 >> 16), sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  if (n % 2) {
    sum1 += std::uint32_t{data[0]} << 8, sum2 += sum1;
    sum1 = (sum1 & 0xffff) + (sum1 >> 16), sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  sum1 = (sum1 & 0xffff) + (sum1 >> 16), sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  return (sum2 << 16) | sum1;
}

TEST(Lz4Filter, Fletcher32GivesHdf5sBits) {
  // Lengths around the 16-word steps and 4096-word blocks, odd and even;
  // bytes that make the sums exact multiples of 65535 (all 0xff: where 0
  // and 0xffff differ) or one off them, zeros, sparse and random.
  std::mt19937_64 rng(21);
  std::vector<std::size_t> sizes;
  for (std::size_t n = 0; n < 80; ++n) sizes.push_back(n);
  for (std::size_t n : {8191u, 8192u, 8193u, 8223u, 8224u, 8225u, 16384u, 65535u, 65536u, 65537u, 131072u, 1310720u})
    sizes.push_back(n);
  for (int k = 0; k < 200; ++k) sizes.push_back(rng() % 200000);
  int checked = 0;
  for (std::size_t n : sizes)
    for (int mode = 0; mode < 5; ++mode) {
      Bytes b(n);
      for (auto& x : b)
        x = mode == 0 || mode == 4 ? 0xff : mode == 1 ? 0 : mode == 2 ? (rng() % 97 == 0 ? 0xff : 0) : static_cast<std::uint8_t>(rng());
      if (mode == 4 && n > 2) b[n / 2] = 0xfe;  // one word off a multiple of 65535
      ASSERT_EQ(fletcher32(b.data(), n), hdf5_fletcher32(b.data(), n)) << n << " bytes, mode " << mode;
      ++checked;
    }
  EXPECT_EQ(checked, 5 * static_cast<int>(sizes.size()));
  // Known values: all-zero input gives 0; nonzero multiples of 65535 give 0xffff.
  EXPECT_EQ(fletcher32(Bytes(64, 0).data(), 64), 0u);
  EXPECT_EQ(fletcher32(Bytes(2, 0xff).data(), 2), 0xffffffffu);  // sum1 = sum2 = 0xffff
  const Bytes ab{0x01, 0x02, 0x03, 0x04};  // words 0x0102, 0x0304: sum1 0x0406, sum2 0x0102 + 0x0406
  EXPECT_EQ(fletcher32(ab.data(), 4), (0x0508u << 16) | 0x0406u);
}

TEST(Lz4Filter, DecodesHandBuiltMultiBlockPage) {
  // 10000 bytes in blocks of 3000: 3000 (LZ4) + 3000 (raw) + 3000 (LZ4) + 1000 (raw).
  Bytes raw = smooth_doubles(1250);
  const Bytes noise = random_bytes(10000, 4);
  std::copy(noise.begin() + 3000, noise.begin() + 6000, raw.begin() + 3000);
  std::copy(noise.begin() + 9000, noise.end(), raw.begin() + 9000);
  Bytes b;
  put_be(b, raw.size(), 8);
  put_be(b, 3000, 4);
  for (std::size_t at = 0; at < raw.size(); at += 3000) {
    const int len = static_cast<int>(std::min<std::size_t>(3000, raw.size() - at));
    const bool compress = (at / 3000) % 2 == 0;
    const Bytes block = compress ? lz4_block(raw.data() + at, len) : Bytes(raw.begin() + at, raw.begin() + at + len);
    ASSERT_TRUE(!compress || block.size() < static_cast<std::size_t>(len));
    put_be(b, block.size(), 4);
    b.insert(b.end(), block.begin(), block.end());
  }
  Bytes out;
  decode_page(seal(b), out, raw.size(), kWhat);
  EXPECT_EQ(out, raw);
  // A block size larger than the page is clamped to it (the plugin does the same).
  Bytes c;
  put_be(c, 100, 8);
  put_be(c, 1u << 30, 4);
  const Bytes small = random_bytes(100, 5);
  put_be(c, 100, 4);
  c.insert(c.end(), small.begin(), small.end());
  decode_page(seal(c), out, 100, kWhat);
  EXPECT_EQ(out, small);
}

// The store's loader decodes into one buffer per thread, page after page,
// without zero-filling it: each page must overwrite every byte it holds, and
// a failure must leave the buffer empty, not holding the page before.
TEST(Lz4Filter, AReusedBufferHoldsOnlyTheNewPage) {
  const Bytes a(65536, 0xab), b = random_bytes(65536, 11), c = smooth_doubles(8192);
  Bytes out;
  for (const Bytes* raw : {&a, &b, &c, &a}) {
    decode_page(encode_page(*raw), out, raw->size(), kWhat);
    EXPECT_EQ(out, *raw);
  }
  Bytes shorter = random_bytes(1000, 12);  // a smaller page into the big buffer: only its bytes
  decode_page(encode_page(shorter), out, shorter.size(), kWhat);
  EXPECT_EQ(out, shorter);
  Bytes bad = encode_page(b);
  bad[bad.size() / 2] ^= 0x5a;
  EXPECT_THROW(decode_page(bad, out, b.size(), kWhat), Error);
  EXPECT_TRUE(out.empty());
  EXPECT_THROW(decode_page(encode_page(b), out, b.size() + 1, kWhat), Error);  // the size field disagrees
  EXPECT_TRUE(out.empty());
}

TEST(Lz4Filter, EverySingleByteFlipIsCaught) {
  for (const Bytes& raw : {smooth_doubles(512), random_bytes(300, 6), Bytes{7}}) {
    const Bytes stored = encode_page(raw);
    std::size_t caught = 0, slack = 0;
    for (std::size_t i = 0; i < stored.size(); ++i) {
      for (std::uint8_t mask : {0x01, 0x80, 0xff, 0x5a}) {
        Bytes bad = stored;
        bad[i] ^= mask;
        Bytes out;
        try {
          decode_page(bad, out, raw.size(), kWhat);
          ASSERT_EQ(out, raw) << "flip of byte " << i << " gave different output";
          ++slack;
        } catch (const Error& e) {
          ASSERT_EQ(e.kind(), ErrorKind::Corrupt);
          ASSERT_NE(std::string(e.what()).find(kWhat), std::string::npos) << e.what();
          ++caught;
        }
      }
    }
    // Fletcher32 catches every single-byte change: no byte of a page is slack.
    EXPECT_EQ(slack, 0u);
    EXPECT_EQ(caught, stored.size() * 4);
  }
}

TEST(Lz4Filter, EveryTruncationIsCaught) {
  for (const Bytes& raw : {smooth_doubles(512), random_bytes(200, 8), Bytes{}}) {
    const Bytes stored = encode_page(raw);
    for (std::size_t len = 0; len < stored.size(); ++len)
      expect_corrupt(std::span(stored).first(len), raw.size(), "truncated to " + std::to_string(len));
    // One byte too many is a lie as well.
    Bytes longer = stored;
    longer.push_back(0);
    expect_corrupt(longer, raw.size(), "one extra byte");
  }
}

TEST(Lz4Filter, LyingSizeFieldsAreCaughtWithoutHugeAllocations) {
  const Bytes raw = random_bytes(4096, 10);
  const auto page = [&](std::uint64_t orig, std::uint64_t block, std::uint64_t stored_size, const Bytes& body) {
    Bytes b;
    put_be(b, orig, 8);
    put_be(b, block, 4);
    put_be(b, stored_size, 4);
    b.insert(b.end(), body.begin(), body.end());
    return seal(b);
  };
  // The checksum is valid in every case below: only the layout lies.
  expect_corrupt(page(std::uint64_t{1} << 60, 4096, 4096, raw), 4096, "original size 2^60");
  expect_corrupt(page(~std::uint64_t{0}, 0xffffffff, 4096, raw), 4096, "original size 2^64-1");
  expect_corrupt(page(4095, 4096, 4096, raw), 4096, "original size one short");
  expect_corrupt(page(4096, 0, 4096, raw), 4096, "block size 0");
  expect_corrupt(page(4096, 4096, 4097, raw), 4096, "stored size past the end");
  expect_corrupt(page(4096, 4096, 0xffffffff, raw), 4096, "stored size 2^32-1");
  expect_corrupt(page(4096, 4096, 0, raw), 4096, "stored size 0");
  expect_corrupt(page(4096, 4096, 4000, raw), 4096, "stored size short, raw bytes not LZ4");
  expect_corrupt(page(4096, 1, 4096, raw), 4096, "block size 1 needs 4096 block headers");
  // Many tiny blocks that each claim to inflate hugely: the ratio check stops them.
  {
    Bytes b;
    put_be(b, 1u << 30, 8);
    put_be(b, 1u << 20, 4);
    for (int k = 0; k < 1024; ++k) put_be(b, 1, 4), b.push_back(0);
    expect_corrupt(seal(b), 1u << 30, "1 GiB from 5 KiB");
  }
  // Valid LZ4 data that decompresses to fewer bytes than the block claims.
  const Bytes zeros(1000, 0);
  const Bytes c = lz4_block(zeros.data(), 1000);
  expect_corrupt(page(2000, 2000, c.size(), c), 2000, "LZ4 data decodes short");
  // ...and to more bytes than the block holds.
  const Bytes zeros2(3000, 0);
  const Bytes c2 = lz4_block(zeros2.data(), 3000);
  expect_corrupt(page(2000, 2000, c2.size(), c2), 2000, "LZ4 data decodes long");
  // Trailing bytes after a complete block.
  Bytes good = encode_page(zeros);
  good.resize(good.size() - 4);
  good.push_back(0);
  expect_corrupt(seal(good), 1000, "trailing byte");
  // A correct page decoded against the wrong expected size.
  expect_corrupt(encode_page(zeros), 999, "expected size differs");
  expect_corrupt(encode_page(zeros), 1001, "expected size differs");
  // Checksum mismatch message names the page and both checksums.
  Bytes bad = encode_page(zeros);
  bad[20] ^= 1;
  try {
    Bytes out;
    decode_page(bad, out, 1000, kWhat);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
}

TEST(Lz4Filter, RegistrationIsIdempotentAndThreadSafe) {
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i) threads.emplace_back([] {
    for (int k = 0; k < 10; ++k) register_lz4_filter();
  });
  for (auto& t : threads) t.join();
  EXPECT_GT(H5Zfilter_avail(kLz4FilterId), 0);
  unsigned int config = 0;
  ASSERT_GE(H5Zget_filter_info(kLz4FilterId, &config), 0);
  EXPECT_TRUE(config & H5Z_FILTER_CONFIG_ENCODE_ENABLED);
  EXPECT_TRUE(config & H5Z_FILTER_CONFIG_DECODE_ENABLED);
}
