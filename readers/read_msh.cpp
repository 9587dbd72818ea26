// Gmsh MSH reader: versions 2.2 and 4.1, ASCII and binary.
//
// This is our own bounds-checked parser, not the Gmsh API: Gmsh 4.8 segfaults
// on some malformed or unusual MSH files and keeps global state; this parser
// gives a clear dicer::Error for every bad file and never crashes.
//
// The whole file is read into memory and parsed with a cursor that checks
// every read against the end of the buffer. Every count read from the file is
// checked against the bytes left before anything is reserved, so a hostile
// count fails with a message instead of a bad_alloc. Messages read
// "<path>: line L: $Section: what is wrong" ("byte offset N" inside binary data).
//
// Mapping to CoarseMesh (see coarse_mesh.hpp):
//  - mode: Volume if the file has hexahedra (type 5), else Surface if it has
//    quadrangles (type 3). Points (15) and lines (1) are classification and
//    set information; any other element type is refused (Unsupported).
//  - blocks: the element's physical group (MSH4: first physical tag of its
//    entity; MSH2: first element tag). If no element of the mesh dimension has
//    a physical group, blocks are the elementary entities (id = entity tag,
//    name "entity <tag>"). Otherwise elements without a physical group go to a
//    block per entity, numbered above the largest physical tag (warning).
//    Physical tag 0 means "none" in both versions.
//  - side sets: physical groups of dimension dim-1 (quads of a volume mesh,
//    lines of a surface mesh), matched to element sides through a sorted
//    key table; a boundary element on an interior face goes to the matching
//    element with the lowest index. Node sets: physical groups of dimension 0.
//  - vertex_geo_dim/tag: MSH4 from the $Nodes entity block; MSH2 from the
//    lowest-dimensional element containing the node.
// Geometry (handedness, duplicates, unused nodes) is left to
// validate_coarse_mesh.
#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"

