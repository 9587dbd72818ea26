// dicer dice: read a coarse mesh, resolve intervals, write the store.
#include <malloc.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "command.hpp"
#include "common.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/diced_rows.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/geometry.hpp"
#include "dicer/mpi.hpp"
#include "dicer/quadratic.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "dice", "dice MESH -o STORE [interval options] [--geometry CAD] [--quiet]",
    R"(Refines every coarse element of MESH by transfinite interpolation, one
interval count per dicer sheet (see `dicer sheets`), and writes the fine
mesh implicitly to STORE (HDF5): coarse mesh, topology, sheets, intervals.
Nothing of the fine mesh itself is stored; `info`, `query` and `verify`
regenerate it on demand.

Second-order input (HEX20, HEX27; QUAD8, QUAD9 in Exodus or MSH) is diced
on its quadratic geometry, no CAD needed: the corners make the coarse mesh,
fine nodes on coarse edges go onto the P2 curve through the mid node, on
faces onto the serendipity (HEX20) or biquadratic (HEX27) surface, and
interiors follow by TFI; the moved nodes are stored. A fine element that
the curvature would invert is refused (exit 7). With --geometry the CAD
wins: the mid nodes are ignored, with a note.

Grading: --sheet-bias S=R@V makes the fine edges of sheet S grow by R from
node V (R > 1: finest at V, e.g. a boundary layer at a wall through V);
--sheet-dual-bias S=R grows them from both ends to the middle. The TFI
then follows the graded edges, so faces and interiors are graded the
same way and the mesh stays conforming. --entity-interval DIM:TAG=N sets
intervals by geometric entity (curve 1, surface 2, volume 3) of an MSH
file's classification, or of the CAD with --geometry.

Under mpirun, --geometry shares out the CAD work (each of P ranks places
every P-th curve and face and checks every P-th coarse element; rank 0
writes the same store one process writes); without it rank 0 dices alone.

Memory: about 1.2 KB per coarse hex (the coarse mesh, its topology and
numbering; the store's rows are written as they are made), whatever the
intervals; --geometry and second-order input hold the store's tables
too (about 2.6 KB per hex), since they move nodes in them.

STORE is written under a temporary name in its folder and renamed when
complete: an interrupted dice (Ctrl-C, SIGTERM, SIGHUP: exit 130, 143,
129) leaves any existing STORE as it was and nothing else behind.
)",
    R"(dicer dice part.exo --interval 8 --block-interval 2=4 -o part.dice.h5
dicer dice part.msh --intervals-file plan.json --sheet-interval 17=12 -o p.h5
dicer dice part.exo --interval 8 --sheet-interval 3=20 --sheet-bias 3=1.2@17 -o p.h5
dicer dice part.exo --size 0.5 --sheet-bias 3=first:0.01@17 -o p.h5
dicer dice part.msh --interval 4 --entity-interval 1:12=16 --sheet-dual-bias 2=1.3 -o p.h5
dicer mesh-coarse part.step --size 4 -o coarse.msh
dicer dice coarse.msh --geometry part.step --interval 10 -o fine.dice.h5
dicer dice pipe_hex27.e --interval 6 -o pipe.dice.h5    # quadratic edges and faces
)"};

