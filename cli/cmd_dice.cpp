// dicer dice: read a coarse mesh, resolve intervals, write the store.
#include <cstdio>

#include "common.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/geometry.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer dice MESH -o STORE [interval options] [--geometry CAD] [--quiet]

Refines every coarse element of MESH by transfinite interpolation, one
interval count per dicer sheet (see `dicer sheets`), and writes the fine
mesh implicitly to STORE (HDF5): coarse mesh, topology, sheets, intervals.
Nothing of the fine mesh itself is stored; `info`, `query` and `verify`
regenerate it on demand.

Interval options (precedence: sheet > block > size > global > 1):
  --interval N            every sheet gets N (default 1)
  --size H                each sheet gets the smallest N that makes all its
                          edges no longer than H
  --block-interval B=N    sheets touching block B (id or name) get N; a sheet
                          touching several such blocks gets the LARGEST, and
                          the conflict is reported (repeatable)
  --sheet-interval S=N    sheet S gets N, whatever its blocks ask (repeatable)
  --intervals-file FILE   JSON with any of these keys:
                          {"global": 4, "size": 0.05, "blocks": {"2": 6,
                          "inlet": 3}, "sheets": {"17": 12}}
                          flags on the command line override the file
Geometry (fine nodes on the CAD instead of the coarse facets):
  --geometry CAD          STEP (.step/.stp) or BREP (.brep/.brp) model the
                          coarse mesh was made from. Boundary vertices,
                          edges and faces are matched to its points, curves
                          and surfaces (MSH classification when the tags
                          agree, geometrically otherwise); edge nodes then
                          face nodes move onto them; hex interiors follow.
                          The moved nodes go into the store, so reading it
                          never needs the CAD. Refused (exit 7) when the mesh
                          does not fit the CAD or a fine element would invert.
  --geometry-tol T        a boundary vertex must be within T x the CAD's
                          bounding-box diagonal of its entity (default 1e-4)
Other options:
  -o, --output STORE      the store to write (written to a temporary name in
                          the same folder, renamed when complete; Ctrl-C,
                          SIGTERM and SIGHUP (exit 130, 143, 129) leave
                          nothing behind)
  --quiet                 no summary on stdout

Examples:
  dicer dice part.exo --interval 8 --block-interval 2=4 -o part.dice.h5
  dicer mesh-coarse part.step --size 4 -o coarse.msh
  dicer dice coarse.msh --geometry part.step --interval 10 -o fine.dice.h5
)";

int cmd_dice(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  std::vector<std::string> vflags = kIntervalFlags;
  vflags.push_back("-o");
  vflags.push_back("--output");
  vflags.push_back("--geometry");
  vflags.push_back("--geometry-tol");
  Args args("dice", argv, vflags, {"--quiet"}, 1);
  const std::string in = args.need_positional(0, "MESH");
  auto out = args.value("-o");
  if (!out) out = args.value("--output");
  if (!out) throw Error(ErrorKind::Usage, "missing -o STORE (the output file)");
  const IntervalRequest req = interval_request(args);
  const auto cad = args.value("--geometry");
  ConformOptions copt;
  if (auto t = args.value("--geometry-tol")) copt.tolerance = parse_double("--geometry-tol", *t);
  if (args.value("--geometry-tol") && !cad) throw Error(ErrorKind::Usage, "--geometry-tol needs --geometry CAD");
  const CancelOnSignals cancel_on_signals;
  const std::string nothing_written = "nothing written to " + *out;
  CoarseMesh mesh = read_coarse_mesh(in);
  for (const auto& w : mesh.warnings) std::fprintf(stderr, "dicer dice: warning: %s: %s\n", in.c_str(), w.c_str());
  std::vector<std::string> notes;
  FineMesh fine = FineMesh::dice(std::move(mesh), req, &notes);
  for (const auto& n : notes) std::fprintf(stderr, "dicer dice: note: %s\n", n.c_str());
  throw_if_cancelled(nothing_written);
  ConformReport geo;
  if (cad) {
    Progress bar("dice: geometry", 1, args.has("--quiet"));
    copt.progress = [&](const char*, Id done, Id total) { bar.update(done, total); };
    geo = conform_to_geometry(fine, *cad, copt);
    throw_if_cancelled(nothing_written);
  }
  {
    Progress bar("dice: writing", 1, args.has("--quiet"));
    // Thrown from the page callback: write_store removes its temporary file.
    write_store(fine, *out, [&](std::int64_t done, std::int64_t total) {
      throw_if_cancelled(nothing_written);
      bar.update(done, total);
    });
  }
  if (!args.has("--quiet"))
    std::printf("diced %s: %lld coarse %s -> %s fine nodes, %s fine elements (%lld sheets); wrote %s\n", in.c_str(),
                static_cast<long long>(fine.num_coarse_elements()), fine.mode() == Mode::Volume ? "hexes" : "quads",
                human_count(fine.num_nodes()).c_str(), human_count(fine.num_elements()).c_str(),
                static_cast<long long>(fine.info().sheets), out->c_str());
  if (cad && !args.has("--quiet"))
    std::printf("geometry %s: %lld vertices on the CAD (largest snap %.3g), %lld edges on curves, %lld on surfaces, "
                "%lld faces on surfaces; moved %lld edges + %lld faces = %s bounding nodes (%lld by closest point); "
                "min scaled Jacobian %.4f over %s elements checked\n",
                cad->c_str(), static_cast<long long>(geo.vertices_on_cad), geo.max_vertex_snap,
                static_cast<long long>(geo.edges_on_curves), static_cast<long long>(geo.edges_on_surfaces),
                static_cast<long long>(geo.faces_on_surfaces), static_cast<long long>(geo.edges_moved),
                static_cast<long long>(geo.faces_moved), human_count(geo.bounding_nodes).c_str(),
                static_cast<long long>(geo.closest_point_fallbacks), geo.min_scaled_jacobian,
                human_count(geo.elements_checked).c_str());
  return 0;
}

}  // namespace dicer::cli