namespace dicer {
namespace {

constexpr Id kMaxId = std::numeric_limits<Id>::max();
constexpr Id kInt32Min = std::numeric_limits<std::int32_t>::min();
constexpr Id kInt32Max = std::numeric_limits<std::int32_t>::max();

// ---------------------------------------------------------------------------
// Gmsh element types with a fixed number of nodes (from Gmsh's own table).

enum class Shape : std::uint8_t { Point, Line, Triangle, Quadrilateral, Tetrahedron, Hexahedron, Prism, Pyramid };

struct ElementType {
  int type;
  int nodes;
  Shape shape;
};

constexpr ElementType kElementTypes[] = {
    {1, 2, Shape::Line},          {2, 3, Shape::Triangle},       {3, 4, Shape::Quadrilateral},
    {4, 4, Shape::Tetrahedron},   {5, 8, Shape::Hexahedron},     {6, 6, Shape::Prism},
    {7, 5, Shape::Pyramid},       {8, 3, Shape::Line},           {9, 6, Shape::Triangle},
    {10, 9, Shape::Quadrilateral}, {11, 10, Shape::Tetrahedron}, {12, 27, Shape::Hexahedron},
    {13, 18, Shape::Prism},       {14, 14, Shape::Pyramid},      {15, 1, Shape::Point},
    {16, 8, Shape::Quadrilateral}, {17, 20, Shape::Hexahedron},  {18, 15, Shape::Prism},
    {19, 13, Shape::Pyramid},     {20, 9, Shape::Triangle},      {21, 10, Shape::Triangle},
    {22, 12, Shape::Triangle},    {23, 15, Shape::Triangle},     {24, 15, Shape::Triangle},
    {25, 21, Shape::Triangle},    {26, 4, Shape::Line},          {27, 5, Shape::Line},
    {28, 6, Shape::Line},         {29, 20, Shape::Tetrahedron},  {30, 35, Shape::Tetrahedron},
    {31, 56, Shape::Tetrahedron}, {32, 22, Shape::Tetrahedron},  {33, 28, Shape::Tetrahedron},
    {36, 16, Shape::Quadrilateral}, {37, 25, Shape::Quadrilateral}, {38, 36, Shape::Quadrilateral},
    {39, 12, Shape::Quadrilateral}, {40, 16, Shape::Quadrilateral}, {41, 20, Shape::Quadrilateral},
    {42, 28, Shape::Triangle},    {43, 36, Shape::Triangle},     {44, 45, Shape::Triangle},
    {45, 55, Shape::Triangle},    {46, 66, Shape::Triangle},     {47, 49, Shape::Quadrilateral},
    {48, 64, Shape::Quadrilateral}, {49, 81, Shape::Quadrilateral}, {50, 100, Shape::Quadrilateral},
    {51, 121, Shape::Quadrilateral}, {52, 18, Shape::Triangle},  {53, 21, Shape::Triangle},
    {54, 24, Shape::Triangle},    {55, 27, Shape::Triangle},     {56, 30, Shape::Triangle},
    {57, 24, Shape::Quadrilateral}, {58, 28, Shape::Quadrilateral}, {59, 32, Shape::Quadrilateral},
    {60, 36, Shape::Quadrilateral}, {61, 40, Shape::Quadrilateral}, {62, 7, Shape::Line},
    {63, 8, Shape::Line},         {64, 9, Shape::Line},          {65, 10, Shape::Line},
    {66, 11, Shape::Line},        {71, 84, Shape::Tetrahedron},  {72, 120, Shape::Tetrahedron},
    {73, 165, Shape::Tetrahedron}, {74, 220, Shape::Tetrahedron}, {75, 286, Shape::Tetrahedron},
    {79, 34, Shape::Tetrahedron}, {80, 40, Shape::Tetrahedron},  {81, 46, Shape::Tetrahedron},
    {82, 52, Shape::Tetrahedron}, {83, 58, Shape::Tetrahedron},  {84, 1, Shape::Line},
    {85, 1, Shape::Triangle},     {86, 1, Shape::Quadrilateral}, {87, 1, Shape::Tetrahedron},
    {88, 1, Shape::Hexahedron},   {89, 1, Shape::Prism},         {92, 64, Shape::Hexahedron},
    {93, 125, Shape::Hexahedron}, {94, 216, Shape::Hexahedron},  {95, 343, Shape::Hexahedron},
    {96, 512, Shape::Hexahedron}, {97, 729, Shape::Hexahedron},  {98, 1000, Shape::Hexahedron},
    {99, 32, Shape::Hexahedron},  {100, 44, Shape::Hexahedron},  {101, 56, Shape::Hexahedron},
    {102, 68, Shape::Hexahedron}, {103, 80, Shape::Hexahedron},  {104, 92, Shape::Hexahedron},
    {105, 104, Shape::Hexahedron}, {118, 30, Shape::Pyramid},    {119, 55, Shape::Pyramid},
    {120, 91, Shape::Pyramid},    {121, 140, Shape::Pyramid},    {122, 204, Shape::Pyramid},
    {123, 285, Shape::Pyramid},   {124, 385, Shape::Pyramid},    {125, 21, Shape::Pyramid},
    {126, 29, Shape::Pyramid},    {127, 37, Shape::Pyramid},     {128, 45, Shape::Pyramid},
    {129, 53, Shape::Pyramid},    {130, 61, Shape::Pyramid},     {131, 69, Shape::Pyramid},
    {132, 1, Shape::Pyramid},     {137, 16, Shape::Tetrahedron},
};

// The element types dicer keeps, indexed by their dimension.
constexpr int kPoint = 15, kLine = 1, kQuad = 3, kHex = 5;
constexpr int kNodesOfDim[4] = {1, 2, 4, 8};

const ElementType* find_type(Id type) {
  for (const ElementType& t : kElementTypes)
    if (t.type == type) return &t;
  return nullptr;
}

// Dimension of a kept type, or -1 for every other type.
int kept_dim(Id type) {
  switch (type) {
    case kPoint: return 0;
    case kLine: return 1;
    case kQuad: return 2;
    case kHex: return 3;
    default: return -1;
  }
}

std::string type_name(int type) {
  static const char* const kShapeNames[] = {"point",       "line",       "triangle", "quadrangle",
                                            "tetrahedron", "hexahedron", "prism",    "pyramid"};
  const ElementType* t = find_type(type);
  if (!t) return "element of unknown type";
  const char* shape = kShapeNames[static_cast<int>(t->shape)];
  if (type <= 7 || type == kPoint) return shape;  // the first-order types
  return std::to_string(t->nodes) + "-node " + shape;
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// A piece of the file fit for a one-line message: at most 40 characters,
// anything unprintable shown as '?'.
std::string shown(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > 40) out += "...";
  return out;
}

std::string read_whole_file(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error(ErrorKind::Io, path + ": cannot open: " + std::strerror(errno));
  std::string data;
  char buf[1 << 16];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) data.append(buf, n);
  const int err = errno;
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) throw Error(ErrorKind::Io, path + ": cannot read: " + std::strerror(err));
  return data;
}

// Elements of one kept type (points, lines, quads or hexes), in file order.
struct Group {
  std::vector<Id> tag;                   // element tag in the file
  std::vector<std::int8_t> entity_dim;   // elementary entity (MSH4: of its block)
  std::vector<std::int32_t> entity;
  std::vector<std::int32_t> physical;    // MSH2 only: first tag, 0 = none
  std::vector<Id> conn;                  // vertex indices, kNodesOfDim[dim] each
  std::size_t size() const { return tag.size(); }
};

class MshParser {
 public:
  MshParser(const std::string& path, std::string data) : path_(path), data_(std::move(data)) {}
  CoarseMesh parse();

