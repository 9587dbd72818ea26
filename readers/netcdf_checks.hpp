#pragma once
// Checks of an Exodus (netCDF) file made before the netCDF and Exodus
// libraries read it: they trust it. Private to readers/.
//
// netCDF 4.9 sizes its allocations from header counts (an attribute claiming
// 2^31 values: gigabytes and tens of seconds) and crashes on some byte-mutated
// headers; the Exodus 6.02 getters size nothing themselves: they read whole
// variables and attributes into the caller's buffers (and their own, in
// ex_id_lkup), which the caller sized from the header's dimensions.
#include <cstdint>
#include <limits>
#include <string>

namespace dicer {

// Sizes computed from untrusted counts saturate instead of wrapping.
inline std::uint64_t mul_sat(std::uint64_t a, std::uint64_t b) {
  return (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a) ? std::numeric_limits<std::uint64_t>::max()
                                                                       : a * b;
}
inline std::uint64_t add_sat(std::uint64_t a, std::uint64_t b) {
  return b > std::numeric_limits<std::uint64_t>::max() - a ? std::numeric_limits<std::uint64_t>::max() : a + b;
}

class InputFile;

// netCDF classic (CDF-1), 64-bit offset (CDF-2) and 64-bit data (CDF-5)
// files: parses the header (layout: Unidata's "netCDF file format
// specifications") and requires every count, name and attribute to fit in
// the file, every dimension id to exist, at most one record dimension, and
// every variable's data to lie after the header and inside the file.
// Throws Error{BadInput} "<path>: not a readable Exodus II file (netCDF
// header: ...)" naming the dimension, attribute or variable. Not for
// netCDF-4 (HDF5) files, which netCDF hands to HDF5 as they are.
void check_classic_header(const InputFile& file, const std::string& path);

// The global attributes ex_open, ex_large_model and ex_inquire read into
// one value (version, word size, file_size, int64_status,
// maximum_name_length) must hold one. Call before ex_open. Throws
// Error{BadInput} "<path>: attribute '<name>': ...".
void audit_exodus_attributes(int ncid, const std::string& path);

// Every variable the reader's Exodus calls read whole must have exactly the
// shape of the dimensions its buffer is sized from: coordinates, id maps,
// block and set ids and status, connectivity, side and node set lists; and each block's elem_type must fit the library's 33-byte buffer.
// Call once the header's counts are known to fit the file (the loops run
// over blocks and sets). Throws Error{BadInput} "<path>: variable '<name>'
// (<what>): ...".
void audit_exodus_variables(int exoid, const std::string& path);

}  // namespace dicer
