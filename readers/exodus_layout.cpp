// audit_exodus_attributes and audit_exodus_variables (netcdf_checks.hpp):
// what the Exodus 6.02 calls read whole, checked against the buffers they
// read it into before any of them runs.
//
// Names (eb_names, ...) are not checked: the library reads them row by row
// with a bounded count, and netCDF refuses a row or count past the end.
// Variable names follow the Exodus II conventions (exodusII_int.h). Block and set
// variables are numbered by position in the id arrays (eb_prop1, ...),
// 1-based: block i's connectivity is connect<i>, sized num_el_in_blk<i> x
// num_nod_per_el<i>.
#include <exodusII.h>
#include <netcdf.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "dicer/error.hpp"
#include "netcdf_checks.hpp"

namespace dicer {
namespace {

class Layout {
 public:
  Layout(int ncid, const std::string& path) : ncid_(ncid), path_(path) {}

  // Length of a dimension; 0 when the file lacks it (so a variable that
  // would need it cannot be read into a buffer sized from it either).
  std::uint64_t dim(const std::string& name) const {
    int id = -1;
    std::size_t len = 0;
    if (nc_inq_dimid(ncid_, name.c_str(), &id) != NC_NOERR || nc_inq_dimlen(ncid_, id, &len) != NC_NOERR) return 0;
    return len;
  }

  // If `var` exists, its dimension lengths must be exactly `want`.
  void shape(const std::string& var, const std::vector<std::uint64_t>& want, const std::string& what) const {
    int id = -1;
    if (nc_inq_varid(ncid_, var.c_str(), &id) != NC_NOERR) return;
    int rank = 0;
    if (nc_inq_varndims(ncid_, id, &rank) != NC_NOERR || rank < 0 || rank > NC_MAX_VAR_DIMS)
      fail(var, what, "its rank cannot be read");
    std::vector<int> dims(static_cast<std::size_t>(rank));
    if (rank > 0 && nc_inq_vardimid(ncid_, id, dims.data()) != NC_NOERR) fail(var, what, "its shape cannot be read");
    std::vector<std::uint64_t> have;
    for (int d : dims) {
      std::size_t len = 0;
      if (nc_inq_dimlen(ncid_, d, &len) != NC_NOERR) fail(var, what, "its shape cannot be read");
      have.push_back(len);
    }
    if (have != want)
      fail(var, what, "has shape " + shown(have) + " but the dimensions the reader sizes it from give " + shown(want) +
                          " (the Exodus library would read past the buffer)");
  }

  // A numeric attribute the library reads into one variable must hold one value.
  void scalar_attribute(int varid, const char* name) const {
    std::size_t len = 0;
    if (nc_inq_attlen(ncid_, varid, name, &len) != NC_NOERR) return;
    if (len != 1)
      throw Error(ErrorKind::BadInput, path_ + ": attribute '" + name + "' has " + std::to_string(len) +
                                           " values; Exodus reads it into one");
  }

  // Block i's elem_type: the library copies it into a 33-byte buffer
  // (MAX_STR_LENGTH + 1) and then strcpy()s it, so it must fit with its end.
  void element_type(const std::string& var, const std::string& what) const {
    int id = -1;
    if (nc_inq_varid(ncid_, var.c_str(), &id) != NC_NOERR) return;
    std::size_t len = 0;
    nc_type type = NC_NAT;
    if (nc_inq_att(ncid_, id, "elem_type", &type, &len) != NC_NOERR) return;
    const std::size_t cap = MAX_STR_LENGTH + 1;
    if (len > cap)
      fail(var, what, "its elem_type attribute is " + std::to_string(len) + " characters long; Exodus allows " +
                          std::to_string(MAX_STR_LENGTH));
    if (type != NC_CHAR || len < cap) return;  // not text: the library refuses it itself
    char text[cap] = {};
    if (nc_get_att_text(ncid_, id, "elem_type", text) != NC_NOERR) return;
    if (text[cap - 1] != '\0')
      fail(var, what, "its elem_type attribute is " + std::to_string(cap) + " characters with no end; Exodus allows " +
                          std::to_string(MAX_STR_LENGTH));
  }