 private:
  // --- messages ------------------------------------------------------------
  std::size_t line_of(std::size_t at) const {
    return 1 + static_cast<std::size_t>(std::count(data_.begin(), data_.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
  }
  std::string location() const {
    return in_binary_ ? "byte offset " + std::to_string(tok_) : "line " + std::to_string(line_of(tok_));
  }
  [[noreturn]] void fail(const std::string& what, ErrorKind kind = ErrorKind::BadInput) const {
    throw Error(kind, path_ + ": " + location() + ": " + (section_.empty() ? "" : section_ + ": ") + what);
  }
  // Truncation. With a detail (a count too large for the bytes left), the
  // location is the count; otherwise it is the end of the file.
  [[noreturn]] void eof(const std::string& detail = "") {
    if (detail.empty()) tok_ = data_.size();
    std::string s = path_ + ": " + location() + ": unexpected end of file";
    if (!section_.empty()) s += " in " + section_;
    if (!detail.empty()) s += ": " + detail;
    throw Error(ErrorKind::BadInput, s);
  }
  [[noreturn]] void too_many(const std::string& what, std::uint64_t n) {
    eof(what + " " + std::to_string(n) + " needs more than the " + std::to_string(remaining()) + " bytes left");
  }

  // --- ASCII ---------------------------------------------------------------
  std::size_t remaining() const { return data_.size() - pos_; }
  void skip_space() {
    while (pos_ < data_.size() && is_space(data_[pos_])) ++pos_;
  }
  std::string_view token() {
    skip_space();
    if (pos_ >= data_.size()) eof();
    tok_ = pos_;
    while (pos_ < data_.size() && !is_space(data_[pos_])) ++pos_;
    return std::string_view(data_).substr(tok_, pos_ - tok_);
  }
  // The rest of the current line (without its end), moving past the '\n'.
  std::string_view rest_of_line() {
    const std::size_t start = pos_;
    std::size_t end = data_.find('\n', pos_);
    if (end == std::string::npos) end = data_.size();
    pos_ = std::min(end + 1, data_.size());
    return std::string_view(data_).substr(start, end - start);
  }
  // Reads a whole line as a section header (tok_ at its start).
  std::string header_line() {
    skip_space();
    tok_ = pos_;
    return std::string(trim(rest_of_line()));
  }
  Id integer(const std::string& what, Id lo, Id hi = kMaxId) {
    std::string_view t = token();
    if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
    Id v = 0;
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size())
      fail("expected " + what + " (an integer), found '" + shown(t) + "'");
    if (v < lo || v > hi) fail(what + " " + std::to_string(v) + " is out of range");
    return v;
  }
  // A count of items of at least `tokens_each` tokens, checked against the
  // bytes left (each token needs a character and a separator).
  std::size_t count(const std::string& what, std::size_t tokens_each) {
    const Id n = integer(what, 0);
    if (static_cast<std::uint64_t>(n) > (remaining() + 1) / (2 * tokens_each)) too_many(what, static_cast<std::uint64_t>(n));
    return static_cast<std::size_t>(n);
  }
  double real(const std::string& what) {
    std::string_view t = token();
    if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
    double v = 0;
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    const bool out_of_range = ec == std::errc::result_out_of_range;
    if ((ec != std::errc() && !out_of_range) || end != t.data() + t.size())
      fail("expected " + what + " (a number), found '" + shown(t) + "'");
    if (out_of_range) {  // underflow (negative exponent) reads as 0, overflow as inf (refused later)
      const std::size_t e = t.find_first_of("eE");
      const bool underflow = e != std::string_view::npos && e + 1 < t.size() && t[e + 1] == '-';
      v = underflow ? 0.0 : std::numeric_limits<double>::infinity();
    }
    return v;
  }
  void expect_end(const std::string& name) {
    skip_space();
    if (pos_ >= data_.size()) eof();
    const std::string line = header_line();
    if (line != "$End" + name) fail("expected $End" + name + ", found '" + shown(line) + "'");
  }
  // After an ASCII count in MSH2 binary sections: exactly one line end, then data.
  void start_binary_data() {
    while (pos_ < data_.size() && (data_[pos_] == ' ' || data_[pos_] == '\r')) ++pos_;
    if (pos_ >= data_.size()) eof();
    if (data_[pos_] != '\n') {
      tok_ = pos_;
      fail("expected a line end before the binary data");
    }
    ++pos_;
    in_binary_ = true;
  }

  // --- binary --------------------------------------------------------------
  template <class T>
  T bin() {
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
  // A size_t count of items of `bytes_each` bytes, checked against the file.
  std::size_t bin_count(const std::string& what, std::size_t bytes_each) {
    const std::uint64_t n = bin<std::uint64_t>();
    if (n > remaining() / bytes_each) too_many(what, n);
    return static_cast<std::size_t>(n);
  }
  Id bin_tag(const std::string& what) {
    const std::uint64_t v = bin<std::uint64_t>();
    if (v == 0 || v > static_cast<std::uint64_t>(kMaxId)) fail(what + " " + std::to_string(v) + " is out of range");
    return static_cast<Id>(v);
  }
  std::int32_t bin_int(const std::string& what, Id lo = kInt32Min, Id hi = kInt32Max) {
    const std::int32_t v = bin<std::int32_t>();
    if (v < lo || v > hi) fail(what + " " + std::to_string(v) + " is out of range");
    return v;
  }
  void skip_bytes(std::uint64_t n) {
    if (n > remaining()) eof();
    pos_ += static_cast<std::size_t>(n);
  }

  // --- sections --------------------------------------------------------------
  void read_format();
  void read_physical_names();
  void read_entities();
  void read_nodes();
  void read_elements();
  void skip_section(const std::string& name);

  void add_node_tag(Id tag);
  void add_coords(Id tag, double x, double y, double z);
  void add_element(int dim, Id tag, int entity_dim, Id entity, Id physical, const Id* nodes);
  void count_unsupported(Id type, std::size_t n) { unsupported_[type] += n; }
  [[noreturn]] void fail_unknown_type(Id type);

  std::span<const int> physicals(int dim, std::size_t i) const;
  CoarseMesh build();

  const std::string& path_;
  std::string data_;
  std::size_t pos_ = 0;
  std::size_t tok_ = 0;        // start of the last token read (messages)
  std::string section_;        // "$Nodes" while in it (messages)
  bool in_binary_ = false;     // inside binary data (messages give byte offsets)
  bool binary_ = false;        // file-type 1
  bool swap_ = false;          // binary data of the other byte order
  bool msh4_ = false;
  bool saw_nodes_ = false, saw_elements_ = false;

  std::vector<double> x_, y_, z_;
  std::vector<Id> node_tag_;
  std::vector<std::int8_t> geo_dim_;
  std::vector<std::int32_t> geo_tag_;
  std::unordered_map<Id, Id> node_index_;  // file tag -> 0-based vertex
  std::unordered_map<Id, std::pair<int, std::size_t>> element_tags_;  // tag -> (dim, index in group)
  std::size_t repeated_ = 0;  // MSH2 elements written once per physical group
  Group groups_[4];                         // by dimension: points, lines, quads, hexes
  std::map<Id, std::size_t> unsupported_;   // element type -> count
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals_;  // MSH4 (dim, tag)
  std::map<std::pair<int, Id>, std::string> physical_names_;          // (dim, tag)
};

// ---------------------------------------------------------------------------

void MshParser::read_format() {
  skip_space();
  if (pos_ >= data_.size()) throw Error(ErrorKind::BadInput, path_ + ": the file is empty");
  const std::string first = header_line();
  if (first == "$NOD" || first == "$NOE")
    fail("MSH version 1.0 is not supported; dicer reads MSH 2.2 and 4.1 (re-save the mesh with Gmsh)",
         ErrorKind::Unsupported);
  if (first != "$MeshFormat")
    fail("not a Gmsh MSH file: expected $MeshFormat on the first line, found '" + shown(first) + "'");
  section_ = "$MeshFormat";
  const std::string version(token());
  binary_ = integer("file-type", 0, 1) == 1;
  const Id data_size = integer("data-size", 0);
  double v = 0;
  auto [end, ec] = std::from_chars(version.data(), version.data() + version.size(), v);
  if (ec != std::errc() || end != version.data() + version.size())
    fail("expected a version number, found '" + shown(version) + "'");
  if (v >= 2.0 && v < 3.0) {
    msh4_ = false;
  } else if (std::abs(v - 4.1) < 1e-9) {
    msh4_ = true;
  } else {
    fail("MSH version " + shown(version) + " is not supported; dicer reads MSH 2.2 and 4.1 (re-save the mesh with Gmsh)",
         ErrorKind::Unsupported);
  }
  if (binary_ && data_size != 8)
    fail("binary data-size " + std::to_string(data_size) + " is not supported; only 8-byte doubles are");
  if (!trim(rest_of_line()).empty()) fail("unexpected text after the data-size");
  if (binary_) {
    in_binary_ = true;
    const std::int32_t one = bin<std::int32_t>();
    if (one != 1) {
      swap_ = true;
      pos_ -= 4;
      if (bin<std::int32_t>() != 1) fail("expected the binary integer 1 that tells the byte order");
    }
    in_binary_ = false;
  }
  expect_end("MeshFormat");
}

void MshParser::read_physical_names() {
  const std::size_t n = count("number of physical names", 3);
  for (std::size_t i = 0; i < n; ++i) {
    const int dim = static_cast<int>(integer("physical dimension", 0, 3));
    const Id tag = integer("physical tag", kInt32Min, kInt32Max);
    std::string_view name = trim(rest_of_line());
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"') name = name.substr(1, name.size() - 2);
    physical_names_.emplace(std::make_pair(dim, tag), std::string(name));
  }
  expect_end("PhysicalNames");
}

// MSH 4.1: the physical tags of every entity (bounding boxes and boundaries
// are skipped).
void MshParser::read_entities() {
  std::size_t n[4];
  if (binary_) {
    in_binary_ = true;
    for (int d = 0; d < 4; ++d) n[d] = bin_count("number of entities", d == 0 ? 36 : 68);
  } else {
    for (int d = 0; d < 4; ++d) n[d] = count("number of entities", d == 0 ? 5 : 9);
  }
  for (int d = 0; d < 4; ++d) {
    for (std::size_t i = 0; i < n[d]; ++i) {
      std::vector<int> phys;
      int tag;
      if (binary_) {
        tag = bin_int("entity tag");
        skip_bytes(d == 0 ? 24 : 48);
        const std::size_t np = bin_count("number of physical tags", 4);
        for (std::size_t k = 0; k < np; ++k) phys.push_back(bin_int("physical tag"));
        if (d > 0) skip_bytes(4 * bin_count("number of bounding entities", 4));
      } else {
        tag = static_cast<int>(integer("entity tag", kInt32Min, kInt32Max));
        for (int k = 0; k < (d == 0 ? 3 : 6); ++k) token();
        const std::size_t np = count("number of physical tags", 1);
        for (std::size_t k = 0; k < np; ++k) phys.push_back(static_cast<int>(integer("physical tag", kInt32Min, kInt32Max)));
        if (d > 0) {
          const std::size_t nb = count("number of bounding entities", 1);
          for (std::size_t k = 0; k < nb; ++k) token();
        }
      }
      std::erase(phys, 0);
      entity_physicals_[{d, tag}] = std::move(phys);
    }
  }
  expect_end("Entities");
}

void MshParser::add_node_tag(Id tag) {
  const Id index = static_cast<Id>(node_tag_.size());
  if (!node_index_.emplace(tag, index).second) fail("node tag " + std::to_string(tag) + " appears twice");
  node_tag_.push_back(tag);
}

void MshParser::add_coords(Id tag, double x, double y, double z) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
    fail("node tag " + std::to_string(tag) + " has a coordinate that is not a finite number");
  x_.push_back(x);
  y_.push_back(y);
  z_.push_back(z);
}

void MshParser::read_nodes() {
  saw_nodes_ = true;
  if (!msh4_) {
    // MSH2: count, then "tag x y z" per node.
    const std::size_t n = count("number of nodes", 4);
    if (binary_) {
      start_binary_data();
      if (n > remaining() / 28) too_many("number of nodes", n);
    }
    node_index_.reserve(node_index_.size() + n);
    for (std::size_t i = 0; i < n; ++i) {
      Id tag;
      double c[3];
      if (binary_) {
        tag = bin_int("node tag", 1);
        for (double& v : c) v = bin<double>();
      } else {
        tag = integer("node tag", 1);
        for (double& v : c) v = real("coordinate");
      }
      add_node_tag(tag);
      add_coords(tag, c[0], c[1], c[2]);
      geo_dim_.push_back(-1);
      geo_tag_.push_back(-1);
    }
    expect_end("Nodes");
    return;
  }
  // MSH 4.1: header, then entity blocks (tags, then coordinates).
  std::size_t blocks, total;
  if (binary_) {
    in_binary_ = true;
    blocks = bin_count("number of entity blocks", 20);
    total = bin_count("number of nodes", 32);
    bin<std::uint64_t>();  // min and max tags: not needed
    bin<std::uint64_t>();
  } else {
    blocks = count("number of entity blocks", 4);
    total = count("number of nodes", 4);
    integer("minimum node tag", 0);
    integer("maximum node tag", 0);
  }
  node_index_.reserve(node_index_.size() + total);
  std::size_t seen = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    int dim, tag, parametric;
    std::size_t n;
    if (binary_) {
      dim = bin_int("entity dimension", 0, 3);
      tag = bin_int("entity tag");
      parametric = bin_int("parametric flag", 0, 1);
      n = bin_count("number of nodes in the block", 32);
    } else {
      dim = static_cast<int>(integer("entity dimension", 0, 3));
      tag = static_cast<int>(integer("entity tag", kInt32Min, kInt32Max));
      parametric = static_cast<int>(integer("parametric flag", 0, 1));
      n = count("number of nodes in the block", 4);
    }
    if (n > total - seen) fail("the entity blocks hold more nodes than the header's total of " + std::to_string(total));
    seen += n;
    const std::size_t first = node_tag_.size();
    for (std::size_t i = 0; i < n; ++i) add_node_tag(binary_ ? bin_tag("node tag") : integer("node tag", 1));
    const int extra = parametric ? dim : 0;  // u, v, w after x, y, z
    for (std::size_t i = 0; i < n; ++i) {
      double c[3];
      if (binary_) {
        for (double& v : c) v = bin<double>();
        skip_bytes(8 * static_cast<std::uint64_t>(extra));
      } else {
        for (double& v : c) v = real("coordinate");
        for (int k = 0; k < extra; ++k) real("parametric coordinate");
      }
      add_coords(node_tag_[first + i], c[0], c[1], c[2]);
      geo_dim_.push_back(static_cast<std::int8_t>(dim));
      geo_tag_.push_back(tag);
    }
  }
  if (seen != total)
    fail("the header says " + std::to_string(total) + " nodes but the entity blocks hold " + std::to_string(seen));
  expect_end("Nodes");
}

