// MSH sections: one reader per section and version (2.2 and 4.1, ASCII and
// binary), filling MshSections (see msh_reader.hpp). Hostile counts are
// refused by the lexer before anything is reserved.
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <unordered_map>

#include "msh_reader.hpp"

namespace dicer::msh {

// ---- Gmsh element types (fixed-size ones, from Gmsh's own table) ------------

namespace {

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

}  // namespace

const ElementType* find_type(Id type) {
  for (const ElementType& t : kElementTypes)
    if (t.type == type) return &t;
  return nullptr;
}

int kept_dim(Id type) {
  switch (type) {
    case kPoint: return 0;
    case kLine: case 8: return 1;
    case kQuad: case 16: case 10: return 2;
    case kHex: case 17: case 12: return 3;
    default: return -1;
  }
}

int type_dim(Id type) {
  static constexpr int kShapeDim[] = {0, 1, 2, 2, 3, 3, 3, 3};
  const ElementType* t = find_type(type);
  return t ? kShapeDim[static_cast<int>(t->shape)] : -1;
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

std::span<const int> MshSections::physicals(int dim, std::size_t i) const {
  const Group& g = groups[dim];
  if (!msh4) {
    const std::int32_t& p = g.physical[i];
    return p != 0 ? std::span<const int>(&p, 1) : std::span<const int>();
  }
  auto it = entity_physicals.find({g.entity_dim[i], g.entity[i]});
  if (it == entity_physicals.end()) return {};
  return it->second;
}

// ---- section readers ------------------------------------------------------------

namespace {

class SectionReader {
 public:
  explicit SectionReader(Lexer& lex) : lex_(lex) {}
  MshSections read();

 private:
  void read_format();
  void read_physical_names();
  void read_entities();
  // MSH 1 ($NOD, $ENDNOD) and 2: a count, then "tag x y z" per node.
  void read_nodes_msh12(const std::string& end_line);
  void read_nodes_msh41();
  void read_elements_msh1();
  void read_elements_msh2();
  void read_elements_msh41();
  // The nodes of one ASCII element (MSH 1 and 2), after its tags; `listed`
  // is MSH 1's node count (-1 in MSH 2, which does not state it).
  void ascii_element_nodes(Id tag, Id type, Id entity, Id physical, Id listed);

  // MSH 4.1 $Nodes / $Elements header: number of entity blocks, number of
  // items (each at least `bytes_each` binary bytes or `tokens_each` tokens),
  // minimum and maximum tags (not needed).
  std::pair<std::size_t, std::size_t> msh41_header(const std::string& item, std::size_t bytes_each,
                                                   std::size_t tokens_each);
  void add_node_tag(Id tag);
  void add_coords(Id tag, double x, double y, double z);
  // A kept element: its type's nodes (find_type), corners first.
  void add_element(int dim, Id type, Id tag, int entity_dim, Id entity, Id physical, const Id* nodes);
  void count_other(Id type, int entity_dim, Id entity, Id physical, std::size_t n) {
    s_.others[{type, entity_dim, entity, physical}] += n;
  }
  [[noreturn]] void fail_unknown_type(Id type);

  Lexer& lex_;
  MshSections s_;
  int version_ = 0;      // 1, 2 or 4 once known ($NOD or $MeshFormat)
  bool binary_ = false;  // file-type 1
  bool saw_nodes_ = false, saw_elements_ = false;
  std::unordered_map<Id, Id> node_index_;                               // file tag -> 0-based vertex
  std::unordered_map<Id, std::pair<int, std::size_t>> element_tags_;  // tag -> (dim, index in group)
};

void SectionReader::read_format() {
  const std::string version(lex_.token());
  binary_ = lex_.integer("file-type", 0, 1) == 1;
  const Id data_size = lex_.integer("data-size", 0);
  double v = 0;
  auto [end, ec] = std::from_chars(version.data(), version.data() + version.size(), v);
  if (ec != std::errc() || end != version.data() + version.size())
    lex_.fail("expected a version number, found '" + shown(version) + "'");
  if (v >= 2.0 && v < 3.0) {
    version_ = 2;
  } else if (std::abs(v - 4.1) < 1e-9) {
    version_ = 4;
  } else {
    lex_.fail("MSH version " + shown(version) +
                  " is not supported; dicer reads MSH 1, 2.2 and 4.1 (re-save the mesh with Gmsh)",
              ErrorKind::Unsupported);
  }
  s_.msh4 = version_ == 4;
  if (binary_ && data_size != 8)
    lex_.fail("binary data-size " + std::to_string(data_size) + " is not supported; only 8-byte doubles are");
  if (!trim(lex_.rest_of_line()).empty()) lex_.fail("unexpected text after the data-size");
  if (binary_) {
    lex_.set_binary(true);
    const std::int32_t one = lex_.bin<std::int32_t>();
    if (one != 1) {
      lex_.set_swap(true);
      lex_.unread(4);
      if (lex_.bin<std::int32_t>() != 1) lex_.fail("expected the binary integer 1 that tells the byte order");
    }
    lex_.set_binary(false);
  }
  lex_.expect_end("MeshFormat");
}

void SectionReader::read_physical_names() {
  const std::size_t n = lex_.count("number of physical names", 3);
  for (std::size_t i = 0; i < n; ++i) {
    const int dim = static_cast<int>(lex_.integer("physical dimension", 0, 3));
    const Id tag = lex_.integer("physical tag", kInt32Min, kInt32Max);
    std::string_view name = trim(lex_.rest_of_line());
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"') name = name.substr(1, name.size() - 2);
    s_.physical_names.emplace(std::make_pair(dim, tag), std::string(name));
  }
  lex_.expect_end("PhysicalNames");
}

// MSH 4.1: the physical tags of every entity and the entities bounding each
// curve, surface and volume (bounding boxes are skipped).
void SectionReader::read_entities() {
  std::size_t n[4];
  if (binary_) {
    lex_.set_binary(true);
    for (int d = 0; d < 4; ++d) n[d] = lex_.bin_count("number of entities", d == 0 ? 36 : 68);
  } else {
    for (int d = 0; d < 4; ++d) n[d] = lex_.count("number of entities", d == 0 ? 5 : 9);
  }
  for (int d = 0; d < 4; ++d) {
    for (std::size_t i = 0; i < n[d]; ++i) {
      std::vector<int> phys, bounding;
      int tag;
      if (binary_) {
        tag = lex_.bin_int("entity tag");
        lex_.skip_bytes(d == 0 ? 24 : 48);
        const std::size_t np = lex_.bin_count("number of physical tags", 4);
        for (std::size_t k = 0; k < np; ++k) phys.push_back(lex_.bin_int("physical tag"));
        if (d > 0) {
          const std::size_t nb = lex_.bin_count("number of bounding entities", 4);
          for (std::size_t k = 0; k < nb; ++k) bounding.push_back(lex_.bin_int("bounding entity"));
        }
      } else {
        tag = static_cast<int>(lex_.integer("entity tag", kInt32Min, kInt32Max));
        for (int k = 0; k < (d == 0 ? 3 : 6); ++k) lex_.token();
        const std::size_t np = lex_.count("number of physical tags", 1);
        for (std::size_t k = 0; k < np; ++k)
          phys.push_back(static_cast<int>(lex_.integer("physical tag", kInt32Min, kInt32Max)));
        if (d > 0) {
          const std::size_t nb = lex_.count("number of bounding entities", 1);
          for (std::size_t k = 0; k < nb; ++k)
            bounding.push_back(static_cast<int>(lex_.integer("bounding entity", kInt32Min, kInt32Max)));
        }
      }
      // Tag 0 is a group here (Gmsh's own reader keeps it; deal.ii writes
      // its default boundary id 0 so): "none" is a count of 0. Only MSH2's
      // element tag 0 means none.
      s_.entity_physicals[{d, tag}] = std::move(phys);
      if (d > 0) {
        // Signs give the orientation of the boundary: dicer needs only which.
        for (int& b : bounding) b = b == kInt32Min ? b : std::abs(b);
        s_.entities.push_back({d, tag, std::move(bounding)});
      }
    }
  }
  lex_.expect_end("Entities");
}

std::pair<std::size_t, std::size_t> SectionReader::msh41_header(const std::string& item, std::size_t bytes_each,
                                                                 std::size_t tokens_each) {
  std::size_t blocks, total;
  if (binary_) {
    lex_.set_binary(true);
    blocks = lex_.bin_count("number of entity blocks", 20);
    total = lex_.bin_count("number of " + item + "s", bytes_each);
    lex_.bin<std::uint64_t>();
    lex_.bin<std::uint64_t>();
  } else {
    blocks = lex_.count("number of entity blocks", 4);
    total = lex_.count("number of " + item + "s", tokens_each);
    lex_.integer("minimum " + item + " tag", 0);
    lex_.integer("maximum " + item + " tag", 0);
  }
  return {blocks, total};
}

void SectionReader::add_node_tag(Id tag) {
  const Id index = static_cast<Id>(s_.node_tag.size());
  if (!node_index_.emplace(tag, index).second) lex_.fail("node tag " + std::to_string(tag) + " appears twice");
  s_.node_tag.push_back(tag);
}

void SectionReader::add_coords(Id tag, double x, double y, double z) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
    lex_.fail("node tag " + std::to_string(tag) + " has a coordinate that is not a finite number");
  s_.x.push_back(x);
  s_.y.push_back(y);
  s_.z.push_back(z);
}

void SectionReader::read_nodes_msh12(const std::string& end_line) {
  saw_nodes_ = true;
  const std::size_t n = lex_.count("number of nodes", 4);
  if (binary_) {
    lex_.start_binary_data();
    if (n > lex_.remaining() / 28) lex_.too_many("number of nodes", n);
  }
  node_index_.reserve(node_index_.size() + n);
  for (std::size_t i = 0; i < n; ++i) {
    Id tag;
    double c[3];
    if (binary_) {
      tag = lex_.bin_int("node tag", 1);
      for (double& v : c) v = lex_.bin<double>();
    } else {
      tag = lex_.integer("node tag", 1);
      for (double& v : c) v = lex_.real("coordinate");
    }
    add_node_tag(tag);
    add_coords(tag, c[0], c[1], c[2]);
    s_.geo_dim.push_back(-1);
    s_.geo_tag.push_back(-1);
  }
  lex_.expect_line(end_line);
}

// MSH 4.1: header, then entity blocks (tags, then coordinates).
void SectionReader::read_nodes_msh41() {
  saw_nodes_ = true;
  const auto [blocks, total] = msh41_header("node", 32, 4);
  node_index_.reserve(node_index_.size() + total);
  std::size_t seen = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    int dim, tag, parametric;
    std::size_t n;
    if (binary_) {
      dim = lex_.bin_int("entity dimension", 0, 3);
      tag = lex_.bin_int("entity tag");
      parametric = lex_.bin_int("parametric flag", 0, 1);
      n = lex_.bin_count("number of nodes in the block", 32);
    } else {
      dim = static_cast<int>(lex_.integer("entity dimension", 0, 3));
      tag = static_cast<int>(lex_.integer("entity tag", kInt32Min, kInt32Max));
      parametric = static_cast<int>(lex_.integer("parametric flag", 0, 1));
      n = lex_.count("number of nodes in the block", 4);
    }
    if (n > total - seen) lex_.fail("the entity blocks hold more nodes than the header's total of " + std::to_string(total));
    seen += n;
    const std::size_t first = s_.node_tag.size();
    for (std::size_t i = 0; i < n; ++i) add_node_tag(binary_ ? lex_.bin_tag("node tag") : lex_.integer("node tag", 1));
    const int extra = parametric ? dim : 0;  // u, v, w after x, y, z
    for (std::size_t i = 0; i < n; ++i) {
      double c[3];
      if (binary_) {
        for (double& v : c) v = lex_.bin<double>();
        lex_.skip_bytes(8 * static_cast<std::uint64_t>(extra));
      } else {
        for (double& v : c) v = lex_.real("coordinate");
        for (int k = 0; k < extra; ++k) lex_.real("parametric coordinate");
      }
      add_coords(s_.node_tag[first + i], c[0], c[1], c[2]);
      s_.geo_dim.push_back(static_cast<std::int8_t>(dim));
      s_.geo_tag.push_back(tag);
    }
  }
  if (seen != total)
    lex_.fail("the header says " + std::to_string(total) + " nodes but the entity blocks hold " + std::to_string(seen));
  lex_.expect_end("Nodes");
}

void SectionReader::add_element(int dim, Id type, Id tag, int entity_dim, Id entity, Id physical, const Id* nodes) {
  Group& g = s_.groups[dim];
  const auto [it0, fresh] = element_tags_.emplace(tag, std::make_pair(dim, g.tag.size()));
  if (!fresh) {
    // Gmsh's MSH 2 writer repeats an element, same tag and nodes, once per
    // physical group it belongs to: keep the first (its first group).
    bool same = !s_.msh4 && it0->second.first == dim;
    for (int k = 0; same && k < kNodesOfDim[dim]; ++k) {
      auto it = node_index_.find(nodes[k]);
      same = it != node_index_.end() &&
             g.conn[it0->second.second * static_cast<std::size_t>(kNodesOfDim[dim]) + static_cast<std::size_t>(k)] ==
                 it->second;
    }
    if (!same) lex_.fail("element tag " + std::to_string(tag) + " appears twice");
    ++s_.repeated;
    return;
  }
  auto index = [&](Id node) {
    auto it = node_index_.find(node);
    if (it == node_index_.end())
      lex_.fail("element " + std::to_string(tag) + " references node tag " + std::to_string(node) +
                ", which is not in $Nodes");
    return it->second;
  };
  for (int k = 0; k < kNodesOfDim[dim]; ++k) g.conn.push_back(index(nodes[k]));
  const int total = find_type(type)->nodes;
  if (dim >= 2) {
    const Mode mode = dim == 3 ? Mode::Volume : Mode::Surface;
    const std::size_t slots = static_cast<std::size_t>(mid_slots(mode));
    if (total > kNodesOfDim[dim] || !g.mid.empty()) {
      const std::size_t first = g.tag.size() * slots;  // the earlier elements' slots, -1 if first order
      g.mid.resize(first + slots, -1);
      for (int k = kNodesOfDim[dim]; k < total; ++k) g.mid[first + static_cast<std::size_t>(mid_slot(NodeOrder::Gmsh, mode, k))] = index(nodes[k]);
    }
  } else {
    for (int k = kNodesOfDim[dim]; k < total; ++k) index(nodes[k]);  // a line's middle: must exist, not kept
  }
  g.tag.push_back(tag);
  g.entity_dim.push_back(static_cast<std::int8_t>(entity_dim));
  g.entity.push_back(static_cast<std::int32_t>(entity));
  g.physical.push_back(static_cast<std::int32_t>(physical));
}

void SectionReader::fail_unknown_type(Id type) {
  lex_.fail("element type " + std::to_string(type) +
                " is not a fixed-size Gmsh element type; dicer needs all-hex (type 5) or all-quad (type 3) meshes",
            ErrorKind::Unsupported);
}

void SectionReader::ascii_element_nodes(Id tag, Id type, Id entity, Id physical, Id listed) {
  const int dim = kept_dim(type);
  if (dim >= 0) {
    Id nodes[kMaxKeptNodes];
    for (int k = 0; k < find_type(type)->nodes; ++k) nodes[k] = lex_.integer("node tag", 1);
    add_element(dim, type, tag, dim, entity, physical, nodes);
    return;
  }
  count_other(type, type_dim(type), entity, physical, 1);
  const ElementType* info = find_type(type);
  if (listed >= 0 || info) {
    for (Id k = 0; k < (listed >= 0 ? listed : info->nodes); ++k) lex_.token();
  } else {
    lex_.rest_of_line();
  }
}

// MSH 1: "tag type reg-phys reg-elem number-of-nodes nodes..." per line.
void SectionReader::read_elements_msh1() {
  if (!saw_nodes_) lex_.fail("no $NOD section before $ELM");
  saw_elements_ = true;
  const std::size_t n = lex_.count("number of elements", 6);
  for (std::size_t i = 0; i < n; ++i) {
    const Id tag = lex_.integer("element tag", 1);
    const Id type = lex_.integer("element type", 1, kInt32Max);
    const Id physical = lex_.integer("physical entity", kInt32Min, kInt32Max);
    const Id entity = lex_.integer("elementary entity", kInt32Min, kInt32Max);
    const std::size_t listed = lex_.count("number of nodes", 1);
    const ElementType* info = find_type(type);
    if (info && listed != static_cast<std::size_t>(info->nodes))
      lex_.fail("element " + std::to_string(tag) + ": a " + type_name(static_cast<int>(type)) + " (type " +
                std::to_string(type) + ") has " + std::to_string(info->nodes) + " nodes, the line says " +
                std::to_string(listed));
    ascii_element_nodes(tag, type, entity, physical, static_cast<Id>(listed));
  }
  lex_.expect_line("$ENDELM");
}

void SectionReader::read_elements_msh2() {
  if (!saw_nodes_) lex_.fail("no $Nodes section before $Elements");
  saw_elements_ = true;
  Id nodes[kMaxKeptNodes];
  const std::size_t n = lex_.count("number of elements", 4);
  if (binary_) {
    // Binary MSH2: blocks of elements of one type: {type, count, number of tags},
    // then per element: tag, tags, node tags (all 4-byte ints).
    lex_.start_binary_data();
    std::size_t seen = 0;
    while (seen < n) {
      const int type = lex_.bin_int("element type", 1);
      const std::size_t follow = static_cast<std::size_t>(lex_.bin_int("number of elements in the block", 1));
      const int ntags = lex_.bin_int("number of tags", 0);
      if (follow > n - seen)
        lex_.fail("the element blocks hold more elements than the header's total of " + std::to_string(n));
      const ElementType* info = find_type(type);
      if (!info) fail_unknown_type(type);
      const std::size_t bytes_each = 4 * (1 + static_cast<std::size_t>(ntags) + static_cast<std::size_t>(info->nodes));
      if (follow > lex_.remaining() / bytes_each) lex_.too_many("number of elements in the block", follow);
      const int dim = kept_dim(type);
      for (std::size_t i = 0; i < follow; ++i) {
        const Id tag = lex_.bin_int("element tag", 1);
        Id physical = 0, entity = 0;
        for (int k = 0; k < ntags; ++k) {
          const Id t = lex_.bin<std::int32_t>();
          if (k == 0) physical = t;
          if (k == 1) entity = t;
        }
        if (dim < 0) {
          count_other(type, type_dim(type), entity, physical, 1);
          lex_.skip_bytes(4 * static_cast<std::uint64_t>(info->nodes));
          continue;
        }
        for (int k = 0; k < info->nodes; ++k) nodes[k] = lex_.bin_int("node tag", 1);
        add_element(dim, type, tag, dim, entity, physical, nodes);
      }
      seen += follow;
    }
  } else {
    // ASCII MSH2: "tag type ntags tags... nodes..." per line.
    for (std::size_t i = 0; i < n; ++i) {
      const Id tag = lex_.integer("element tag", 1);
      const Id type = lex_.integer("element type", 1, kInt32Max);
      const std::size_t ntags = lex_.count("number of tags", 1);
      Id physical = 0, entity = 0;
      for (std::size_t k = 0; k < ntags; ++k) {
        const Id t = lex_.integer("element tag value", kInt32Min, kInt32Max);
        if (k == 0) physical = t;
        if (k == 1) entity = t;
      }
      ascii_element_nodes(tag, type, entity, physical, -1);
    }
  }
  lex_.expect_end("Elements");
}

// MSH 4.1: header, then entity blocks of one element type each.
void SectionReader::read_elements_msh41() {
  if (!saw_nodes_) lex_.fail("no $Nodes section before $Elements");
  saw_elements_ = true;
  Id nodes[kMaxKeptNodes];
  const auto [blocks, total] = msh41_header("element", 16, 2);
  std::size_t seen = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    int entity_dim, entity, type;
    std::size_t n;
    const ElementType* info;
    if (binary_) {
      entity_dim = lex_.bin_int("entity dimension", 0, 3);
      entity = lex_.bin_int("entity tag");
      type = lex_.bin_int("element type", 1);
      info = find_type(type);
      if (!info) fail_unknown_type(type);
      n = lex_.bin_count("number of elements in the block", 8 * (1 + static_cast<std::size_t>(info->nodes)));
    } else {
      entity_dim = static_cast<int>(lex_.integer("entity dimension", 0, 3));
      entity = static_cast<int>(lex_.integer("entity tag", kInt32Min, kInt32Max));
      type = static_cast<int>(lex_.integer("element type", 1, kInt32Max));
      info = find_type(type);
      n = lex_.count("number of elements in the block", info ? 1 + static_cast<std::size_t>(info->nodes) : 1);
    }
    if (n > total - seen)
      lex_.fail("the entity blocks hold more elements than the header's total of " + std::to_string(total));
    seen += n;
    const int dim = kept_dim(type);
    if (dim < 0) {
      count_other(type, entity_dim, entity, 0, n);
      if (binary_) {
        lex_.skip_bytes(static_cast<std::uint64_t>(n) * 8 * (1 + static_cast<std::uint64_t>(info->nodes)));
      } else {
        for (std::size_t i = 0; i < n; ++i) {
          if (info) {
            for (int k = 0; k <= info->nodes; ++k) lex_.token();
          } else {
            lex_.token();
            lex_.rest_of_line();
          }
        }
      }
      continue;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Id tag = binary_ ? lex_.bin_tag("element tag") : lex_.integer("element tag", 1);
      for (int k = 0; k < info->nodes; ++k)
        nodes[k] = binary_ ? lex_.bin_tag("node tag") : lex_.integer("node tag", 1);
      add_element(dim, type, tag, entity_dim, entity, 0, nodes);
    }
  }
  if (seen != total)
    lex_.fail("the header says " + std::to_string(total) + " elements but the entity blocks hold " + std::to_string(seen));
  lex_.expect_end("Elements");
}