int cmd_dice(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string in, out, cad, tolerance(16, '\0');
  tolerance.resize(static_cast<size_t>(std::snprintf(tolerance.data(), tolerance.size(), "%g", ConformOptions{}.tolerance)));
  bool quiet = false;
  cmd.input("MESH", in, "the coarse mesh: Exodus II or Gmsh MSH 1/2.2/4.1, hexes or quads, first or second order");
  cmd.output(out, "STORE", "the store to write (.dice.h5)");
  cmd.flag("--quiet", quiet, "no progress bar, no summary on stdout");
  IntervalFlags intervals(cmd);
  const std::string geometry = "Geometry (fine nodes on the CAD instead of the coarse facets)";
  auto* o_cad = cmd.input_value("--geometry", cad, "CAD",
                                "STEP (.step/.stp) or BREP (.brep/.brp) model the "
                                "coarse mesh was made from. Boundary vertices, "
                                "edges and faces are matched to its points, curves "
                                "and surfaces (MSH classification when the tags "
                                "agree, geometrically otherwise); edge nodes then "
                                "face nodes move onto them; hex interiors follow. "
                                "The moved nodes go into the store, so reading it "
                                "never needs the CAD. Refused (exit 7) when the mesh "
                                "does not fit the CAD or a fine element would invert. "
                                "Runs in dicer-cad (with Gmsh)",
                                geometry);
  auto* o_tol = cmd.value("--geometry-tol", tolerance, "T",
                          "a boundary vertex must be within T x the CAD's "
                          "bounding-box diagonal of its entity",
                          geometry);
  bool run = true;
  agree([&] { run = cmd.parse(argv); });
  if (!run) return 0;
  // Under mpirun only the CAD work is shared out: every rank dices the
  // coarse mesh, places every P-th curve and face and checks every P-th
  // coarse element (ConformOptions::parts), and rank 0 writes the store a
  // single process writes. Without --geometry rank 0 does it alone.
  mpi::Session& mpi = session();
  const bool with_cad = cmd.given(o_cad);
  const bool shared = mpi.active() && with_cad, lead = !shared || mpi.rank() == 0;
  // Each step ends with an agreement when shared (a rank that fails is
  // known to all before anyone waits for it).
  auto step = [&](const std::function<void()>& fn) {
    if (shared) agree(fn);
    else fn();
  };
  auto body = [&]() -> int {
    IntervalRequest req;
    ConformOptions copt;
    const CancelOnSignals cancel_on_signals;
    // Dicing allocates and frees arrays of hundreds of MB in turn (sort keys,
    // permutations, tables). glibc maps every block over 32 MiB on its own,
    // so each is fresh memory the kernel zeroes page by page (a third of the
    // time of a dice of 1e6 hexes); in the heap, freed pages are reused.
    // Peak memory stays the same; it returns to the system at exit.
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    const std::string nothing_written = "nothing written to " + out;
    // Plain dicing streams the tables' rows into the store (DicedRows: less
    // than half the memory); the CAD and second-order input move nodes in
    // tables compiled into memory first.
    std::optional<DicedRows> rows;
    std::optional<FineMesh> diced;
    SecondOrderReport quad;
    // Under mpirun with --geometry every rank reads MESH, the CAD and the
    // intervals file itself: copies local to each node must agree (checked
    // before the nodes are placed), or the ranks' shares would not fit.
    std::string fingerprint;
    auto fold = [&](const void* data, size_t bytes) {
      fingerprint += std::to_string(std::hash<std::string_view>{}({static_cast<const char*>(data), bytes})) + " ";
    };
    step([&] {
      req = intervals.request();
      if (cmd.given(o_tol) && !with_cad) throw Error(ErrorKind::Usage, "--geometry-tol needs --geometry CAD");
      copt.tolerance = parse_double("--geometry-tol", tolerance);
      CoarseMesh mesh = read_coarse_mesh(in);
      if (lead)
        for (const auto& w : mesh.warnings)
          std::fprintf(stderr, "dicer dice: warning: %s: %s\n", printable(in).c_str(), printable(w).c_str());
      // Intervals by entity name the CAD's entities when a CAD is given.
      if (with_cad && (!req.entities.empty() || !req.entity_bias.empty())) classify_on_geometry(mesh, cad, copt);
      if (shared) {
        for (const auto* a : {&mesh.x, &mesh.y, &mesh.z}) fold(a->data(), a->size() * sizeof(double));
        fold(mesh.conn.data(), mesh.conn.size() * sizeof(Id));
        // The CAD's bytes, a block at a time.
        const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(cad.c_str(), "rb"), &std::fclose);
        if (!file) throw Error(ErrorKind::Io, cad + ": cannot open: " + std::strerror(errno));
        std::vector<char> block(1 << 20);
        for (size_t n; (n = std::fread(block.data(), 1, block.size(), file.get())) > 0;) fold(block.data(), n);
        if (std::ferror(file.get())) throw Error(ErrorKind::Io, cad + ": read failed");
      }
      std::vector<std::string> notes;
      const bool second_order = mesh.second_order();
      if (with_cad || second_order) diced.emplace(FineMesh::dice(std::move(mesh), req, &notes));
      else rows.emplace(std::move(mesh), req, &notes);
      if (lead)
        for (const auto& n : notes) std::fprintf(stderr, "dicer dice: note: %s\n", printable(n).c_str());
      throw_if_cancelled(nothing_written);
      if (second_order && with_cad) {
        if (lead)
          std::fprintf(stderr,
                       "dicer dice: note: %s is second order; with --geometry the CAD places the boundary and its mid "
                       "nodes are ignored\n",
                       in.c_str());
      } else if (second_order) {
        quad = apply_second_order(*diced);
        throw_if_cancelled(nothing_written);
      }
      // The intervals and gradings the request resolved to (an intervals
      // file that differs shows there).
      if (shared) {
        fold(diced->sheet_intervals().data(), diced->sheet_intervals().size() * sizeof(Id));
        // As text, then hashed: the fingerprint stays a few hashes long
        // however many sheets (every rank gathers every rank's).
        std::string gradings;
        char g[96];
        for (const SheetGrading& s : diced->sheet_gradings()) {
          std::snprintf(g, sizeof g, "%d %d %.17g %lld;", static_cast<int>(s.grading.kind), s.grading.flip ? 1 : 0,
                        s.grading.ratio, static_cast<long long>(s.start));
          gradings += g;
        }
        fold(gradings.data(), gradings.size());
      }
    });
    if (shared)
      dicer::mpi::require_same(mpi.comm(), fingerprint, ErrorKind::BadInput, [&](int q, const std::string&) {
        return "rank " + std::to_string(q) + " read other contents than rank 0 from " + in + ", " + cad +
               " or the intervals: every rank must read the same files (copies local to each node that differ?)";
      });
    ConformReport geo;
    if (with_cad) {
      FineMesh& fine = *diced;
      step([&] {
        Progress bar("dice: geometry", 1, quiet || !lead);
        copt.progress = [&](const char*, Id done, Id total) { bar.update(done, total); };
        if (shared) {
          copt.part = mpi.rank(), copt.parts = mpi.size();
          copt.share = [&](const std::string& mine) { return dicer::mpi::allgather_bytes(mpi.comm(), mine); };
        }
        geo = conform_to_geometry(fine, cad, copt);
        throw_if_cancelled(nothing_written);
      });
    }
    step([&] {
      if (!lead) return;
      Progress bar("dice: writing", 1, quiet);
      // Thrown from the page callback: write_store removes its temporary file.
      const auto page_written = [&](std::int64_t done, std::int64_t total) {
        throw_if_cancelled(nothing_written);
        bar.update(done, total);
      };
      if (rows) write_store(*rows, out, page_written);
      else write_store(*diced, out, page_written);
    });
    if (!lead) return 0;
    if (with_cad) warn_cad_reader("dice", cad, geo.cad_reader_said);
    const MeshInfo& info = rows ? rows->info() : diced->info();
    if (!quiet)
      std::printf("diced %s: %lld coarse %s -> %s fine nodes, %s fine elements (%lld sheets); wrote %s\n", printable(in).c_str(),
                  static_cast<long long>(info.coarse_elements), info.mode == Mode::Volume ? "hexes" : "quads",
                  human_count(info.nodes).c_str(), human_count(info.elements).c_str(),
                  static_cast<long long>(info.sheets), printable(out).c_str());
    // The quality dice checks is of the fine elements in coarse elements
    // whose nodes moved (verify checks every element: its minimum may be
    // lower, from elements that never moved).
    auto moved_quality = [](double min_jacobian, Id checked) {
      if (checked == 0) return std::string("no element moved");
      char b[160];
      std::snprintf(b, sizeof b, "min scaled Jacobian %.4f over the %s fine elements of coarse elements that moved",
                    min_jacobian, human_count(checked).c_str());
      return std::string(b);
    };
    if (quad.second_order && !quiet)
      std::printf("second order %s: %lld edges and %lld faces curved = %s bounding nodes; %s\n", printable(in).c_str(),
                  static_cast<long long>(quad.edges_curved), static_cast<long long>(quad.faces_curved),
                  human_count(quad.bounding_nodes).c_str(),
                  moved_quality(quad.min_scaled_jacobian, quad.elements_checked).c_str());
    if (with_cad && !quiet)
      std::printf("geometry %s: %lld vertices on the CAD (largest snap %.3g), %lld edges on curves, %lld on surfaces, "
                  "%lld faces on surfaces; moved %lld edges + %lld faces = %s bounding nodes (%lld by closest point); "
                  "%s\n",
                  printable(cad).c_str(), static_cast<long long>(geo.vertices_on_cad), geo.max_vertex_snap,
                  static_cast<long long>(geo.edges_on_curves), static_cast<long long>(geo.edges_on_surfaces),
                  static_cast<long long>(geo.faces_on_surfaces), static_cast<long long>(geo.edges_moved),
                  static_cast<long long>(geo.faces_moved), human_count(geo.bounding_nodes).c_str(),
                  static_cast<long long>(geo.closest_point_fallbacks),
                  moved_quality(geo.min_scaled_jacobian, geo.elements_checked).c_str());
    return 0;
  };
  if (mpi.active() && !with_cad) return on_rank0(body);
  return body();
}

}  // namespace dicer::cli
