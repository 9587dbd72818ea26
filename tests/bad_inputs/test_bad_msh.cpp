// read_msh on malformed, truncated, hostile and unsupported MSH files: each
// must throw dicer::Error of the right kind with a message that names the
// file and the problem, and never crash or over-allocate.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "test_support.hpp"

using dicer::ErrorKind;
using dicer::test::data_path;
using dicer::test::TempDir;
using dicer::test::write_file;
using testing::HasSubstr;
using testing::StartsWith;

namespace {

struct Outcome {
  bool threw = false;
  ErrorKind kind = ErrorKind::Usage;
  std::string message;
  std::string path;
};

// Writes `bytes` to a temporary file and reads it, catching dicer::Error.
Outcome read_bytes(const std::string& bytes) {
  TempDir tmp;
  Outcome o;
  o.path = tmp.path("bad.msh");
  write_file(o.path, bytes);
  try {
    dicer::read_msh(o.path);
  } catch (const dicer::Error& e) {
    o.threw = true;
    o.kind = e.kind();
    o.message = e.what();
  }
  return o;
}

#define EXPECT_MSH_ERROR(outcome, expected_kind, substring)       \
  do {                                                           \
    const Outcome& o_ = (outcome);                               \
    ASSERT_TRUE(o_.threw) << "no error";                         \
    EXPECT_EQ(o_.kind, expected_kind) << o_.message;             \
    EXPECT_THAT(o_.message, StartsWith(o_.path + ": "));         \
    EXPECT_THAT(o_.message, HasSubstr(substring));               \
  } while (0)

const std::string kHeader22 = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
const std::string kHeader41 = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
const std::string kCubeNodes22 =
    "$Nodes\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$EndNodes\n";
const std::string kOneHex22 = "$Elements\n1\n1 5 2 1 1 1 2 3 4 5 6 7 8\n$EndElements\n";

// A valid little binary MSH 4.1 file (one hex) in the chosen byte order.
std::string tiny_binary41(bool big_endian) {
  const bool swap = big_endian != (std::endian::native == std::endian::big);
  std::string s = "$MeshFormat\n4.1 1 8\n";
  auto put = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    if (swap) std::reverse(b, b + sizeof(v));
    s.append(b, sizeof(v));
  };
  auto u64 = [&](std::uint64_t v) { put(v); };
  auto i32 = [&](std::int32_t v) { put(v); };
  i32(1);
  s += "\n$EndMeshFormat\n$Nodes\n";
  u64(1), u64(8), u64(1), u64(8);
  i32(3), i32(1), i32(0), u64(8);
  for (int t = 1; t <= 8; ++t) u64(t);
  const double c[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (const auto& p : c)
    for (double v : p) put(v);
  s += "\n$EndNodes\n$Elements\n";
  u64(1), u64(1), u64(1), u64(1);
  i32(3), i32(1), i32(5), u64(1);
  u64(1);
  for (int t = 1; t <= 8; ++t) u64(t);
  s += "\n$EndElements\n";
  return s;
}

}  // namespace

TEST(BadMsh, ValidFixturesRead) {
  // The fixtures the other tests break are themselves fine.
  EXPECT_FALSE(read_bytes(kHeader22 + kCubeNodes22 + kOneHex22).threw);
  EXPECT_FALSE(read_bytes(tiny_binary41(false)).threw);
  EXPECT_FALSE(read_bytes(tiny_binary41(true)).threw);
}

TEST(BadMsh, MissingFileIsIo) {
  TempDir tmp;
  try {
    dicer::read_msh(tmp.path("does-not-exist.msh"));
    FAIL() << "no error";
  } catch (const dicer::Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io);
    EXPECT_THAT(e.what(), HasSubstr("does-not-exist.msh: cannot open"));
  }
}

TEST(BadMsh, EmptyFile) {
  EXPECT_MSH_ERROR(read_bytes(""), ErrorKind::BadInput, "empty");
  EXPECT_MSH_ERROR(read_bytes("\n \n"), ErrorKind::BadInput, "empty");
}

