// check_classic_header (netcdf_checks.hpp): the netCDF classic header,
// parsed and checked against the file before netCDF parses it.
//
//   header    = magic numrecs dim_list gatt_list var_list
//   list      = ABSENT (ZERO ZERO) | tag nelems [item ...]
//   dim       = name dim_length                     (length 0: the record dimension)
//   attr      = name nc_type nelems [values, padded to 4 bytes]
//   var       = name nelems [dimid ...] vatt_list nc_type vsize begin
//   name      = nelems chars, padded to 4 bytes
// Big-endian. NON_NEG (nelems, lengths, dimids, vsize) is 4 bytes in CDF-1
// and CDF-2, 8 in CDF-5; begin is 4 bytes in CDF-1, 8 in CDF-2 and CDF-5.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "dicer/error.hpp"
#include "input_file.hpp"
#include "netcdf_checks.hpp"

namespace dicer {
namespace {

constexpr std::uint32_t kDimensionTag = 10, kVariableTag = 11, kAttributeTag = 12;
constexpr std::uint64_t kMaxName = 256;     // NC_MAX_NAME
constexpr std::uint64_t kMaxVarDims = 1024;  // NC_MAX_VAR_DIMS

std::uint64_t pad4(std::uint64_t n) { return n > std::numeric_limits<std::uint64_t>::max() - 3 ? n : (n + 3) / 4 * 4; }

// External size of a netCDF type (1..6 classic, 7..11 CDF-5 only); 0 if none.
std::uint64_t type_size(std::uint32_t type, int version) {
  static constexpr std::uint64_t kSize[12] = {0, 1, 1, 2, 4, 4, 8, 1, 2, 4, 8, 8};
  if (type < 1 || type > (version == 5 ? 11u : 6u)) return 0;
  return kSize[type];
}

struct Dim {
  std::string name;
  std::uint64_t length;
};
struct Var {
  std::string name;
  std::vector<std::uint64_t> dims;
  std::uint64_t type_size;
  std::uint64_t begin;
};

class HeaderReader {
 public:
  HeaderReader(const InputFile& file, const std::string& path)
      : file_(file), path_(path), size_(static_cast<std::uint64_t>(file.size())) {}

  void check() {
    const std::string magic = take(4, "the magic number");
    version_ = magic[3];
    if (magic.compare(0, 3, "CDF") != 0 || (version_ != 1 && version_ != 2 && version_ != 5))
      fail("the magic number is not CDF 1, 2 or 5");
    numrecs_ = version_ == 5 ? u64("the number of records") : u32("the number of records");
    const bool streaming = numrecs_ == (version_ == 5 ? ~std::uint64_t{0} : 0xFFFFFFFFu);
    if (streaming) numrecs_ = 0;
    else if (numrecs_ > max_non_neg()) fail("the number of records is " + std::to_string(numrecs_) + " (negative)");

    const std::uint64_t ndims = list(kDimensionTag, "dimension");
    for (std::uint64_t i = 0; i < ndims; ++i) {
      Dim d;
      d.name = name("dimension " + std::to_string(i));
      d.length = non_neg("the length of dimension '" + d.name + "'");
      if (d.length == 0) {
        if (record_dim_ >= 0)
          fail("two record (unlimited) dimensions, '" + dims_[static_cast<std::size_t>(record_dim_)].name + "' and '" +
               d.name + "'");
        record_dim_ = static_cast<std::int64_t>(dims_.size());
      }
      dims_.push_back(std::move(d));
    }
    attributes("global attribute");
    const std::uint64_t nvars = list(kVariableTag, "variable");
    for (std::uint64_t i = 0; i < nvars; ++i) vars_.push_back(variable(i));
    check_data(pos_);
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(ErrorKind::BadInput, path_ + ": not a readable Exodus II file (netCDF header: " + what + ")");
  }

  std::uint64_t max_non_neg() const {
    return version_ == 5 ? std::numeric_limits<std::int64_t>::max() : std::numeric_limits<std::int32_t>::max();
  }

  // The header must lie inside the file.
  void need(std::uint64_t n, const std::string& what) const {
    if (n > size_ || pos_ > size_ - n)
      fail("truncated: " + what + " needs bytes " + std::to_string(pos_) + ".." + std::to_string(add_sat(pos_, n)) +
           ", the file has " + std::to_string(size_));
  }
  // n bytes at the current position.
  const char* bytes(std::uint64_t n, const std::string& what) {
    need(n, what);
    if (pos_ < buf_at_ || pos_ + n > buf_at_ + buf_.size()) {
      buf_ = file_.read_at(static_cast<std::int64_t>(pos_), std::max<std::uint64_t>(n, 1 << 16));
      buf_at_ = pos_;
      if (buf_.size() < n) fail("truncated while reading " + what);
    }
    const char* p = buf_.data() + (pos_ - buf_at_);
    pos_ += n;
    return p;
  }
  std::string take(std::uint64_t n, const std::string& what) { return std::string(bytes(n, what), n); }
  void skip(std::uint64_t n, const std::string& what) {
    need(n, what);
    pos_ += n;
  }
  std::uint64_t be(std::uint64_t n, const std::string& what) {
    const unsigned char* p = reinterpret_cast<const unsigned char*>(bytes(n, what));
    std::uint64_t v = 0;
    for (std::uint64_t k = 0; k < n; ++k) v = v << 8 | p[k];
    return v;
  }
  std::uint32_t u32(const std::string& what) { return static_cast<std::uint32_t>(be(4, what)); }
  std::uint64_t u64(const std::string& what) { return be(8, what); }
  std::uint64_t non_neg(const std::string& what) {
    const std::uint64_t v = version_ == 5 ? u64(what) : u32(what);
    if (v > max_non_neg()) fail(what + " is " + std::to_string(v) + " (negative)");
    return v;
  }
  std::uint64_t remaining() const { return size_ - pos_; }