 private:
  static std::string shown(const std::vector<std::uint64_t>& lengths) {
    if (lengths.empty()) return "(scalar)";
    std::string s;
    for (std::uint64_t n : lengths) s += (s.empty() ? "" : " x ") + std::to_string(n);
    return s;
  }
  [[noreturn]] void fail(const std::string& var, const std::string& what, const std::string& problem) const {
    throw Error(ErrorKind::BadInput, path_ + ": variable '" + var + "' (" + what + "): " + problem);
  }

  int ncid_;
  const std::string& path_;
};

std::string numbered(const char* stem, std::uint64_t i) { return stem + std::to_string(i); }

}  // namespace

void audit_exodus_attributes(int ncid, const std::string& path) {
  const Layout f(ncid, path);
  // Read by ex_open, ex_large_model and ex_inquire.
  for (const char* att : {"version", "api_version", "api version", "floating_point_word_size",
                          "floating point word size", "file_size", "int64_status", "maximum_name_length"})
    f.scalar_attribute(NC_GLOBAL, att);
}

void audit_exodus_variables(int ncid, const std::string& path) {
  const Layout f(ncid, path);
  const std::uint64_t nodes = f.dim("num_nodes"), num_dim = f.dim("num_dim"), elems = f.dim("num_elem");
  for (const char* c : {"coordx", "coordy", "coordz"}) f.shape(c, {nodes}, "node coordinates");
  f.shape("coord", {num_dim, nodes}, "node coordinates");
  f.shape("node_num_map", {nodes}, "node id map");
  f.shape("elem_num_map", {elems}, "element id map");

  // Each block and set has dimensions of its own (num_el_in_blk<i>, ...):
  // counts beyond the file's dimensions are lies, and would only make the
  // loops below long.
  const std::uint64_t blocks = f.dim("num_el_blk"), side_sets = f.dim("num_side_sets"),
                      node_sets = f.dim("num_node_sets");
  int ndims = 0;
  nc_inq_ndims(ncid, &ndims);
  if (add_sat(add_sat(blocks, side_sets), node_sets) > static_cast<std::uint64_t>(std::max(ndims, 0)))
    throw Error(ErrorKind::BadInput, path + ": the header claims " + std::to_string(blocks) + " element blocks, " +
                                         std::to_string(side_sets) + " side sets and " + std::to_string(node_sets) +
                                         " node sets but defines only " + std::to_string(ndims) +
                                         " dimensions (each needs its own)");

  f.shape("eb_prop1", {blocks}, "element block ids");
  f.shape("eb_status", {blocks}, "element block status");
  for (std::uint64_t i = 1; i <= blocks; ++i) {
    const std::string what = "element block " + std::to_string(i) + " of " + std::to_string(blocks) + ", connectivity";
    const std::string conn = numbered("connect", i);
    f.shape(conn, {f.dim(numbered("num_el_in_blk", i)), f.dim(numbered("num_nod_per_el", i))}, what);
    f.element_type(conn, what);
  }

  f.shape("ss_prop1", {side_sets}, "side set ids");
  f.shape("ss_status", {side_sets}, "side set status");
  for (std::uint64_t i = 1; i <= side_sets; ++i) {
    const std::uint64_t n = f.dim(numbered("num_side_ss", i));
    const std::string what = "side set " + std::to_string(i) + " of " + std::to_string(side_sets);
    f.shape(numbered("elem_ss", i), {n}, what + ", elements");
    f.shape(numbered("side_ss", i), {n}, what + ", sides");
  }

  f.shape("ns_prop1", {node_sets}, "node set ids");
  f.shape("ns_status", {node_sets}, "node set status");
  for (std::uint64_t i = 1; i <= node_sets; ++i)
    f.shape(numbered("node_ns", i), {f.dim(numbered("num_nod_ns", i))},
            "node set " + std::to_string(i) + " of " + std::to_string(node_sets) + ", nodes");
}

}  // namespace dicer
