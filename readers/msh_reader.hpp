#pragma once
// Private to the Gmsh MSH reader (readers/msh_*.cpp), in three steps:
//   msh_lexer.cpp     bytes -> tokens: ASCII and binary, every read checked
//                     against the end of the buffer, messages with a line
//                     (or byte offset) and the section;
//   msh_sections.cpp  tokens -> MshSections: one reader per section and
//                     version, Gmsh's element type table;
//   msh_assemble.cpp  MshSections -> CoarseMesh: blocks, side and node sets.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"

namespace dicer::msh {

inline constexpr Id kMaxId = std::numeric_limits<Id>::max();
inline constexpr Id kInt32Min = std::numeric_limits<std::int32_t>::min();
inline constexpr Id kInt32Max = std::numeric_limits<std::int32_t>::max();

// ---- Gmsh element types -----------------------------------------------------

enum class Shape : std::uint8_t { Point, Line, Triangle, Quadrilateral, Tetrahedron, Hexahedron, Prism, Pyramid };

struct ElementType {
  int type;
  int nodes;
  Shape shape;
};

// The fixed-size types of Gmsh's table; nullptr for any other number.
const ElementType* find_type(Id type);
// "hexahedron", "27-node hexahedron", "element of unknown type".
std::string type_name(int type);
// 0 points, 1 lines, 2 triangles and quadrangles, 3 solids; -1 unknown type.
int type_dim(Id type);

// The types dicer keeps: the first-order point, line, quadrangle and
// hexahedron, and the second-order line (8), quadrangles (16 QUAD8, 10
// QUAD9) and hexahedra (17 HEX20, 12 HEX27), whose nodes after the corners
// (kNodesOfDim) are mid nodes (orientation.hpp, NodeOrder::Gmsh).
inline constexpr int kPoint = 15, kLine = 1, kQuad = 3, kHex = 5;
inline constexpr int kNodesOfDim[4] = {1, 2, 4, 8};
inline constexpr int kMaxKeptNodes = 27;
// Dimension of a kept type, or -1 for every other type.
int kept_dim(Id type);

// ---- lexer --------------------------------------------------------------------

bool is_space(char c);
std::string_view trim(std::string_view s);
// A piece of the file fit for a one-line message: at most 40 characters,
// anything unprintable shown as '?'.
std::string shown(std::string_view s);

// A cursor over the whole file. Every read checks the bytes left; every
// count read from the file is checked against them before anything is
// reserved. Messages: "<path>: line L: $Section: what is wrong" ("byte
// offset N" inside binary data).
class Lexer {
 public:
  Lexer(const std::string& path, std::string data) : path_(path), data_(std::move(data)) {}

  const std::string& path() const { return path_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  bool at_end() const { return pos_ >= data_.size(); }

  // Messages name this section ("$Nodes"); empty between sections.
  void set_section(std::string s) { section_ = std::move(s); }
  const std::string& section() const { return section_; }
  // Binary data of the other byte order.
  void set_swap(bool swap) { swap_ = swap; }
  // Inside binary data messages give byte offsets, not lines.
  void set_binary(bool in_binary) { in_binary_ = in_binary; }

  [[noreturn]] void fail(const std::string& what, ErrorKind kind = ErrorKind::BadInput) const;
  // Truncation. With a detail (a count too large for the bytes left), the
  // location is the count; otherwise it is the end of the file.
  [[noreturn]] void eof(const std::string& detail = "");
  [[noreturn]] void too_many(const std::string& what, std::uint64_t n);

  // ASCII.
  void skip_space();
  std::string_view token();
  // The rest of the current line (without its end), moving past the '\n'.
  std::string_view rest_of_line();
  // Reads a whole line as a section header.
  std::string header_line();
  Id integer(const std::string& what, Id lo, Id hi = kMaxId);
  // A count of items of at least `tokens_each` tokens, checked against the
  // bytes left (each token needs a character and a separator).
  std::size_t count(const std::string& what, std::size_t tokens_each);
  double real(const std::string& what);
  void expect_end(const std::string& name) { expect_line("$End" + name); }
  // The next non-blank line must be exactly `line`.
  void expect_line(const std::string& line);
  // After an ASCII count in MSH2 binary sections: exactly one line end, then data.
  void start_binary_data();
  // Moves past the line "$End<name>", wherever it is; the section's content
  // is not read.
  void skip_to_end_line(const std::string& name);

  // Binary.
  template <class T>
  T bin();
  // A size_t count of items of `bytes_each` bytes, checked against the file.
  std::size_t bin_count(const std::string& what, std::size_t bytes_each);
  Id bin_tag(const std::string& what);
  std::int32_t bin_int(const std::string& what, Id lo = kInt32Min, Id hi = kInt32Max);
  void skip_bytes(std::uint64_t n);
  // Steps back over the last binary value read (byte-order probe).
  void unread(std::size_t bytes) { pos_ -= bytes; }

 private:
  std::size_t line_of(std::size_t at) const;
  std::string location() const;

  const std::string& path_;
  std::string data_;
  std::size_t pos_ = 0;
  std::size_t tok_ = 0;      // start of the last token read (messages)
  std::string section_;      // "$Nodes" while in it (messages)
  bool in_binary_ = false;
  bool swap_ = false;
};

template <class T>
T Lexer::bin() {
  if (remaining() < sizeof(T)) eof();
  tok_ = pos_;
  char bytes[sizeof(T)];
  std::memcpy(bytes, data_.data() + pos_, sizeof(T));
  if (swap_) std::reverse(bytes, bytes + sizeof(T));
  T v;
  std::memcpy(&v, bytes, sizeof(T));
  pos_ += sizeof(T);
  return v;
}

// ---- sections ----------------------------------------------------------------

// Elements of one kept type (points, lines, quads or hexes), in file order.
struct Group {
  std::vector<Id> tag;                   // element tag in the file
  std::vector<std::int8_t> entity_dim;   // elementary entity (MSH4: of its block)
  std::vector<std::int32_t> entity;
  std::vector<std::int32_t> physical;    // MSH2 only: first tag, 0 = none
  std::vector<Id> conn;                  // vertex indices, kNodesOfDim[dim] each
  // Quads and hexes: mid_slots entries per element (vertex indices, -1 none),
  // empty until the first second-order element arrives.
  std::vector<Id> mid;
  std::size_t size() const { return tag.size(); }
};

// What the sections of one file hold, before any mesh is built.
struct MshSections {
  bool msh4 = false;
  std::vector<double> x, y, z;
  std::vector<Id> node_tag;
  std::vector<std::int8_t> geo_dim;
  std::vector<std::int32_t> geo_tag;
  Group groups[4];                           // by dimension: points, lines, quads, hexes
  // Elements of the types dicer does not keep, counted by type and place:
  // (type, entity dimension, entity tag, MSH 1/2 physical tag or 0).
  std::map<std::tuple<Id, int, Id, Id>, std::size_t> others;
  std::size_t repeated = 0;                  // MSH2 elements written once per physical group
  bool periodic = false;                     // a $Periodic section (not applied)
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals;  // MSH4 (dim, tag)
  std::map<std::pair<int, Id>, std::string> physical_names;          // (dim, tag)
  std::vector<GeoEntity> entities;  // MSH4: curves, surfaces, volumes and what bounds them

  // Physical tags of element i of groups[dim] (nonzero only).
  std::span<const int> physicals(int dim, std::size_t i) const;
};

MshSections read_sections(Lexer& lex);

// ---- assembly ----------------------------------------------------------------

CoarseMesh assemble(const std::string& path, MshSections sections);

}  // namespace dicer::msh