void MshParser::add_element(int dim, Id tag, int entity_dim, Id entity, Id physical, const Id* nodes) {
  Group& g = groups_[dim];
  const auto [it0, fresh] = element_tags_.emplace(tag, std::make_pair(dim, g.tag.size()));
  if (!fresh) {
    // Gmsh's MSH 2 writer repeats an element, same tag and nodes, once per
    // physical group it belongs to: keep the first (its first group).
    bool same = !msh4_ && it0->second.first == dim;
    for (int k = 0; same && k < kNodesOfDim[dim]; ++k) {
      auto it = node_index_.find(nodes[k]);
      same = it != node_index_.end() &&
             g.conn[it0->second.second * static_cast<std::size_t>(kNodesOfDim[dim]) + static_cast<std::size_t>(k)] == it->second;
    }
    if (!same) fail("element tag " + std::to_string(tag) + " appears twice");
    ++repeated_;
    return;
  }
  for (int k = 0; k < kNodesOfDim[dim]; ++k) {
    auto it = node_index_.find(nodes[k]);
    if (it == node_index_.end())
      fail("element " + std::to_string(tag) + " references node tag " + std::to_string(nodes[k]) +
           ", which is not in $Nodes");
    g.conn.push_back(it->second);
  }
  g.tag.push_back(tag);
  g.entity_dim.push_back(static_cast<std::int8_t>(entity_dim));
  g.entity.push_back(static_cast<std::int32_t>(entity));
  g.physical.push_back(static_cast<std::int32_t>(physical));
}

