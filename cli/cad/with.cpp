// Linked into `dicer-cad` (the commands with Gmsh): every command runs here.
#include <cstdlib>
#include <string>
#include <vector>

#include "../common.hpp"

namespace dicer::cli {
// dicer-cad is where a handed-over command lands: the mark that dicer set
// (cad/without.cpp) stops here, so no program dicer-cad starts inherits it.
void hand_over_if_cad(char**, const std::vector<std::string>&) { ::unsetenv("DICER_CAD_HANDED_OVER"); }
}  // namespace dicer::cli
