// Linked into `dicer-cad` (the commands with Gmsh): every command runs here.
#include <string>
#include <vector>

#include "../common.hpp"

namespace dicer::cli {
void hand_over_if_cad(char**, const std::vector<std::string>&) {}
}  // namespace dicer::cli