TEST(BadMsh, NotAnMshFile) {
  EXPECT_MSH_ERROR(read_bytes("solid cube\nfacet normal 0 0 1\n"), ErrorKind::BadInput, "not a Gmsh MSH file");
  EXPECT_MSH_ERROR(read_bytes(std::string("\x89HDF\r\n\x1a\n\0\0\0", 11)), ErrorKind::BadInput,
                   "not a Gmsh MSH file");
}

TEST(BadMsh, OtherVersionsAreRefusedByName) {
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), ErrorKind::Unsupported,
                   "MSH version 3.0 is not supported");
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\n4 0 8\n$EndMeshFormat\n"), ErrorKind::Unsupported,
                   "MSH version 4 is not supported");
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\n4.0 0 8\n$EndMeshFormat\n"), ErrorKind::Unsupported,
                   "MSH version 4.0 is not supported");
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), ErrorKind::Unsupported,
                   "re-save the mesh with Gmsh");
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\nfour 0 8\n$EndMeshFormat\n"), ErrorKind::BadInput, "version");
}

TEST(BadMsh, BinaryDataSizeOtherThan8) {
  std::string s = "$MeshFormat\n4.1 1 4\n";
  const std::int32_t one = 1;
  s.append(reinterpret_cast<const char*>(&one), 4);
  s += "\n$EndMeshFormat\n";
  EXPECT_MSH_ERROR(read_bytes(s), ErrorKind::BadInput, "data-size 4");
}

TEST(BadMsh, BinaryWithoutByteOrderMark) {
  EXPECT_MSH_ERROR(read_bytes("$MeshFormat\n2.2 1 8\nABCD\n$EndMeshFormat\n"), ErrorKind::BadInput, "byte order");
}

TEST(BadMsh, TruncatedAsciiFile) {
  const std::string full = dicer::test::read_file(data_path("firedrake_cube_hex.msh"));
  const std::size_t nodes = full.find("$Nodes"), elements = full.find("$Elements");
  ASSERT_NE(nodes, std::string::npos);
  ASSERT_NE(elements, std::string::npos);
  // In the middle of $Nodes and $Elements.
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, elements - 100)), ErrorKind::BadInput,
                   "unexpected end of file in $Nodes");
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, full.size() - 200)), ErrorKind::BadInput,
                   "unexpected end of file in $Elements");
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, 15)), ErrorKind::BadInput, "unexpected end of file in $MeshFormat");
  // Cut early enough that the count itself cannot fit.
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, nodes + 2000)), ErrorKind::BadInput,
                   "unexpected end of file in $Nodes: number of nodes 989 needs more than");
  // Cut right after a whole section.
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, nodes)), ErrorKind::BadInput, "no $Nodes section");
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, elements)), ErrorKind::BadInput, "no $Elements section");
  // Cut inside the closing line.
  EXPECT_MSH_ERROR(read_bytes(full.substr(0, full.size() - 6)), ErrorKind::BadInput, "expected $EndElements");
  // Every cut gives a BadInput naming the file (a cut in the middle of a
  // number can leave a valid shorter number, never a crash).
  for (std::size_t cut = 0; cut + 1 < full.size(); cut += 97) {
    const Outcome o = read_bytes(full.substr(0, cut));
    ASSERT_TRUE(o.threw) << "cut at " << cut;
    EXPECT_EQ(o.kind, ErrorKind::BadInput) << o.message;
    EXPECT_THAT(o.message, StartsWith(o.path + ": "));
  }
}

