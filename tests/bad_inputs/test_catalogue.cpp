// The bad-input catalogue: every case runs the real `dicer` binary on a
// hostile file or argument and checks (1) the documented exit code, (2) one
// line on stderr naming the file (for file cases) and what is wrong, and
// (3) that no output file, not even a temporary, is left behind.
// Fixtures are made by the test from small texts or by editing real files.
#include <exodusII.h>
#include <netcdf.h>
#include <sys/stat.h>
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>

#include "lz4_filter.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace dicer;

namespace {

// Two unit hexes side by side, MSH 2.2 ASCII; the cases edit this text.
const std::string kNodes =
    "$Nodes\n12\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n"
    "9 2 0 0\n10 2 1 0\n11 2 0 1\n12 2 1 1\n$EndNodes\n";
const std::string kHeader = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
const std::string kHex1 = "1 5 2 1 1 1 2 3 4 5 6 7 8\n", kHex2 = "2 5 2 1 1 2 9 10 3 6 11 12 7\n";
std::string msh(const std::string& nodes, const std::string& elements, int count) {
  return kHeader + nodes + "$Elements\n" + std::to_string(count) + "\n" + elements + "$EndElements\n";
}
const std::string kGood = msh(kNodes, kHex1 + kHex2, 2);
std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto p = s.find(a);
  if (p != std::string::npos) s.replace(p, a.size(), b);
  return s;
}

struct Case {
  const char* name;
  // Makes the fixture in dir (if any) and returns the command line; "OUT"
  // stands for the output path, "IN" for the fixture.
  std::function<std::string(const test::TempDir&)> fixture;
  std::vector<std::string> args;
  int exit_code;
  const char* says;
};

std::string text_file(const test::TempDir& d, const std::string& name, const std::string& bytes) {
  test::write_file(d.path(name), bytes);
  return d.path(name);
}

// A store to damage, made once per test process.
const std::string& good_store() { return test::diced_store("cardinal_sphere.e", 2); }

std::string edited_store(const test::TempDir& d, const std::function<void(hid_t)>& edit) {
  return test::edited_copy(good_store(), d.path("bad.dice.h5"), edit);
}

// The two hexes as HEX20 (MSH type 17): nodes 1..12 the corners, then one
// node per edge at its midpoint, in Gmsh's order (nodes 8..19 of an element
// on its local corner pairs below, Gmsh's documentation). The cases edit
// `nodes` (tag = index + 1) and `elements` before formatting.
struct Hex20Pair {
  std::vector<std::array<double, 3>> nodes;
  std::vector<std::vector<int>> elements;  // 20 tags each
  std::string text() const {
    std::ostringstream s;
    s.precision(17);
    s << kHeader << "$Nodes\n" << nodes.size() << "\n";
    for (size_t i = 0; i < nodes.size(); ++i) s << i + 1 << " " << nodes[i][0] << " " << nodes[i][1] << " " << nodes[i][2] << "\n";
    s << "$EndNodes\n$Elements\n" << elements.size() << "\n";
    for (size_t e = 0; e < elements.size(); ++e) {
      s << e + 1 << " 17 2 1 1";
      for (int t : elements[e]) s << " " << t;
      s << "\n";
    }
    s << "$EndElements\n";
    return s.str();
  }
};
Hex20Pair hex20_pair() {
  static const int kGmshEdges[12][2] = {{0, 1}, {0, 3}, {0, 4}, {1, 2}, {1, 5}, {2, 3},
                                        {2, 6}, {3, 7}, {4, 5}, {4, 7}, {5, 6}, {6, 7}};
  Hex20Pair p;
  p.nodes = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1},
             {1, 1, 1}, {0, 1, 1}, {2, 0, 0}, {2, 1, 0}, {2, 0, 1}, {2, 1, 1}};
  std::map<std::pair<int, int>, int> mid;
  for (const std::vector<int>& corners : {std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8}, {2, 9, 10, 3, 6, 11, 12, 7}}) {
    std::vector<int> e = corners;
    for (const auto& pair : kGmshEdges) {
      const int a = corners[pair[0]], b = corners[pair[1]];
      auto [it, fresh] = mid.emplace(std::minmax(a, b), static_cast<int>(p.nodes.size()) + 1);
      if (fresh) {
        const auto &pa = p.nodes[a - 1], &pb = p.nodes[b - 1];
        p.nodes.push_back({0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])});
      }
      e.push_back(it->second);
    }
    p.elements.push_back(e);
  }
  return p;
}