  std::string name(const std::string& what) {
    const std::uint64_t n = non_neg("the name length of " + what);
    if (n == 0 || n > kMaxName)
      fail("the name of " + what + " is " + std::to_string(n) + " characters long (1.." + std::to_string(kMaxName) + ")");
    std::string s = take(n, "the name of " + what);
    skip(pad4(n) - n, "the name of " + what);
    return s;
  }

  // A list's tag and count; ABSENT is a zero tag with a zero count.
  std::uint64_t list(std::uint32_t tag, const std::string& item) {
    const std::uint32_t t = u32("the " + item + " list tag");
    const std::uint64_t n = non_neg("the number of " + item + "s");
    if (t != tag && !(t == 0 && n == 0)) fail("bad " + item + " list tag " + std::to_string(t));
    if (n > remaining() / 8)  // every item takes more than 8 bytes
      fail("claims " + std::to_string(n) + " " + item + "s in the " + std::to_string(remaining()) + " bytes left");
    return n;
  }

  void attributes(const std::string& item) {
    const std::uint64_t n = list(kAttributeTag, item);
    for (std::uint64_t i = 0; i < n; ++i) {
      const std::string a = name(item + " " + std::to_string(i));
      const std::uint32_t type = u32("the type of " + item + " '" + a + "'");
      const std::uint64_t each = type_size(type, version_);
      if (each == 0) fail(item + " '" + a + "' has type " + std::to_string(type) + ", which is not a netCDF type");
      const std::uint64_t count = non_neg("the length of " + item + " '" + a + "'");
      const std::uint64_t bytes = mul_sat(count, each);
      if (bytes > remaining())
        fail(item + " '" + a + "' claims " + std::to_string(count) + " values (" + std::to_string(bytes) +
             " bytes) in the " + std::to_string(remaining()) + " bytes left");
      skip(pad4(bytes), item + " '" + a + "'");
    }
  }

  Var variable(std::uint64_t i) {
    Var v;
    v.name = name("variable " + std::to_string(i));
    const std::string what = "variable '" + v.name + "'";
    const std::uint64_t rank = non_neg("the rank of " + what);
    if (rank > kMaxVarDims) fail(what + " has " + std::to_string(rank) + " dimensions");
    for (std::uint64_t k = 0; k < rank; ++k) {
      const std::uint64_t id = non_neg("a dimension id of " + what);
      if (id >= dims_.size())
        fail(what + " uses dimension id " + std::to_string(id) + "; the file has " + std::to_string(dims_.size()));
      if (static_cast<std::int64_t>(id) == record_dim_ && k != 0)
        fail(what + " uses the record dimension '" + dims_[id].name + "' other than first");
      v.dims.push_back(id);
    }
    attributes("attribute of " + what);
    const std::uint32_t type = u32("the type of " + what);
    v.type_size = type_size(type, version_);
    if (v.type_size == 0) fail(what + " has type " + std::to_string(type) + ", which is not a netCDF type");
    non_neg("the size of " + what);  // netCDF recomputes it from the shape
    v.begin = version_ == 1 ? u32("the offset of " + what) : u64("the offset of " + what);
    if (v.begin > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()) ||
        (version_ == 1 && v.begin > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())))
      fail("the offset of " + what + " is negative");
    return v;
  }

  // Each variable's data after the header and inside the file; all of it
  // together no larger than the file (netCDF reads zeros past the end of a
  // truncated file, and would not say so).
  void check_data(std::uint64_t header_end) const {
    std::uint64_t fixed = 0, per_record = 0;
    std::size_t record_vars = 0;
    for (const Var& v : vars_) record_vars += !v.dims.empty() && static_cast<std::int64_t>(v.dims[0]) == record_dim_;
    for (const Var& v : vars_) {
      const bool record = !v.dims.empty() && static_cast<std::int64_t>(v.dims[0]) == record_dim_;
      std::uint64_t bytes = v.type_size;
      for (std::size_t k = record ? 1 : 0; k < v.dims.size(); ++k) bytes = mul_sat(bytes, dims_[v.dims[k]].length);
      const std::string what = "variable '" + v.name + "'";
      if (record && numrecs_ == 0) continue;  // no record written: no data
      if (v.begin < header_end && bytes > 0)
        fail(what + " starts at byte " + std::to_string(v.begin) + ", inside the header (" +
             std::to_string(header_end) + " bytes)");
      if (add_sat(v.begin, bytes) > size_)
        fail("truncated or lying: " + what + " needs " + std::to_string(bytes) + " bytes from byte " +
             std::to_string(v.begin) + ", the file has " + std::to_string(size_));
      if (record) per_record = add_sat(per_record, record_vars == 1 ? bytes : pad4(bytes));  // netCDF's one exception
      else fixed = add_sat(fixed, bytes);
    }
    const std::uint64_t total = add_sat(fixed, mul_sat(per_record, numrecs_));
    if (total > size_)
      fail("truncated: the header describes " + std::to_string(total) + " bytes of data, the file has " +
           std::to_string(size_));
  }

  const InputFile& file_;
  const std::string& path_;
  const std::uint64_t size_;
  std::uint64_t pos_ = 0;
  std::string buf_;            // file bytes from buf_at_
  std::uint64_t buf_at_ = 0;
  int version_ = 0;
  std::uint64_t numrecs_ = 0;
  std::int64_t record_dim_ = -1;
  std::vector<Dim> dims_;
  std::vector<Var> vars_;
};

}  // namespace

void check_classic_header(const InputFile& file, const std::string& path) { HeaderReader(file, path).check(); }

}  // namespace dicer
