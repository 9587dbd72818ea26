// dicer transfer: nesting of two stores, and the prolongation between them.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <optional>

#include "command.hpp"
#include "common.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "dicer/transfer.hpp"
#include "exit_codes.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "transfer", "transfer COARSE FINE (--check | -o FILE [--format hdf5|petsc]) [--json] [store options]",
    R"(COARSE and FINE are two dicings of one coarse mesh (COARSE may be the
mesh file itself: it is then diced at interval 1 in memory). They are
nested when every sheet's interval in FINE is a multiple of its interval in
COARSE; then every FINE node lies in a COARSE cell at a known position, and
the prolongation P (fine nodes x coarse nodes, both in id order; for a
mesh file, its corner nodes in increasing file node id: a second-order
file's mid nodes and nodes no element uses are not columns, so for a
linear file whose nodes are all used and numbered 1..N (Exodus without a
node map, MSH tags 1..N) node i is column i-1) gives it
the trilinear (bilinear for quads) weights of that cell's corners: at most
8 (4) non-zeros per row, a unit row where the nodes coincide. Graded
sheets (--sheet-bias) are not nested: P's weights assume equal spacing.

"One coarse mesh" is checked on content, not on names: the corner
coordinates bit for bit, the topology, orientation, sheets, blocks and CAD
owners must all agree (a reordered copy of the same mesh is refused, exit 3).

--check says whether the two are nested (exit 0) or names the first sheet
that is not (exit 1); for stores diced onto a CAD it also compares every
moved COARSE node with its FINE twin (exit 1 when one differs). -o FILE of
two stores that are not nested has no P to write: exit 3, naming the sheet.

-o FILE writes P, streaming the rows in id order (memory stays bounded
whatever the size): --format hdf5 (the default, and for any other name
than .bin or .petsc) is CSR in HDF5, datasets indptr, indices, data and
attribute shape, which scipy reads as csr_matrix((data, indices, indptr),
shape); --format petsc (the default for FILE.bin and FILE.petsc) is
PETSc's binary matrix format for MatLoad (32-bit indices unless
--petsc-int 64).
The file appears under FILE only when complete.
)",
    R"(dicer transfer sphere2.dice.h5 sphere4.dice.h5 --check
dicer transfer sphere.e sphere4.dice.h5 --check --json
dicer transfer sphere2.dice.h5 sphere4.dice.h5 -o P.h5
dicer transfer sphere2.dice.h5 sphere4.dice.h5 --format petsc -o P.bin
)"};

namespace {

// A store, or a mesh file diced at interval 1 here (the coarse mesh itself).
FineMesh open_level(const std::string& path, const StoreOptions& options) {
  char sig[8] = {};
  std::ifstream(path, std::ios::binary).read(sig, sizeof sig);
  if (std::string(sig, sizeof sig) == std::string("\x89HDF\r\n\x1a\n", 8)) return read_store(path, options);
  IntervalRequest one;
  one.global = 1;
  CoarseMesh c = read_coarse_mesh(path);
  // What the reader dropped (nodes no element uses) is not among P's columns.
  for (const auto& w : c.warnings)
    std::fprintf(stderr, "dicer transfer: warning: %s: %s\n", printable(path).c_str(), printable(w).c_str());
  if (c.second_order())
    std::fprintf(stderr, "dicer transfer: note: %s is second order: P's columns are its %lld corner nodes, not its mid nodes\n",
                 printable(path).c_str(), static_cast<long long>(c.num_vertices()));
  FineMesh m = FineMesh::dice(std::move(c), one);
  m.set_origin(path);
  return m;
}

// P's columns for a mesh file: its corner nodes (the vertices elements
// use) in increasing file node id (Exodus: the node map's ids; MSH: the
// tags), so that a linear file numbered 1..N has node i at column i-1, as
// a solver reading it numbers its nodal vectors; not the order of the
// store dicing it at interval 1 (space-filling curve).
std::vector<Id> file_columns(const FineMesh& m) {
  const CoarseMesh& c = *m.coarse();
  const Id nv = c.num_vertices();
  DICER_ASSERT(m.num_nodes() == nv, "a mesh diced at interval 1 has a node per vertex");
  std::vector<Id> by_id(static_cast<size_t>(nv));
  std::iota(by_id.begin(), by_id.end(), Id{0});
  auto file_id = [&](Id v) { return c.vertex_file_id.empty() ? v + 1 : c.vertex_file_id[v]; };
  std::sort(by_id.begin(), by_id.end(), [&](Id a, Id b) { return file_id(a) < file_id(b); });
  MeshCursor cur;
  const RowReader R(m.tables(), cur);
  std::vector<Id> columns(static_cast<size_t>(nv));
  for (Id k = 0; k < nv; ++k) columns[static_cast<size_t>(R.vertex(by_id[k]).node)] = k;
  return columns;
}

}  // namespace