// An Exodus file with one block of `type` and `nodes_per` nodes per element.
std::string exodus_block(const test::TempDir& d, const char* type, int nodes_per) {
  const std::string p = d.path("bad.exo");
  int cpu = 8, io = 8;
  const int id = ex_create(p.c_str(), EX_CLOBBER, &cpu, &io);
  const int nn = nodes_per;
  ex_put_init(id, "bad", 3, nn, 1, 1, 0, 0);
  std::vector<double> x(nn), y(nn), z(nn);
  for (int i = 0; i < nn; ++i) x[i] = i, y[i] = i % 2, z[i] = i % 3;
  ex_put_coord(id, x.data(), y.data(), z.data());
  ex_put_block(id, EX_ELEM_BLOCK, 1, type, 1, nodes_per, 0, 0, 0);
  std::vector<int> conn(nodes_per);
  for (int i = 0; i < nodes_per; ++i) conn[i] = i + 1;
  ex_put_conn(id, EX_ELEM_BLOCK, 1, conn.data(), nullptr, nullptr);
  ex_close(id);
  return p;
}

std::vector<Case> catalogue() {
  const std::string M = "dice", I = "--interval";
  auto mesh_case = [&](const char* name, std::function<std::string(const test::TempDir&)> fx, int code, const char* says) {
    return Case{name, std::move(fx), {M, "IN", I, "2", "-o", "OUT"}, code, says};
  };
  auto text = [](const char* file, std::string bytes) {
    return [file, bytes](const test::TempDir& d) { return text_file(d, file, bytes); };
  };
  const std::string sphere = test::data_path("cardinal_sphere.e");
  auto real = [sphere](const test::TempDir&) { return sphere; };
  std::vector<Case> c = {
      // ---- MSH
      mesh_case("msh truncated in $Nodes", text("a.msh", kGood.substr(0, kGood.find("9 2 0 0"))), 3, "end of file"),
      mesh_case("msh version 3.0", text("a.msh", replace(kGood, "2.2 0 8", "3.0 0 8")), 4, "3.0"),
      mesh_case("msh version 4.0", text("a.msh", replace(kGood, "2.2 0 8", "4 0 8")), 4, "4"),
      mesh_case("msh binary with data size 4", text("a.msh", replace(kGood, "2.2 0 8", "2.2 1 4")), 3, "size"),
      mesh_case("msh binary with a bad endianness marker", text("a.msh", replace(kGood, "2.2 0 8\n", "2.2 1 8\nXXXX\n")), 3,
                "a.msh"),
      mesh_case("msh element references a missing node", text("a.msh", msh(kNodes, kHex1 + replace(kHex2, " 9 ", " 99 "), 2)),
                3, "99"),
      mesh_case("msh node tag out of range", text("a.msh", replace(kGood, "12 2 1 1\n$EndNodes", "-12 2 1 1\n$EndNodes")), 3,
                "a.msh"),
      mesh_case("msh tetrahedra", text("a.msh", msh(kNodes, kHex1 + "2 4 2 1 1 9 10 11 12\n", 2)), 4, "tetrahedr"),
      mesh_case("msh triangles in a quad mesh", text("a.msh", msh(kNodes, "1 3 2 1 1 1 2 3 4\n2 2 2 1 1 9 10 11\n", 2)), 4,
                "triangle"),
      mesh_case("msh duplicated element", text("a.msh", msh(kNodes, kHex1 + replace(kHex1, "1 5", "2 5"), 2)), 3,
                "duplicates"),
      mesh_case("msh duplicated element tag", text("a.msh", msh(kNodes, kHex1 + replace(kHex2, "2 5 2", "1 5 2"), 2)), 3,
                "element tag 1"),
      mesh_case("msh NaN coordinate", text("a.msh", replace(kGood, "7 1 1 1", "7 nan 1 1")), 3, "7"),
      mesh_case("msh Inf coordinate", text("a.msh", replace(kGood, "7 1 1 1", "7 1 inf 1")), 3, "7"),
      mesh_case("msh huge node count", text("a.msh", replace(kGood, "$Nodes\n12\n", "$Nodes\n999999999999\n")), 3, "a.msh"),
      mesh_case("msh empty file", text("a.msh", ""), 3, "empty"),
      mesh_case("msh garbage", text("a.msh", "hello world\n"), 3, "not an Exodus II (netCDF) or Gmsh MSH file"),
      mesh_case("msh without $Nodes", text("a.msh", kHeader + "$Elements\n1\n" + kHex1 + "$EndElements\n"), 3, "$Nodes"),
      mesh_case("msh mixed handedness",
                text("a.msh", msh(kNodes, kHex1 + "2 5 2 1 1 2 3 10 9 6 7 12 11\n", 2)), 3, "mixed handedness"),
      mesh_case("msh tangled hex", text("a.msh", msh(replace(kNodes, "7 1 1 1", "7 -0.5 -0.5 1"), kHex1, 1)), 3,
                "inverted or degenerate"),
      mesh_case("msh degenerate hex", text("a.msh", msh(kNodes, "1 5 2 1 1 1 2 3 3 5 6 7 8\n", 1)), 3, "appears twice"),
      // A third hex (inside the first, right-handed) on the face x = 1 that the first two share.
      mesh_case("msh non-manifold face",
                text("a.msh", msh(replace(replace(kNodes, "$Nodes\n12\n", "$Nodes\n16\n"), "$EndNodes",
                                          "13 0.5 0 0\n14 0.5 1 0\n15 0.5 0 1\n16 0.5 1 1\n$EndNodes"),
                                  kHex1 + kHex2 + "3 5 2 1 1 13 2 3 14 15 6 7 16\n", 3)),
                3, "non-manifold face"),
      // ---- second order (HEX20): mid nodes are checked like corners
      mesh_case("msh HEX20 mid node missing",
                [](const test::TempDir& d) {
                  Hex20Pair p = hex20_pair();
                  p.elements[1][13] = 99;
                  return text_file(d, "a.msh", p.text());
                },
                3, "element 2 references node tag 99, which is not in $Nodes"),
      mesh_case("msh HEX20 mid node not finite",
                [](const test::TempDir& d) {
                  Hex20Pair p = hex20_pair();
                  p.nodes[p.elements[1][19] - 1][1] = std::nan("");
                  return text_file(d, "a.msh", p.text());
                },
                3, "not a finite number"),
      mesh_case("msh HEX20 mid node that is a corner",
                [](const test::TempDir& d) {
                  Hex20Pair p = hex20_pair();
                  p.elements[1][19] = 1;
                  return text_file(d, "a.msh", p.text());
                },
                3, "node 1 is a corner of element 1 and a mid node of element 2"),
      mesh_case("msh HEX20 pair disagreeing on a shared edge's mid node",
                [](const test::TempDir& d) {
                  Hex20Pair p = hex20_pair();
                  // Element 2's local edge 0-3 (Gmsh node 9) is the shared edge 2-3.
                  p.nodes.push_back({1.05, 0.5, 0});
                  p.elements[1][9] = static_cast<int>(p.nodes.size());
                  return text_file(d, "a.msh", p.text());
                },
                3, "disagree on the mid node of their common edge"),
      mesh_case("msh HEX20 mid node that inverts fine elements",
                [](const test::TempDir& d) {
                  Hex20Pair p = hex20_pair();
                  p.nodes[p.elements[1][18] - 1][0] = 0.6;  // element 2's edge 5-6, at x = 2, bent to x = 0.6
                  return text_file(d, "a.msh", p.text());
                },
                7, "the second-order geometry of element 2 (block 1) would invert"),
      mesh_case("exodus HEX20 mid node out of range",
                [](const test::TempDir& d) {
                  const std::string path = d.path("bad.exo");
                  const Hex20Pair p = hex20_pair();
                  static const int kGmshToExodus[12] = {8, 11, 12, 9, 13, 10, 14, 15, 16, 19, 17, 18};
                  int cpu = 8, io = 8;
                  const int id = ex_create(path.c_str(), EX_CLOBBER, &cpu, &io);
                  const int nn = static_cast<int>(p.nodes.size());
                  ex_put_init(id, "bad", 3, nn, 2, 1, 0, 0);
                  std::vector<double> x, y, z;
                  for (const auto& n : p.nodes) x.push_back(n[0]), y.push_back(n[1]), z.push_back(n[2]);
                  ex_put_coord(id, x.data(), y.data(), z.data());
                  ex_put_block(id, EX_ELEM_BLOCK, 1, "HEX20", 2, 20, 0, 0, 0);
                  std::vector<int> conn;
                  for (const auto& e : p.elements) {
                    std::vector<int> ex(e.begin(), e.begin() + 8);
                    ex.resize(20);
                    for (int k = 0; k < 12; ++k) ex[kGmshToExodus[k]] = e[8 + k];
                    conn.insert(conn.end(), ex.begin(), ex.end());
                  }
                  conn[20 + 17] = 999;
                  ex_put_conn(id, EX_ELEM_BLOCK, 1, conn.data(), nullptr, nullptr);
                  ex_close(id);
                  return path;
                },
                3, "element block 1: element 2 references node 999"),
      // ---- Exodus
      mesh_case("exodus truncated",
                [](const test::TempDir& d) {
                  const std::string b = test::read_file(test::data_path("cardinal_sphere.e"));
                  return text_file(d, "cut.e", b.substr(0, b.size() / 2));
                },
                3, "cut.e"),
      mesh_case("exodus corrupt netCDF", text("bad.e", std::string("CDF\x01", 4) + std::string(200, '\x7f')), 3, "bad.e"),
      mesh_case("exodus tetra block", [](const test::TempDir& d) { return exodus_block(d, "TETRA4", 4); }, 4, "TETRA"),
      mesh_case("exodus HEX block with 64 nodes", [](const test::TempDir& d) { return exodus_block(d, "HEX", 64); }, 4,
                "64"),
      mesh_case("missing input file", [](const test::TempDir& d) { return d.path("nope.exo"); }, 5, "nope.exo"),
      // ---- the store
      Case{"store that is not HDF5", text("x.dice.h5", "not a store"), {"info", "IN"}, 3, "not an HDF5 file"},
      Case{"store of an unknown version",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               hid_t a = H5Aopen(f, "format_version", H5P_DEFAULT);
               const long long v = 99;
               H5Awrite(a, H5T_NATIVE_LLONG, &v);
               H5Aclose(a);
             });
           },
           {"info", "IN"}, 4, "version 99"},
      Case{"store with a missing dataset",
           [](const test::TempDir& d) { return edited_store(d, [](hid_t f) { H5Ldelete(f, "topology/edges", H5P_DEFAULT); }); },
           {"query", "IN", "--node", "0"}, 8, "topology/edges is missing"},
      Case{"store truncated",
           [](const test::TempDir& d) {
             const std::string b = test::read_file(good_store());
             return text_file(d, "cut.dice.h5", b.substr(0, b.size() / 3));
           },
           {"verify", "IN"}, 8, "cut.dice.h5"},
      Case{"store with a flipped byte in a page",
           [](const test::TempDir& d) {
             haddr_t addr = 0;
             hsize_t size = 0;
             const std::string p = edited_store(d, [&](hid_t f) {
               hid_t ds = H5Dopen2(f, "topology/elements", H5P_DEFAULT);
               hsize_t off[2] = {0, 0};
               unsigned mask = 0;
               H5Dget_chunk_info_by_coord(ds, off, &mask, &addr, &size);
               H5Dclose(ds);
             });
             std::string b = test::read_file(p);
             b[addr + size / 3] ^= 1;
             test::write_file(p, b);
             return p;
           },
           {"query", "IN", "--element", "5"}, 8, "topology/elements page 0"},
      Case{"store page whose size field lies",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               hid_t ds = H5Dopen2(f, "topology/elements", H5P_DEFAULT);
               hsize_t off[2] = {0, 0}, stored = 0;
               H5Dget_chunk_storage_size(ds, off, &stored);
               std::vector<std::uint8_t> raw(stored);
               std::uint32_t mask = 0;
               H5Dread_chunk(ds, H5P_DEFAULT, off, &mask, raw.data());
               raw[7] ^= 0x10;  // the original-size field (8 bytes, big-endian)
               const std::uint32_t sum = store::fletcher32(raw.data(), raw.size() - 4);  // a valid checksum of the lie
               for (int k = 0; k < 4; ++k) raw[raw.size() - 4 + k] = static_cast<std::uint8_t>(sum >> (8 * k));
               H5Dwrite_chunk(ds, H5P_DEFAULT, 0, off, raw.size(), raw.data());
               H5Dclose(ds);
             });
           },
           {"query", "IN", "--element", "5"}, 8, "topology/elements page 0"},
      Case{"store row with a lying interval (valid checksums)",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               hid_t ds = H5Dopen2(f, "topology/elements", H5P_DEFAULT);
               hid_t sp = H5Dget_space(ds);
               hsize_t dims[2] = {0, 0};
               H5Sget_simple_extent_dims(sp, dims, nullptr);
               H5Sclose(sp), H5Dclose(ds);
               // Element 5's first interval (column W-7, before the grading's four) claims 2^41;
               // Fletcher32 and CRC-32 recomputed.
               test::forge_page(f, "topology/elements", 0, [&](std::vector<std::uint8_t>& page) {
                 reinterpret_cast<std::int64_t*>(page.data())[5 * dims[1] + dims[1] - 7] = std::int64_t{1} << 41;
               }, true);
             });
           },
           {"query", "IN", "--element", "40"}, 8, "topology/elements row 5: interval 2199023255552 out of range"},
      Case{"store page with the Fletcher32 blind spot (0x0000 -> 0xFFFF)",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               // A zero 16-bit word turned into 0xFFFF keeps Fletcher32 valid; only the CRC-32 sees it.
               // (element corner coordinates: what a node query reads)
               test::forge_page(f, "topology/element_corners", 0, [](std::vector<std::uint8_t>& page) {
                 for (size_t i = 0; i + 1 < page.size(); i += 2)
                   if (page[i] == 0 && page[i + 1] == 0) {
                     page[i] = page[i + 1] = 0xff;
                     return;
                   }
               }, false);
             });
           },
           {"query", "IN", "--node", "0"}, 8, "topology/element_corners page 0: page checksum (CRC-32) mismatch"},
      Case{"HDF5 file that is not a dicer store",
           [](const test::TempDir& d) {
             const std::string p = d.path("other.h5");
             H5Fclose(H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT));
             return p;
           },
           {"info", "IN"}, 3, "not a dicer store"},
      // ---- arguments
      Case{"unknown flag", real, {"dice", "IN", "--frobnicate", "-o", "OUT"}, 2, "unknown option --frobnicate"},
      Case{"unknown command", real, {"frobnicate"}, 2, "unknown command"},
      Case{"interval 0", real, {"dice", "IN", "--interval", "0", "-o", "OUT"}, 2, ">= 1"},
      Case{"negative interval", real, {"dice", "IN", "--interval", "-3", "-o", "OUT"}, 2, ">= 1"},
      Case{"interval beyond 64 bits", real, {"dice", "IN", "--interval", "123456789012345678901", "-o", "OUT"}, 2,
           "does not fit in 64 bits"},
      Case{"more grid points in a coarse element than any reader takes", real,
           {"dice", "IN", "--interval", "10321", "-o", "OUT"}, 6, "more than 2^40 grid points in one coarse element"},
      Case{"negative size", real, {"dice", "IN", "--size", "-1", "-o", "OUT"}, 2, "--size"},
      Case{"unknown block", real, {"dice", "IN", "--block-interval", "inlet=3", "-o", "OUT"}, 2, "inlet"},
      Case{"unknown sheet", real, {"dice", "IN", "--sheet-interval", "999=3", "-o", "OUT"}, 2, "no sheet 999"},
      Case{"malformed intervals file", text("plan.json", "{\"global\": "), {"dice", sphere, "--intervals-file", "IN", "-o", "OUT"},
           2, "not valid JSON"},
      Case{"unknown key in intervals file", text("plan.json", "{\"globall\": 3}"),
           {"dice", sphere, "--intervals-file", "IN", "-o", "OUT"}, 2, "globall"},
      Case{"missing -o", real, {"dice", "IN", "--interval", "2"}, 2, "missing -o"},
      Case{"malformed box", [](const test::TempDir&) { return good_store(); },
           {"export", "IN", "--format", "msh", "--box", "0,0,0,1,1", "-o", "OUT"}, 2, "six numbers"},
      Case{"inverted box", [](const test::TempDir&) { return good_store(); },
           {"export", "IN", "--format", "msh", "--box", "1,0,0,0,1,1", "-o", "OUT"}, 2, "lower corner above upper"},
      Case{"chunk k >= K", [](const test::TempDir&) { return good_store(); },
           {"export", "IN", "--format", "exodus", "--chunk", "4/4", "-o", "OUT"}, 2, "0 <= K < N"},
      Case{"chunk of zero", [](const test::TempDir&) { return good_store(); },
           {"export", "IN", "--format", "exodus", "--chunk", "0/0", "-o", "OUT"}, 2, "0 <= K < N"},
      Case{"unknown export format", [](const test::TempDir&) { return good_store(); },
           {"export", "IN", "--format", "stl", "-o", "OUT"}, 2, "stl"},
      Case{"cache budget 0", [](const test::TempDir&) { return good_store(); }, {"info", "IN", "--cache-mb", "0"}, 2,
           "--cache-mb"},
      Case{"node id out of range", [](const test::TempDir&) { return good_store(); },
           {"query", "IN", "--node", "123456789"}, 2, "out of range"},
      // ---- one per class of the hostile-input campaign (issue 18); the
      // dedicated suites (test_hostile_store, test_bad_exodus,
      // test_file_faults, test_bad_readers) hold the variants.
      Case{"store attribute holding 1000 values",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               const hsize_t n = 1000;
               std::vector<std::int64_t> v(n, 7);
               H5Adelete(f, "format_version");
               const hid_t sp = H5Screate_simple(1, &n, nullptr);
               const hid_t a = H5Acreate2(f, "format_version", H5T_NATIVE_INT64, sp, H5P_DEFAULT, H5P_DEFAULT);
               H5Awrite(a, H5T_NATIVE_INT64, v.data());
               H5Aclose(a), H5Sclose(sp);
             });
           },
           {"info", "IN"}, 8, "exactly one value"},
      Case{"store count attribute that its tables contradict",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               const hid_t a = H5Aopen(f, "fine_elements", H5P_DEFAULT);
               std::int64_t v = 0;
               H5Aread(a, H5T_NATIVE_INT64, &v);
               ++v;
               H5Awrite(a, H5T_NATIVE_INT64, &v);
               H5Aclose(a);
             });
           },
           {"info", "IN"}, 8, "fine_elements"},
      Case{"store whose source order is neither 1 nor 2",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               const hid_t a = H5Aopen(f, "source_order", H5P_DEFAULT);
               const std::int64_t v = 3;
               H5Awrite(a, H5T_NATIVE_INT64, &v);
               H5Aclose(a);
             });
           },
           {"info", "IN"}, 8, "source_order is 3"},
      Case{"store table replaced by a link to another file",
           [](const test::TempDir& d) {
             return edited_store(d, [](hid_t f) {
               H5Ldelete(f, "sheets/sheet_interval", H5P_DEFAULT);
               H5Lcreate_external("elsewhere.h5", "/x", f, "sheets/sheet_interval", H5P_DEFAULT, H5P_DEFAULT);
             });
           },
           {"info", "IN"}, 8, "external link"},
      mesh_case("exodus elem_type longer than the Exodus library's buffer",
                [](const test::TempDir& d) {
                  const std::string p = exodus_block(d, "HEX8", 8);
                  int ncid = -1, var = -1;
                  nc_open(p.c_str(), NC_WRITE, &ncid);
                  nc_redef(ncid);
                  nc_inq_varid(ncid, "connect1", &var);
                  const std::string type = "HEX8" + std::string(496, 'X');
                  nc_put_att_text(ncid, var, "elem_type", type.size(), type.data());
                  nc_close(ncid);
                  return p;
                },
                3, "elem_type attribute is 500 characters"),
      Case{"export onto its own store",
           [](const test::TempDir& d) {
             fs::copy_file(good_store(), d.path("s.dice.h5"));
             return d.path("s.dice.h5");
           },
           {"export", "IN", "--format", "msh", "-o", "IN"}, 2, "is the same file as"},
      Case{"output that is an existing directory",
           [](const test::TempDir& d) {
             fs::create_directory(d.path("out.dice.h5"));
             return d.path("out.dice.h5");
           },
           {"dice", sphere, "--interval", "2", "-o", "IN"}, 2, "is a directory"},
      mesh_case("FIFO given as the mesh",
                [](const test::TempDir& d) {
                  ::mkfifo(d.path("pipe.msh").c_str(), 0600);
                  return d.path("pipe.msh");
                },
                2, "is a FIFO (named pipe), not a regular file"),
  };
  return c;
}

