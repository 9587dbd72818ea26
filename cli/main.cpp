// dicer: the command-line tool. One file per subcommand; this one dispatches
// and turns dicer::Error into a one-line message and a documented exit code.
#include <cstdio>
#include <cstring>
#include <exception>
#include <map>
#include <string>
#include <vector>

#include "common.hpp"
#include "dicer/error.hpp"

namespace {

const char* kUsage = R"(dicer - refine coarse all-hex (or all-quad) meshes into huge conforming
fine meshes that are stored implicitly: coarse mesh + intervals + recipe.

Usage: dicer <command> [options]      dicer <command> --help for details

Commands (in the order you use them):
  mesh-coarse CAD -o MESH  coarse all-hex (--surface: all-quad) mesh of a STEP
                   or BREP model with Gmsh, ready for dice --geometry CAD
  sheets  MESH     list the dicer sheets (edges that must share one interval)
  dice    MESH -o STORE   choose intervals and write the implicit fine mesh
  info    STORE    counts, blocks and settings of a store
  query   STORE    fine nodes and elements by id (--node, --nodes, --element, --elements)
  verify  STORE    stream through every fine element and check conformity,
                   counts, coincident nodes and element quality
  footprint STORE  bytes on disk and in memory vs an explicit mesh
  export  STORE    a chunk, a box or the whole mesh to VTKHDF, MSH 4.1 or Exodus II
  sweep   STORE    every fine node and element in N threads, rate and checksum

mesh-coarse and --geometry run dicer-cad (the same commands built with Gmsh),
installed beside dicer; DICER_CAD=PATH overrides where it is found.

MESH is an Exodus II file (.e .exo .ex2 .g) or a Gmsh MSH 2.2/4.1 file
(ASCII or binary) holding hexahedra (volume dicing) or quadrilaterals
(surface dicing). STORE is the HDF5 file `dice` writes (.dice.h5).

Example:
  dicer sheets examples/cardinal_sphere.e
  dicer dice examples/cardinal_sphere.e --interval 8 -o sphere.dice.h5
  dicer mesh-coarse part.step --size 4 -o coarse.msh
  dicer dice coarse.msh --geometry part.step --interval 10 -o part.dice.h5
  dicer info sphere.dice.h5
  dicer query sphere.dice.h5 --element 1000 --json
  dicer verify sphere.dice.h5

Exit codes:
  0 success            1 verify found a defect     2 bad command-line usage
  3 bad input file     4 unsupported content       5 I/O error
  6 counts overflow 64-bit ids                     7 mesh and CAD do not fit,
                                                     or an element would invert
  8 corrupt or unknown store                       70 internal error
  130 interrupted (Ctrl-C): no output file was left behind
)";

}  // namespace

int main(int argc, char** argv) {
  using namespace dicer::cli;
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "--version") {
    std::puts("dicer 0.1.0");
    return 0;
  }
  const std::map<std::string, Command> commands = {
      {"sheets", cmd_sheets}, {"dice", cmd_dice}, {"info", cmd_info}, {"query", cmd_query}, {"verify", cmd_verify},
      {"footprint", cmd_footprint}, {"export", cmd_export}, {"sweep", cmd_sweep}, {"mesh-coarse", cmd_mesh_coarse}};
  auto it = commands.find(args[0]);
  if (it == commands.end()) {
    std::fprintf(stderr, "dicer: error: unknown command \"%s\" (commands: mesh-coarse, sheets, dice, info, query, verify, footprint, export, sweep; see dicer --help)\n",
                 args[0].c_str());
    return 2;
  }
  try {
    hand_over_if_cad(argv, args);
    return it->second(std::vector<std::string>(args.begin() + 1, args.end()));
  } catch (const dicer::Error& e) {
    std::fprintf(stderr, "dicer %s: error: %s\n", args[0].c_str(), e.what());
    return static_cast<int>(e.kind());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "dicer %s: error: out of memory\n", args[0].c_str());
    return kExitInternal;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dicer %s: internal error: %s\n", args[0].c_str(), e.what());
    return kExitInternal;
  }
}
