#pragma once
// The store's page codec: HDF5 filter 32004 (LZ4, the HDF Group's H5Zlz4
// plugin layout) implemented in-process, followed by HDF5's built-in
// Fletcher32 checksum. Private to store/ (and its tests).
//
// On-disk layout of one page (one HDF5 chunk) after the pipeline
//   [LZ4 32004]  8-byte big-endian original size N
//                4-byte big-endian block size B (the writer's B clamped to N;
//                0 only when N == 0)
//                then ceil(N / B) blocks, each a 4-byte big-endian stored size
//                C followed by C bytes: raw bytes when C equals that block's
//                length (min(B, bytes left)), else one LZ4 block
//                (LZ4_compress_default / LZ4_decompress_safe)
//   [Fletcher32] 4 bytes: HDF5's Fletcher32 of everything before it, stored
//                little-endian (measured: HDF5 1.10.8 writes the uint32 with
//                UINT32ENCODE, least significant byte first)
//
// Block size: the writer uses cd_values[0] when the dataset gives one (> 0),
// else kLz4DefaultBlockSize (1 GiB, the plugin's DEFAULT_BLOCK_SIZE), so a
// 64 KiB page is always one block. Readers accept any block size and any
// multi-block layout the real plugin writes.
//
// Fletcher32 byte-reversed checksums: HDF5's own filter also accepts the
// pair-swapped checksum written by HDF5 1.6.0-1.6.2 (2004). decode_page does
// NOT: the LZ4 filter postdates those releases, so no genuine LZ4 page can
// carry one, and accepting it would only weaken corruption detection.
#include <hdf5.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace dicer::store {

inline constexpr int kLz4FilterId = 32004;
// The plugin's default block size (1 GiB; LZ4 blocks must stay < ~1.97 GiB).
inline constexpr std::uint32_t kLz4DefaultBlockSize = 1u << 30;

// Registers filter 32004 (encoder and decoder) with HDF5 in this process, so
// no HDF5_PLUGIN_PATH is needed; replaces a plugin HDF5 may have loaded for
// the same id. Idempotent and thread-safe (serialised by a mutex; re-registers
// on every call, so it also survives an H5close()). Cost: one HDF5 table
// lookup. Throws Error{Io} if HDF5 refuses the registration.
//
// The filter callback never throws and never crashes on a bad buffer: on any
// failure (truncated or lying header, bad LZ4 data, allocation failure) it
// returns 0 and HDF5 fails the read or write. Without a known chunk size, its
// decoder bounds the allocation by the stored size: each block may claim at
// most 256 * C + 64 bytes (LZ4's ratio is < 255:1).
void register_lz4_filter();

// Adds the page pipeline to a dataset creation property list: LZ4 (32004,
// mandatory, no cd_values, so the default block size) then HDF5's built-in
// Fletcher32 (H5Pset_fletcher32), in that order. Registers the filter first.
// Setting chunking is the caller's job (before or after this call).
// Throws Error{Io} if HDF5 rejects the property list.
void add_page_filters(hid_t dcpl);

// HDF5's Fletcher32 checksum exactly as H5Z's fletcher32 filter computes it
// (big-endian 16-bit words, an odd last byte taken as the high byte of a
// word, sums reduced with end-around carry), 16 words at a time in vector
// lanes. O(n), never throws.
std::uint32_t fletcher32(const std::uint8_t* data, std::size_t n);

// Encodes one page the way the pipeline stores it on disk (LZ4 layout above
// with the default block size, then the 4-byte little-endian Fletcher32), so
// H5Dwrite_chunk(filter mask 0) can write a page directly and H5Dread through
// the pipeline reads it. Byte-identical to what H5Dwrite stores for the same
// chunk bytes. Cost: one LZ4 compression, output <= LZ4_compressBound + 20
// bytes. Throws Error{Usage} only for a page over 2^62 bytes.
std::vector<std::uint8_t> encode_page(std::span<const std::uint8_t> raw);

// Decodes the raw bytes H5Dread_chunk returned for a page: checks the
// Fletcher32 checksum, then the LZ4 layout, and writes the original bytes into
// out (resized to expected_size, every byte written: a reused buffer of that
// size is not zero-filled first; emptied on failure).
// expected_size: the page's uncompressed size as the caller knows it from the
// dataset shape. `what` names the page in errors, e.g.
// "store.dice.h5: dataset /coarse/x page 17".
// Throws Error{Corrupt, what + ": ..."} on checksum mismatch, truncation,
// trailing bytes, or a size field that lies (original size != expected_size,
// block size 0, a stored block size past the end, a decompressed length
// mismatch). Never reads or writes out of bounds and never allocates more
// than expected_size, whatever the header says. Cost: O(stored + expected).
void decode_page(std::span<const std::uint8_t> stored, std::vector<std::uint8_t>& out, std::size_t expected_size,
                 const std::string& what);
// The same into out's out.size() bytes, which are the expected size; after
// a failure they hold anything (the store's loader: a cache page's bytes,
// dropped on failure).
void decode_page_into(std::span<const std::uint8_t> stored, std::span<std::uint8_t> out, const std::string& what);

// CRC-32 (zlib's) of a page's decoded bytes. Fletcher32 cannot see a 16-bit
// word turning from 0x0000 into 0xFFFF (ones'-complement sums); every paged
// dataset X therefore has a companion X + kPageCrcSuffix holding the CRC-32
// of each of its decoded pages, which the store's loader checks too.
std::uint32_t page_crc(std::span<const std::uint8_t> bytes);

// HDF5's byte shuffle (H5Z_FILTER_SHUFFLE) of a page of elements of `elem`
// bytes: byte j of element i goes to j * count + i, a tail of fewer than
// `elem` bytes stays in place. Used before LZ4 on every 8-byte integer
// table (ids and the bounding arrays' small zigzag-coded corrections leave
// their high byte planes all zero).
// Written here (30 lines) because H5Dwrite_chunk / H5Dread_chunk bypass
// HDF5's filters and the library exposes no shuffle call of its own.
void shuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::vector<std::uint8_t>& out);
void unshuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::vector<std::uint8_t>& out);
// The same into out[0 .. in.size()).
void unshuffle_bytes(std::span<const std::uint8_t> in, std::size_t elem, std::uint8_t* out);
inline constexpr const char* kPageCrcSuffix = "_crc";

}  // namespace dicer::store