TEST(BadMsh, TruncatedBinaryFile) {
  for (bool big : {false, true}) {
    const std::string full = tiny_binary41(big);
    const std::size_t nodes = full.find("$Nodes\n") + 7;
    EXPECT_MSH_ERROR(read_bytes(full.substr(0, nodes + 100)), ErrorKind::BadInput,
                     "unexpected end of file in $Nodes");
    EXPECT_THAT(read_bytes(full.substr(0, nodes + 100)).message, HasSubstr("byte offset"));
    const std::size_t elements = full.find("$Elements\n") + 10;
    EXPECT_MSH_ERROR(read_bytes(full.substr(0, elements + 50)), ErrorKind::BadInput,
                     "unexpected end of file in $Elements");
    for (std::size_t cut = 0; cut + 1 < full.size(); ++cut) {
      const Outcome o = read_bytes(full.substr(0, cut));
      ASSERT_TRUE(o.threw) << "cut at " << cut;
      EXPECT_EQ(o.kind, ErrorKind::BadInput) << o.message;
    }
  }
}

TEST(BadMsh, HugeCountsInATinyFile) {
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$Nodes\n1000000000000000000\n1 0 0 0\n$EndNodes\n"), ErrorKind::BadInput,
                   "unexpected end of file in $Nodes: number of nodes 1000000000000000000 needs more than");
  EXPECT_MSH_ERROR(read_bytes(kHeader41 + "$Nodes\n1 1000000000000000000 1 1\n3 1 0 1\n1\n0 0 0\n$EndNodes\n"),
                   ErrorKind::BadInput, "needs more than");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + "$Elements\n999999999999\n" + kOneHex22.substr(12)),
                   ErrorKind::BadInput, "number of elements");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$PhysicalNames\n123456789012\n$EndPhysicalNames\n"), ErrorKind::BadInput,
                   "number of physical names");
  // Binary: a size_t node count of 10^18.
  std::string bin = tiny_binary41(false);
  const std::size_t at = bin.find("$Nodes\n") + 7 + 8;
  const std::uint64_t huge = 1000000000000000000ull;
  bin.replace(at, 8, reinterpret_cast<const char*>(&huge), 8);
  EXPECT_MSH_ERROR(read_bytes(bin), ErrorKind::BadInput, "number of nodes 1000000000000000000");
  // A count that does not fit 64 bits.
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$Nodes\n99999999999999999999999\n$EndNodes\n"), ErrorKind::BadInput,
                   "number of nodes");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$Nodes\n-5\n$EndNodes\n"), ErrorKind::BadInput, "out of range");
}

TEST(BadMsh, DuplicateNodeTag) {
  const std::string nodes = "$Nodes\n3\n1 0 0 0\n7 1 0 0\n7 1 1 0\n$EndNodes\n";
  const Outcome o = read_bytes(kHeader22 + nodes + kOneHex22);
  EXPECT_MSH_ERROR(o, ErrorKind::BadInput, "line 8: $Nodes: node tag 7 appears twice");
}

TEST(BadMsh, DuplicateElementTag) {
  const std::string elements = "$Elements\n2\n4 5 2 1 1 1 2 3 4 5 6 7 8\n4 3 2 1 1 1 2 3 4\n$EndElements\n";
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + elements), ErrorKind::BadInput,
                   "element tag 4 appears twice");
}

TEST(BadMsh, ElementReferencesMissingNode) {
  const std::string elements = "$Elements\n1\n12 5 2 1 1 1 2 3 4 5 6 7 99\n$EndElements\n";
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + elements), ErrorKind::BadInput,
                   "element 12 references node tag 99");
}

TEST(BadMsh, TetrahedraAreListedByTypeAndCount) {
  const std::string elements =
      "$Elements\n4\n"
      "1 4 2 1 1 1 2 3 5\n2 4 2 1 1 2 3 4 7\n3 2 2 1 1 1 2 3\n4 11 2 1 1 1 2 3 4 5 6 7 8 1 2\n"
      "$EndElements\n";
  const Outcome o = read_bytes(kHeader22 + kCubeNodes22 + elements);
  EXPECT_MSH_ERROR(o, ErrorKind::Unsupported, "2 tetrahedron (type 4)");
  EXPECT_THAT(o.message, HasSubstr("1 10-node tetrahedron (type 11)"));
  EXPECT_THAT(o.message, HasSubstr("all-hex (type 5; 17, 12 second order) or all-quad (type 3; 16, 10 second order)"));
  // Lower-dimensional elements are never the reason for a refusal.
  EXPECT_THAT(o.message, testing::Not(HasSubstr("triangle")));
}

