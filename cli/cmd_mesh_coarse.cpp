// dicer mesh-coarse: CAD -> coarse all-hex (or all-quad) mesh via Gmsh.
#include <cstdio>

#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer mesh-coarse CAD --size H -o MESH [--surface] [--subdivide] [--quiet]

Meshes the STEP (.step/.stp) or BREP (.brep/.brp) model CAD with Gmsh into a
coarse all-hex mesh (with --surface: an all-quad mesh of its surfaces) and
writes it as MSH 4.1, with one physical group per volume (the blocks; in
surface mode per surface) and per surface (side sets), and every node
classified on its CAD entity. Dicing it with the same CAD then puts the fine
boundary nodes on the model:

  dicer mesh-coarse part.step --size 4 -o coarse.msh
  dicer dice coarse.msh --geometry part.step --interval 10 -o part.dice.h5

Gmsh meshes transfinitely where every surface is a 4-sided patch and every
volume 6-sided (a box, a swept block); otherwise it meshes with tetrahedra
(triangles) and subdivides each into hexahedra (quads): valid, all-hex,
but with more and less regular elements.

  --size H      target coarse element size (in the model's units; required)
  --surface     all-quad surface mesh of the model's surfaces
  --subdivide   skip the transfinite attempt
  -o, --output MESH   the MSH file to write (temporary name, then renamed)
  --quiet       no summary
)";

int cmd_mesh_coarse(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  Args args("mesh-coarse", argv, {"--size", "-o", "--output"}, {"--surface", "--subdivide", "--quiet"}, 1);
  const std::string cad = args.need_positional(0, "CAD");
  auto out = args.value("-o");
  if (!out) out = args.value("--output");
  if (!out) throw Error(ErrorKind::Usage, "missing -o MESH (the coarse mesh to write)");
  const auto size = args.value("--size");
  if (!size) throw Error(ErrorKind::Usage, "missing --size H (the coarse element size)");
  CoarseMeshOptions opt;
  opt.size = parse_double("--size", *size);
  opt.surface = args.has("--surface");
  opt.subdivide = args.has("--subdivide");
  const CoarseMeshReport r = mesh_coarse(cad, *out, opt);
  if (!args.has("--quiet"))
    std::printf("meshed %s (%lld volumes, %lld surfaces) by %s: %lld coarse %s, %lld vertices; wrote %s\n", cad.c_str(),
                static_cast<long long>(r.volumes), static_cast<long long>(r.surfaces), r.method.c_str(),
                static_cast<long long>(r.elements), opt.surface ? "quads" : "hexes", static_cast<long long>(r.vertices),
                out->c_str());
  return 0;
}

}  // namespace dicer::cli