void MshParser::fail_unknown_type(Id type) {
  fail("element type " + std::to_string(type) +
           " is not a fixed-size Gmsh element type; dicer needs all-hex (type 5) or all-quad (type 3) meshes",
       ErrorKind::Unsupported);
}

void MshParser::read_elements() {
  if (!saw_nodes_) fail("no $Nodes section before $Elements");
  saw_elements_ = true;
  Id nodes[8];
  if (!msh4_) {
    const std::size_t n = count("number of elements", 4);
    if (binary_) {
      // Binary MSH2: blocks of elements of one type: {type, count, number of tags},
      // then per element: tag, tags, node tags (all 4-byte ints).
      start_binary_data();
      std::size_t seen = 0;
      while (seen < n) {
        const int type = bin_int("element type", 1);
        const std::size_t follow = static_cast<std::size_t>(bin_int("number of elements in the block", 1));
        const int ntags = bin_int("number of tags", 0);
        if (follow > n - seen) fail("the element blocks hold more elements than the header's total of " + std::to_string(n));
        const ElementType* info = find_type(type);
        if (!info) fail_unknown_type(type);
        const std::size_t bytes_each = 4 * (1 + static_cast<std::size_t>(ntags) + static_cast<std::size_t>(info->nodes));
        if (follow > remaining() / bytes_each) too_many("number of elements in the block", follow);
        const int dim = kept_dim(type);
        if (dim < 0) {
          count_unsupported(type, follow);
          skip_bytes(follow * bytes_each);
        } else {
          for (std::size_t i = 0; i < follow; ++i) {
            const Id tag = bin_int("element tag", 1);
            Id physical = 0, entity = 0;
            for (int k = 0; k < ntags; ++k) {
              const Id t = bin<std::int32_t>();
              if (k == 0) physical = t;
              if (k == 1) entity = t;
            }
            for (int k = 0; k < kNodesOfDim[dim]; ++k) nodes[k] = bin_int("node tag", 1);
            add_element(dim, tag, dim, entity, physical, nodes);
          }
        }
        seen += follow;
      }
    } else {
      // ASCII MSH2: "tag type ntags tags... nodes..." per line.
      for (std::size_t i = 0; i < n; ++i) {
        const Id tag = integer("element tag", 1);
        const Id type = integer("element type", 1, kInt32Max);
        const std::size_t ntags = count("number of tags", 1);
        Id physical = 0, entity = 0;
        for (std::size_t k = 0; k < ntags; ++k) {
          const Id t = integer("element tag value", kInt32Min, kInt32Max);
          if (k == 0) physical = t;
          if (k == 1) entity = t;
        }
        const int dim = kept_dim(type);
        if (dim >= 0) {
          for (int k = 0; k < kNodesOfDim[dim]; ++k) nodes[k] = integer("node tag", 1);
          add_element(dim, tag, dim, entity, physical, nodes);
        } else {
          count_unsupported(type, 1);
          const ElementType* info = find_type(type);
          if (info) {
            for (int k = 0; k < info->nodes; ++k) token();
          } else {
            rest_of_line();
          }
        }
      }
    }
    expect_end("Elements");
    return;
  }
  // MSH 4.1: header, then entity blocks of one element type each.
  std::size_t blocks, total;
  if (binary_) {
    in_binary_ = true;
    blocks = bin_count("number of entity blocks", 20);
    total = bin_count("number of elements", 16);
    bin<std::uint64_t>();  // min and max tags: not needed
    bin<std::uint64_t>();
  } else {
    blocks = count("number of entity blocks", 4);
    total = count("number of elements", 2);
    integer("minimum element tag", 0);
    integer("maximum element tag", 0);
  }
  std::size_t seen = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    int entity_dim, entity, type;
    std::size_t n;
    const ElementType* info;
    if (binary_) {
      entity_dim = bin_int("entity dimension", 0, 3);
      entity = bin_int("entity tag");
      type = bin_int("element type", 1);
      info = find_type(type);
      if (!info) fail_unknown_type(type);
      n = bin_count("number of elements in the block", 8 * (1 + static_cast<std::size_t>(info->nodes)));
    } else {
      entity_dim = static_cast<int>(integer("entity dimension", 0, 3));
      entity = static_cast<int>(integer("entity tag", kInt32Min, kInt32Max));
      type = static_cast<int>(integer("element type", 1, kInt32Max));
      info = find_type(type);
      n = count("number of elements in the block", info ? 1 + static_cast<std::size_t>(info->nodes) : 1);
    }
    if (n > total - seen) fail("the entity blocks hold more elements than the header's total of " + std::to_string(total));
    seen += n;
    const int dim = kept_dim(type);
    if (dim < 0) {
      count_unsupported(type, n);
      if (binary_) {
        skip_bytes(static_cast<std::uint64_t>(n) * 8 * (1 + static_cast<std::uint64_t>(info->nodes)));
      } else {
        for (std::size_t i = 0; i < n; ++i) {
          if (info) {
            for (int k = 0; k <= info->nodes; ++k) token();
          } else {
            token();
            rest_of_line();
          }
        }
      }
      continue;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Id tag = binary_ ? bin_tag("element tag") : integer("element tag", 1);
      for (int k = 0; k < kNodesOfDim[dim]; ++k) nodes[k] = binary_ ? bin_tag("node tag") : integer("node tag", 1);
      add_element(dim, tag, entity_dim, entity, 0, nodes);
    }
  }
  if (seen != total)
    fail("the header says " + std::to_string(total) + " elements but the entity blocks hold " + std::to_string(seen));
  expect_end("Elements");
}