TEST(BadMsh, TrianglesInAQuadMesh41) {
  const std::string text = kHeader41 +
                           "$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n$EndNodes\n"
                           "$Elements\n2 3 1 3\n2 1 3 1\n1 1 2 3 4\n2 1 2 2\n2 1 2 3\n3 1 3 4\n$EndElements\n";
  EXPECT_MSH_ERROR(read_bytes(text), ErrorKind::Unsupported, "2 triangle (type 2)");
}

TEST(BadMsh, ThirdOrderHexInBinary41) {
  // Unsupported types in binary are skipped by their known size and listed
  // (second-order hexes are read: tests/geometry/test_second_order.cpp).
  std::string s = tiny_binary41(false);
  const std::size_t block = s.find("$Elements\n") + 10 + 32;
  const std::int32_t type64 = 92;
  s.replace(block + 8, 4, reinterpret_cast<const char*>(&type64), 4);  // element type of the block
  // The block now claims 64 nodes per element: make room for them.
  const std::size_t end = s.find("\n$EndElements");
  s.insert(end, std::string(56 * 8, '\0'));
  EXPECT_MSH_ERROR(read_bytes(s), ErrorKind::Unsupported, "1 64-node hexahedron (type 92)");
}

TEST(BadMsh, NoHexNoQuad) {
  const std::string elements = "$Elements\n2\n1 1 2 1 1 1 2\n2 15 2 1 1 3\n$EndElements\n";
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + elements), ErrorKind::Unsupported, "no hexahedra");
}

TEST(BadMsh, NonFiniteCoordinate) {
  const std::string nodes = "$Nodes\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 nan 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$EndNodes\n";
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + nodes + kOneHex22), ErrorKind::BadInput, "node tag 4");
  EXPECT_THAT(read_bytes(kHeader22 + nodes + kOneHex22).message, HasSubstr("not a finite number"));
  const std::string inf = "$Nodes\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1e999\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$EndNodes\n";
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + inf + kOneHex22), ErrorKind::BadInput, "node tag 5");
  // Binary: a NaN in the first node's x.
  std::string bin = tiny_binary41(false);
  const std::size_t coords = bin.find("$Nodes\n") + 7 + 32 + 20 + 64;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  bin.replace(coords, 8, reinterpret_cast<const char*>(&nan), 8);
  EXPECT_MSH_ERROR(read_bytes(bin), ErrorKind::BadInput, "node tag 1 has a coordinate that is not a finite number");
}

TEST(BadMsh, MissingSections) {
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kOneHex22), ErrorKind::BadInput, "no $Nodes section");
  EXPECT_MSH_ERROR(read_bytes(kHeader22), ErrorKind::BadInput, "no $Nodes section");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22), ErrorKind::BadInput, "no $Elements section");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + kOneHex22 + "$Comments\nno end\n"), ErrorKind::BadInput,
                   "unexpected end of file in $Comments");
}

TEST(BadMsh, GarbageInsideSections) {
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$Nodes\n1\n1 0 zero 0\n$EndNodes\n" + kOneHex22), ErrorKind::BadInput,
                   "line 6: $Nodes: expected coordinate");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + "hello\n" + kOneHex22), ErrorKind::BadInput,
                   "expected a section header");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + "$Nodes\n1\n1 0 0 0 0\n$EndNodes\n"), ErrorKind::BadInput,
                   "expected $EndNodes");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + "$EndNodes\n"), ErrorKind::BadInput,
                   "has no matching opening line");
  EXPECT_MSH_ERROR(read_bytes(kHeader41 + "$Nodes\n1 2 1 2\n0 1 0 1\n1\n0 0 0\n$EndNodes\n"), ErrorKind::BadInput,
                   "the header says 2 nodes but the entity blocks hold 1");
  EXPECT_MSH_ERROR(read_bytes(kHeader41 + "$Nodes\n1 1 1 2\n7 1 0 1\n1\n0 0 0\n$EndNodes\n"), ErrorKind::BadInput,
                   "entity dimension 7 is out of range");
}