class Catalogue : public ::testing::TestWithParam<size_t> {};

}  // namespace

TEST_P(Catalogue, RefusedClearlyWithNothingLeftBehind) {
  const Case c = catalogue()[GetParam()];
  test::TempDir d;
  const std::string in = c.fixture(d);
  test::TempDir outdir;
  const std::string out = outdir.path("result.out");
  std::vector<std::string> args;
  for (const auto& a : c.args) args.push_back(a == "IN" ? in : a == "OUT" ? out : a);
  const auto r = test::run_cli(args);
  SCOPED_TRACE(c.name);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "one line: " << r.err;
  EXPECT_NE(r.err.find("error"), std::string::npos) << r.err;
  const bool file_case = std::find(c.args.begin(), c.args.end(), "IN") != c.args.end() && in != good_store() &&
                         in.find("/tests/data/") == std::string::npos;
  if (file_case && c.exit_code != 2 && c.exit_code != 6) {
    EXPECT_NE(r.err.find(fs::path(in).filename().string()), std::string::npos) << "names the file: " << r.err;
  }
  EXPECT_TRUE(fs::is_empty(outdir.dir())) << "nothing may be left in the output folder";
}

INSTANTIATE_TEST_SUITE_P(BadInputs, Catalogue, ::testing::Range<size_t>(0, catalogue().size()),
                         [](const ::testing::TestParamInfo<size_t>& i) {
                           std::string s = catalogue()[i.param].name;
                           for (char& ch : s)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return s;
                         });

// The HEX20 fixture the second-order cases break is itself fine.
TEST(CatalogueFixtures, Hex20PairDices) {
  test::TempDir d;
  test::write_file(d.path("ok.msh"), hex20_pair().text());
  const auto r = test::run_cli({"dice", d.path("ok.msh"), "--interval", "2", "-o", d.path("ok.dice.h5")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("second order"), std::string::npos) << r.out;
}

TEST(CatalogueSize, HasAtLeastFortyCases) { EXPECT_GE(catalogue().size(), 40u); }