// Skips an unknown section up to its "$End<name>" line.
void MshParser::skip_section(const std::string& name) {
  const std::string marker = "\n$End" + name;
  std::size_t from = pos_ > 0 ? pos_ - 1 : 0;
  for (;;) {
    const std::size_t at = data_.find(marker, from);
    if (at == std::string::npos) eof("no $End" + name + " line");
    const std::size_t after = at + marker.size();
    if (after == data_.size() || is_space(data_[after])) {
      pos_ = after;
      rest_of_line();
      return;
    }
    from = at + 1;
  }
}

// ---------------------------------------------------------------------------

// Physical tags of element i of groups_[dim] (nonzero only).
std::span<const int> MshParser::physicals(int dim, std::size_t i) const {
  const Group& g = groups_[dim];
  if (!msh4_) {
    const std::int32_t& p = g.physical[i];
    return p != 0 ? std::span<const int>(&p, 1) : std::span<const int>();
  }
  auto it = entity_physicals_.find({g.entity_dim[i], g.entity[i]});
  if (it == entity_physicals_.end()) return {};
  return it->second;
}

CoarseMesh MshParser::parse() {
  read_format();
  for (;;) {
    section_.clear();
    in_binary_ = false;
    skip_space();
    if (pos_ >= data_.size()) break;
    const std::string header = header_line();
    if (header.size() < 2 || header[0] != '$')
      fail("expected a section header such as $Nodes, found '" + shown(header) + "'");
    const std::string name = header.substr(1);
    if (name.starts_with("End")) fail("'" + shown(header) + "' has no matching opening line");
    section_ = header;
    if (name == "MeshFormat") fail("a second $MeshFormat section");
    else if (name == "PhysicalNames") read_physical_names();
    else if (name == "Entities" && msh4_) read_entities();
    else if (name == "Nodes") read_nodes();
    else if (name == "Elements") read_elements();
    else skip_section(name);
  }
  if (!saw_nodes_) throw Error(ErrorKind::BadInput, path_ + ": no $Nodes section");
  if (!saw_elements_) throw Error(ErrorKind::BadInput, path_ + ": no $Elements section");
  return build();
}