TEST(BadMsh, SectionsOutOfPlace) {
  EXPECT_MSH_ERROR(read_bytes("$Comments\nonly a comment\n$EndComments\n"), ErrorKind::BadInput,
                   "not a Gmsh MSH file: no $MeshFormat section");
  EXPECT_MSH_ERROR(read_bytes(kCubeNodes22 + kHeader22 + kOneHex22), ErrorKind::BadInput,
                   "line 1: $Nodes: comes before $MeshFormat");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + kCubeNodes22 + kHeader22 + kOneHex22), ErrorKind::BadInput,
                   "a second $MeshFormat section");
  EXPECT_MSH_ERROR(read_bytes("$Comments\n$EndComments\nhello\n"), ErrorKind::BadInput,
                   "not a Gmsh MSH file: expected a section header such as $MeshFormat, found 'hello'");
  EXPECT_MSH_ERROR(read_bytes("$Comments\nnever closed\n" + kHeader22), ErrorKind::BadInput,
                   "no $EndComments line");
}

// MSH 1: $NOD / $ELM, "tag type reg-phys reg-elem number-of-nodes nodes...".
TEST(BadMsh, Msh1Faults) {
  const std::string nod = "$NOD\n8\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n$ENDNOD\n";
  EXPECT_FALSE(read_bytes(nod + "$ELM\n1\n1 5 1 1 8 1 2 3 4 5 6 7 8\n$ENDELM\n").threw);
  EXPECT_MSH_ERROR(read_bytes(nod), ErrorKind::BadInput, "no $ELM section");
  EXPECT_MSH_ERROR(read_bytes("$ELM\n1\n1 5 1 1 8 1 2 3 4 5 6 7 8\n$ENDELM\n" + nod), ErrorKind::BadInput,
                   "no $NOD section before $ELM");
  EXPECT_MSH_ERROR(read_bytes(nod + "$ELM\n1\n1 5 1 1 7 1 2 3 4 5 6 7\n$ENDELM\n"), ErrorKind::BadInput,
                   "element 1: a hexahedron (type 5) has 8 nodes, the line says 7");
  EXPECT_MSH_ERROR(read_bytes(nod + "$ELM\n1\n1 5 1 1 8 1 2 3 4 5 6 7 8\n$EndElements\n"), ErrorKind::BadInput,
                   "expected $ENDELM");
  EXPECT_MSH_ERROR(read_bytes(nod + "$ELM\n2\n1 5 1 1 8 1 2 3 4 5 6 7 8\n2 4 1 1 4 1 2 3 5\n$ENDELM\n"),
                   ErrorKind::Unsupported, "1 tetrahedron (type 4)");
  EXPECT_MSH_ERROR(read_bytes(nod + kHeader22 + kOneHex22), ErrorKind::BadInput, "$MeshFormat in an MSH 1 file");
  EXPECT_MSH_ERROR(read_bytes(kHeader22 + nod), ErrorKind::BadInput, "an MSH 1 section in an MSH 2 file");
  EXPECT_MSH_ERROR(read_bytes(nod + kCubeNodes22), ErrorKind::BadInput, "an MSH 2/4 section in an MSH 1 file");
  EXPECT_MSH_ERROR(read_bytes("$NOD\n99999999\n1 0 0 0\n$ENDNOD\n"), ErrorKind::BadInput, "needs more than");
}