// Gmsh reads sections in any order and skips those it does not know, before
// $MeshFormat too; so do we. Sections whose layout depends on the format
// (binary or not, version) must come after it.
MshSections SectionReader::read() {
  lex_.skip_space();
  if (lex_.at_end()) throw Error(ErrorKind::BadInput, lex_.path() + ": the file is empty");
  for (;;) {
    lex_.set_section("");
    lex_.set_binary(false);
    lex_.skip_space();
    if (lex_.at_end()) break;
    const std::string header = lex_.header_line();
    if (header.size() < 2 || header[0] != '$') {
      if (version_ == 0) lex_.fail("not a Gmsh MSH file: expected a section header such as $MeshFormat, found '" +
                                   shown(header) + "'");
      lex_.fail("expected a section header such as $Nodes, found '" + shown(header) + "'");
    }
    const std::string name = header.substr(1);
    if (name.starts_with("End") || name.starts_with("END"))
      lex_.fail("'" + shown(header) + "' has no matching opening line");
    lex_.set_section(header);
    const bool msh1_section = name == "NOD" || name == "NOE" || name == "ELM";
    const bool needs_format = name == "Nodes" || name == "Elements" || name == "Entities";
    if (name == "MeshFormat") {
      if (version_ != 0) lex_.fail(version_ == 1 ? "$MeshFormat in an MSH 1 file" : "a second $MeshFormat section");
      read_format();
    } else if (msh1_section) {
      if (version_ > 1) lex_.fail("an MSH 1 section in an MSH " + std::string(s_.msh4 ? "4.1" : "2") + " file");
      version_ = 1;
      if (name == "ELM") read_elements_msh1();
      else read_nodes_msh12("$END" + name);
    } else if (needs_format && version_ == 0) {
      lex_.fail("comes before $MeshFormat, which says how to read it");
    } else if (needs_format && version_ == 1) {
      lex_.fail("an MSH 2/4 section in an MSH 1 file ($NOD)");
    } else if (name == "PhysicalNames") {
      read_physical_names();
    } else if (name == "Entities" && s_.msh4) {
      read_entities();
    } else if (name == "Nodes") {
      if (s_.msh4) read_nodes_msh41();
      else read_nodes_msh12("$EndNodes");
    } else if (name == "Elements") {
      if (s_.msh4) read_elements_msh41();
      else read_elements_msh2();
    } else {
      s_.periodic = s_.periodic || name == "Periodic";
      lex_.skip_to_end_line(name);
    }
  }
  if (version_ == 0)
    throw Error(ErrorKind::BadInput, lex_.path() + ": not a Gmsh MSH file: no $MeshFormat section (nor MSH 1's $NOD)");
  const char* nodes = version_ == 1 ? "$NOD" : "$Nodes";
  const char* elements = version_ == 1 ? "$ELM" : "$Elements";
  if (!saw_nodes_) throw Error(ErrorKind::BadInput, lex_.path() + ": no " + nodes + " section");
  if (!saw_elements_) throw Error(ErrorKind::BadInput, lex_.path() + ": no " + elements + " section");
  return std::move(s_);
}

}  // namespace

MshSections read_sections(Lexer& lex) { return SectionReader(lex).read(); }

}  // namespace dicer::msh
