// Dicing straight to a store (DicedRows: each table's rows made as its
// pages are written) against the tables compiled in memory first
// (FineMesh::dice): the same store, object by object, chunk by chunk (the
// stored bytes, so compression and checksums too) and attribute by
// attribute, but the uuid every store gets anew. The expected store is the
// one every other test checks against independent values; this test
// checks that the streamed one is it.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <map>
#include <random>
#include <string>
#include <vector>

#include "dicer/diced_rows.hpp"
#include "dicer/error.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

using Contents = std::map<std::string, std::string>;

herr_t attribute(hid_t loc, const char* name, const H5A_info_t*, void* data) {
  auto& out = *static_cast<std::pair<std::string, Contents*>*>(data);
  if (out.first == "." && std::string(name) == "uuid") return 0;  // new in every store
  const hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a);
  std::string bytes(H5Aget_storage_size(a), '\0');
  const herr_t st = H5Aread(a, type, bytes.data());
  H5Tclose(type), H5Aclose(a);
  if (st < 0) return -1;
  (*out.second)[out.first + "@" + name] = bytes;
  return 0;
}

herr_t object(hid_t file, const char* name, const H5O_info_t* info, void* data) {
  auto& out = *static_cast<Contents*>(data);
  const hid_t o = H5Oopen(file, name, H5P_DEFAULT);
  std::pair<std::string, Contents*> where{name, &out};
  if (H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, nullptr, attribute, &where) < 0) return H5Oclose(o), -1;
  std::string& v = out[name];
  v = info->type == H5O_TYPE_DATASET ? "dataset" : "group";
  if (info->type == H5O_TYPE_DATASET) {
    const hid_t space = H5Dget_space(o), type = H5Dget_type(o);
    hsize_t dims[2] = {0, 0};
    const int rank = H5Sget_simple_extent_dims(space, dims, nullptr);
    v += " rank " + std::to_string(rank) + " dims " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) +
         " type size " + std::to_string(H5Tget_size(type)) + " class " + std::to_string(H5Tget_class(type));
    hsize_t chunks = 0;
    H5Dget_num_chunks(o, space, &chunks);
    for (hsize_t c = 0; c < chunks; ++c) {
      hsize_t offset[2] = {0, 0}, size = 0;
      unsigned mask = 0;
      haddr_t addr = 0;
      H5Dget_chunk_info(o, space, c, offset, &mask, &addr, &size);
      std::string raw(size, '\0');
      std::uint32_t filters = 0;
      H5Dread_chunk(o, H5P_DEFAULT, offset, &filters, raw.data());
      out[std::string(name) + " chunk at " + std::to_string(offset[0])] = raw;
    }
    H5Tclose(type), H5Sclose(space);
  }
  H5Oclose(o);
  return 0;
}

Contents contents(const std::string& path) {
  Contents out;
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(f, 0) << path;
  if (f < 0) return out;
  EXPECT_GE(H5Ovisit2(f, H5_INDEX_NAME, H5_ITER_INC, object, &out, H5O_INFO_BASIC), 0) << path;
  H5Fclose(f);
  return out;
}

// Dices `mesh` both ways and compares the stores; returns how many entries
// (objects, chunks, attributes) were compared.
size_t expect_same_store(const CoarseMesh& mesh, const IntervalRequest& request, const std::string& what) {
  test::TempDir d;
  const std::string compiled = d.path("compiled.dice.h5"), streamed = d.path("streamed.dice.h5");
  std::vector<std::string> notes_compiled, notes_streamed;
  write_store(FineMesh::dice(mesh, request, &notes_compiled), compiled);
  const DicedRows rows(mesh, request, &notes_streamed);
  write_store(rows, streamed);
  EXPECT_EQ(notes_compiled, notes_streamed) << what;
  const Contents a = contents(compiled), b = contents(streamed);
  EXPECT_EQ(a.size(), b.size()) << what;
  size_t differing = 0;
  for (const auto& [name, bytes] : a) {
    const auto it = b.find(name);
    if (it == b.end()) {
      ADD_FAILURE() << what << ": the streamed store has no " << name;
    } else if (it->second != bytes && ++differing <= 5) {
      ADD_FAILURE() << what << ": " << name << " differs";
    }
  }
  EXPECT_EQ(differing, 0u) << what;
  // The info the CLI prints comes from the rows before anything is read back.
  const FineMesh back = read_store(streamed);
  EXPECT_EQ(rows.info().nodes, back.num_nodes()) << what;
  EXPECT_EQ(rows.info().elements, back.num_elements()) << what;
  EXPECT_EQ(rows.info().block_fine_elements, back.info().block_fine_elements) << what;
  return a.size();
}

TEST(DicedRows, RandomBoxesGiveTheCompiledStore) {
  std::mt19937_64 rng(20261129);
  for (int round = 0; round < 6; ++round) {
    test::BoxSpec spec;
    spec.a = 1 + static_cast<int>(rng() % 4), spec.b = 1 + static_cast<int>(rng() % 3), spec.c = 1 + static_cast<int>(rng() % 3);
    spec.blocks = 1 + static_cast<int>(rng() % 3);
    const CoarseMesh m = test::random_box(spec, rng);
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    IntervalRequest req;
    for (Id q = 0; q < s.num_sheets(); ++q) {
      req.sheets.emplace_back(q, 1 + static_cast<Id>(rng() % 5));
      if (rng() % 3 == 0) continue;
      BiasRequest b;
      b.kind = rng() % 2 ? tfi::Spacing::Dual : tfi::Spacing::Geometric;
      b.ratio = 0.6 + 0.1 * static_cast<double>(rng() % 12);
      req.sheet_bias.emplace_back(q, b);
    }
    // Graded sheets: gradings in the edge and element rows and the sheets'
    // table. (These boxes fit on one page per table; the real meshes below
    // have many.)
    EXPECT_GT(expect_same_store(m, req, "box " + std::to_string(round)), 60u);
  }
}

TEST(DicedRows, AQuadSheetGivesTheCompiledStore) {
  std::mt19937_64 rng(7);
  IntervalRequest req;
  req.global = 3;
  expect_same_store(test::random_quad_sheet(5, 4, true, rng), req, "quad sheet");
}

// Tables of many pages, blocks, side and node sets from a real file.
TEST(DicedRows, RealMeshesWithSetsGiveTheCompiledStore) {
  for (const char* name : {"cardinal_pincell.e", "vtkdata_disk_out_ref.ex2", "libmesh_cylinder_shell.exo"}) {
    const CoarseMesh m = read_coarse_mesh(test::data_path(name));
    IntervalRequest req;
    req.global = 2;
    // Tables of many pages (pincell: 5,310 element rows, 126 a page).
    const size_t entries = expect_same_store(m, req, name);
    EXPECT_GT(entries, 80u) << name;
  }
}

}  // namespace
