// dicer mesh-coarse: CAD -> coarse all-hex (or all-quad) mesh via Gmsh.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "mesh-coarse", "mesh-coarse CAD --size H -o MESH [--surface] [--subdivide]\n                         [--quiet]",
    R"(Meshes the STEP (.step/.stp) or BREP (.brep/.brp) model CAD with Gmsh into a
coarse all-hex mesh (with --surface: an all-quad mesh of its surfaces) and
writes it as MSH 4.1, with one physical group per volume (the blocks; in
surface mode per surface) and per surface (side sets), and every node
classified on its CAD entity. Dicing it with the same CAD then puts the fine
boundary nodes on the model.

Gmsh meshes transfinitely where every surface is a 4-sided patch and every
volume 6-sided (a box, a swept block); otherwise it meshes with tetrahedra
(triangles) and subdivides each into hexahedra (quads): valid, all-hex,
but with more and less regular elements. With --surface, a surface between
two volumes is left out: the mesh is the model's skin. Runs in dicer-cad
(with Gmsh). Gmsh loops on some damaged models: the meshing ends as an error
(exit 7) after 300 s + 1 ms per expected element of CPU time
(DICER_CAD_MESH_SECONDS=S sets it), the read of CAD after 30 s + 60 s per
MiB (DICER_CAD_READ_SECONDS=S; exit 3).
)",
    R"(dicer mesh-coarse part.step --size 4 -o coarse.msh
dicer dice coarse.msh --geometry part.step --interval 10 -o part.dice.h5
)"};

int cmd_mesh_coarse(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string cad, out, size;
  bool surface = false, subdivide = false, quiet = false;
  cmd.input("CAD", cad, "the STEP or BREP model");
  cmd.output(out, "MESH", "the MSH 4.1 file to write (temporary name, then renamed)");
  auto* o_size = cmd.value("--size", size, "H",
                           "target coarse element size, in the model's units: an upper "
                           "bound (curves shorter than H get one element); a size that "
                           "would make more than 5e6 coarse elements is refused");
  cmd.require(o_size, "the coarse element size");
  cmd.flag("--surface", surface, "all-quad surface mesh of the model's surfaces");
  cmd.flag("--subdivide", subdivide, "skip the transfinite attempt");
  cmd.flag("--quiet", quiet, "no summary on stdout");
  if (!cmd.parse(argv)) return 0;
  // MSH 4.1 under a name that says another format would be misread by
  // whatever goes by the extension (dicer's own readers included).
  {
    std::string ext = std::filesystem::path(out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    for (const char* other : {".e", ".exo", ".ex2", ".g", ".h5", ".hdf", ".vtkhdf", ".vtk", ".vtu"})
      if (ext == other)
        throw Error(ErrorKind::Usage, "-o " + out + ": mesh-coarse writes Gmsh MSH 4.1, and a " + ext +
                                          " name says another format; give a .msh name");
  }
  // Past a file size limit the write fails (EFBIG) instead of SIGXFSZ
  // killing dicer-cad with its temporary left behind.
  ignore_file_size_signal();
  CoarseMeshOptions opt;
  opt.size = parse_double("--size", size);
  opt.surface = surface;
  opt.subdivide = subdivide;
  const CoarseMeshReport r = mesh_coarse(cad, out, opt);
  warn_cad_reader("mesh-coarse", cad, r.cad_reader_said);
  if (!quiet) {
    std::printf("meshed %s (%lld volumes, %lld surfaces) by %s: %lld coarse %s, %lld vertices; wrote %s\n", printable(cad).c_str(),
                static_cast<long long>(r.volumes), static_cast<long long>(r.surfaces), r.method.c_str(),
                static_cast<long long>(r.elements), opt.surface ? "quads" : "hexes", static_cast<long long>(r.vertices),
                printable(out).c_str());
    if (r.interfaces_left_out > 0)
      std::printf("left out %lld surface%s between two volumes (the skin only)\n", static_cast<long long>(r.interfaces_left_out),
                  r.interfaces_left_out == 1 ? "" : "s");
  }
  return 0;
}

}  // namespace dicer::cli