CoarseMesh MshParser::build() {
  if (!unsupported_.empty()) {
    std::string list;
    for (const auto& [type, n] : unsupported_) {
      if (!list.empty()) list += ", ";
      list += std::to_string(n) + " " + type_name(static_cast<int>(type)) + " (type " + std::to_string(type) + ")";
    }
    throw Error(ErrorKind::Unsupported, path_ + ": unsupported elements: " + list +
                                            "; dicer needs all-hex (type 5) or all-quad (type 3) meshes");
  }
  if (groups_[3].size() == 0 && groups_[2].size() == 0)
    throw Error(ErrorKind::Unsupported,
                path_ + ": no hexahedra (type 5) or quadrangles (type 3); dicer needs all-hex or all-quad meshes");

  CoarseMesh mesh;
  mesh.source = path_;
  mesh.mode = groups_[3].size() > 0 ? Mode::Volume : Mode::Surface;
  const int dim = mesh.mode == Mode::Volume ? 3 : 2;
  const int corners = kNodesOfDim[dim];
  const Group& cells = groups_[dim];
  const std::size_t num_cells = cells.size();

  // Vertex classification (MSH2: lowest-dimensional element holding the node).
  if (!msh4_) {
    for (int d = 0; d < 4; ++d) {
      const Group& g = groups_[d];
      for (std::size_t i = 0; i < g.conn.size(); ++i) {
        const Id v = g.conn[i];
        if (geo_dim_[v] < 0) {
          geo_dim_[v] = static_cast<std::int8_t>(d);
          geo_tag_[v] = g.entity[i / static_cast<std::size_t>(kNodesOfDim[d])];
        }
      }
    }
  }

  // Blocks.
  std::map<Id, std::string> block_names;  // id -> name
  std::vector<Id> cell_block_id(num_cells);
  std::map<Id, Id> orphan_entities;        // entity tag -> block id (mixed case)
  Id max_physical = std::numeric_limits<Id>::min();
  for (std::size_t i = 0; i < num_cells; ++i) {
    std::span<const int> p = physicals(dim, i);
    if (!p.empty()) max_physical = std::max<Id>(max_physical, p[0]);
  }
  const bool by_physical = max_physical != std::numeric_limits<Id>::min();
  std::size_t orphans = 0;
  for (std::size_t i = 0; i < num_cells; ++i) {
    std::span<const int> p = physicals(dim, i);
    if (!p.empty()) {
      cell_block_id[i] = p[0];
      auto it = physical_names_.find({dim, p[0]});
      block_names.emplace(p[0], it != physical_names_.end() ? it->second : std::string());
    } else if (!by_physical) {
      cell_block_id[i] = cells.entity[i];
      block_names.emplace(cells.entity[i], "entity " + std::to_string(cells.entity[i]));
    } else {
      orphan_entities.emplace(cells.entity[i], 0);
      ++orphans;
    }
  }
  if (orphans > 0) {
    Id next = max_physical;
    for (auto& [entity, id] : orphan_entities) {
      id = ++next;
      block_names.emplace(id, "entity " + std::to_string(entity));
    }
    for (std::size_t i = 0; i < num_cells; ++i)
      if (physicals(dim, i).empty()) cell_block_id[i] = orphan_entities[cells.entity[i]];
    mesh.warnings.push_back(path_ + ": " + std::to_string(orphans) + " " + (dim == 3 ? "hexahedra" : "quadrangles") +
                            " are in no physical group; they were put in blocks named 'entity <tag>' with ids from " +
                            std::to_string(max_physical + 1));
  }
  std::map<Id, std::int32_t> block_index;
  for (const auto& [id, name] : block_names) {
    block_index.emplace(id, static_cast<std::int32_t>(mesh.blocks.size()));
    mesh.blocks.push_back(Block{id, name});
  }
  mesh.element_block.resize(num_cells);
  for (std::size_t i = 0; i < num_cells; ++i) mesh.element_block[i] = block_index[cell_block_id[i]];

  // Side sets: physical groups of dimension dim-1, matched to element sides
  // by the sorted corner ids of each side.
  const Group& bnd = groups_[dim - 1];
  std::map<Id, SideSet> side_sets;
  std::size_t unmatched = 0;
  Id first_unmatched = 0;
  bool any_side = false;
  for (std::size_t i = 0; i < bnd.size() && !any_side; ++i) any_side = !physicals(dim - 1, i).empty();
  if (any_side) {
    using Key = std::array<Id, 4>;
    struct Side {
      Key key;
      Id element;
      std::int8_t side;
    };
    static constexpr int kQuadEdges[4][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}};
    std::vector<Side> sides;
    sides.reserve(num_cells * (dim == 3 ? 6 : 4));
    for (std::size_t e = 0; e < num_cells; ++e) {
      const Id* c = &cells.conn[e * static_cast<std::size_t>(corners)];
      if (dim == 3) {
        for (int s = 0; s < 6; ++s) {
          Key k;
          for (int j = 0; j < 4; ++j) k[j] = c[kHexSideCorners[s][j]];
          std::sort(k.begin(), k.end());
          sides.push_back({k, static_cast<Id>(e), static_cast<std::int8_t>(s)});
        }
      } else {
        for (int s = 0; s < 4; ++s) {
          Key k{-1, -1, c[kQuadEdges[s][0]], c[kQuadEdges[s][1]]};
          std::sort(k.begin(), k.end());
          sides.push_back({k, static_cast<Id>(e), static_cast<std::int8_t>(s + 2)});  // SHELL4 edges are 2..5
        }
      }
    }
    auto less = [](const Side& a, const Side& b) { return std::tie(a.key, a.element) < std::tie(b.key, b.element); };
    std::sort(sides.begin(), sides.end(), less);
    const int bnd_corners = kNodesOfDim[dim - 1];
    for (std::size_t i = 0; i < bnd.size(); ++i) {
      std::span<const int> p = physicals(dim - 1, i);
      if (p.empty()) continue;
      Key k{-1, -1, -1, -1};
      for (int j = 0; j < bnd_corners; ++j) k[4 - bnd_corners + j] = bnd.conn[i * static_cast<std::size_t>(bnd_corners) + j];
      std::sort(k.begin(), k.end());
      auto it = std::lower_bound(sides.begin(), sides.end(), Side{k, -1, 0}, less);
      if (it == sides.end() || it->key != k) {
        if (unmatched++ == 0) first_unmatched = bnd.tag[i];
        continue;
      }
      for (int tag : p) {
        SideSet& ss = side_sets[tag];
        ss.element.push_back(it->element);
        ss.side.push_back(it->side);
      }
    }
    for (auto& [id, ss] : side_sets) {
      ss.id = id;
      auto it = physical_names_.find({dim - 1, id});
      if (it != physical_names_.end()) ss.name = it->second;
      mesh.side_sets.push_back(std::move(ss));
    }
  }
  if (repeated_ > 0)
    mesh.warnings.push_back(path_ + ": " + std::to_string(repeated_) +
                            " element(s) are listed again, same tag and nodes, for a further physical group (Gmsh's MSH 2 "
                            "writer does this); each was kept once, in its first group");
  if (unmatched > 0)
    mesh.warnings.push_back(path_ + ": " + std::to_string(unmatched) + " " + (dim == 3 ? "quadrangles" : "lines") +
                            " in physical groups match no " + (dim == 3 ? "hexahedron face" : "quadrangle edge") +
                            " and were skipped (the first is element " + std::to_string(first_unmatched) + ")");

  // Node sets: physical groups of dimension 0 (point elements).
  std::map<Id, std::vector<Id>> node_sets;
  for (std::size_t i = 0; i < groups_[0].size(); ++i)
    for (int tag : physicals(0, i)) node_sets[tag].push_back(groups_[0].conn[i]);
  for (auto& [id, vertices] : node_sets) {
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    NodeSet ns;
    ns.id = id;
    auto it = physical_names_.find({0, id});
    if (it != physical_names_.end()) ns.name = it->second;
    ns.vertex = std::move(vertices);
    mesh.node_sets.push_back(std::move(ns));
  }

  mesh.x = std::move(x_);
  mesh.y = std::move(y_);
  mesh.z = std::move(z_);
  mesh.vertex_file_id = std::move(node_tag_);
  mesh.vertex_geo_dim = std::move(geo_dim_);
  mesh.vertex_geo_tag = std::move(geo_tag_);
  mesh.conn = cells.conn;
  mesh.element_file_id = cells.tag;
  return mesh;
}

}  // namespace

CoarseMesh read_msh(const std::string& path) {
  MshParser parser(path, read_whole_file(path));
  return parser.parse();
}

}  // namespace dicer