int cmd_transfer(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string coarse_path, fine_path, out, format = "hdf5", petsc_int = "32";
  bool check = false, json = false, quiet = false;
  cmd.input("COARSE", coarse_path, "the coarse level: a store, or the coarse mesh file itself (interval 1)");
  cmd.input("FINE", fine_path, "the fine level: a store of the same coarse mesh");
  auto* o_check = cmd.flag("--check", check, "only say whether FINE is nested in COARSE (exit 0) or not (exit 1)");
  auto* o_out = cmd.output(out, "FILE", "write the prolongation P to FILE", false);
  auto* o_format = cmd.value("--format", format, "FMT", "hdf5 (CSR: indptr, indices, data, shape) or petsc (MatLoad binary)");
  auto* o_petsc_int = cmd.value("--petsc-int", petsc_int, "BITS",
            "index width of the PETSc file: 32 (PETSc's default build) or 64 (--with-64-bit-indices)");
  cmd.flag("--json", json,
           "one JSON object: nested, sheets, sheet, coarse_interval, fine_interval, "
           "min_factor, max_factor, rows, cols, moved_nodes_checked, moved_nodes_differ, "
           "message; with -o also output, format, nonzeros, bytes, seconds");
  cmd.flag("--quiet", quiet, "no progress bar");
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;
  if (cmd.given(o_check) == cmd.given(o_out))
    throw Error(ErrorKind::Usage, "give either --check or -o FILE (see dicer transfer --help)");
  if (!cmd.given(o_format) && !check) {
    // The extension tells, as export's does: P.bin written as HDF5 by a
    // forgotten --format was a trap.
    const std::string ext = std::filesystem::path(out).extension().string();
    if (ext == ".bin" || ext == ".petsc") format = "petsc";
  }
  if (format != "hdf5" && format != "petsc")
    throw Error(ErrorKind::Usage, "--format: \"" + format + "\" is neither hdf5 nor petsc");
  if (petsc_int != "32" && petsc_int != "64") throw Error(ErrorKind::Usage, "--petsc-int: 32 or 64, not " + petsc_int);
  // An option that would change nothing is a mistake said, not ignored.
  if (check && (cmd.given(o_format) || cmd.given(o_petsc_int)))
    throw Error(ErrorKind::Usage, std::string(cmd.given(o_format) ? "--format" : "--petsc-int") +
                                      " is for -o FILE; --check writes nothing");
  if (cmd.given(o_petsc_int) && format != "petsc")
    throw Error(ErrorKind::Usage, "--petsc-int is for --format petsc (the hdf5 format stores 64-bit indices)");

  const FineMesh coarse = open_level(coarse_path, store.options());
  const bool mesh_file = coarse.coarse() != nullptr;
  const FineMesh fine = read_store(fine_path, store.options());
  const Nesting n = check_nesting(coarse, fine);
  auto report = [&](Json extra) {
    if (!json) return;
    Json j = {{"nested", n.nested},
              {"sheets", n.sheets},
              {"sheet", n.sheet},
              {"coarse_interval", n.coarse_interval},
              {"fine_interval", n.fine_interval},
              {"min_factor", n.min_factor},
              {"max_factor", n.max_factor},
              {"rows", n.rows},
              {"cols", n.cols},
              {"moved_nodes_checked", n.moved_nodes_checked},
              {"moved_nodes_differ", n.moved_nodes_differ},
              {"message", n.message}};
    for (auto& [k, v] : extra.items()) j[k] = v;
    print_json(j);
  };
  if (check) {
    if (json) report(Json::object());
    else std::printf("%s\n", printable(n.message).c_str());
    store.report(fine);
    return n.nested && n.moved_nodes_differ == 0 ? kExitSuccess : kExitDefect;
  }
  const Prolongation p(coarse, fine);
  if (n.moved_nodes_differ > 0)
    std::fprintf(stderr, "dicer transfer: warning: %s\n", printable(n.message).c_str());
  CancelOnSignals signals;
  Progress bar("transfer", p.rows(), quiet || json);
  auto progress = [&](Id done, Id) {
    bar.update(done);
    throw_if_cancelled("nothing was written");
  };
  const auto start = std::chrono::steady_clock::now();
  const std::vector<Id> columns = mesh_file ? file_columns(coarse) : std::vector<Id>{};
  if (format == "hdf5")
    write_prolongation_hdf5(p, out, progress, columns,
                            mesh_file ? "the mesh file's corner nodes in increasing node id" : "coarse store node ids");
  else write_prolongation_petsc(p, out, petsc_int == "64" ? 8 : 4, progress, columns);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto bytes = static_cast<std::uint64_t>(std::filesystem::file_size(out));
  if (json) {
    report({{"output", out}, {"format", format}, {"nonzeros", p.nonzeros()}, {"bytes", bytes}, {"seconds", secs}});
  } else {
    std::printf("wrote %s: P is %s x %s with %s non-zeros (%s, %.2f bytes per non-zero) in %.2f s\n", printable(out).c_str(),
                human_count(p.rows()).c_str(), human_count(p.cols()).c_str(), human_count(p.nonzeros()).c_str(),
                human_bytes(bytes).c_str(), p.nonzeros() ? static_cast<double>(bytes) / static_cast<double>(p.nonzeros()) : 0.0,
                secs);
  }
  store.report(fine);
  return kExitSuccess;
}

}  // namespace dicer::cli
