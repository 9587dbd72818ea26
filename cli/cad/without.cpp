// Linked into `dicer` only: the commands that need a CAD model (mesh-coarse,
// dice --geometry, verify --geometry) are handed to `dicer-cad`, the same
// commands linked with dicer_geometry. Why two executables: Gmsh and
// OpenCASCADE bring ~100 shared libraries into every start of the tool
// (~50 MiB and ~0.1 s for `dicer info` or `dicer query`), for the few
// commands that use them.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"

namespace dicer::cli {
namespace {

bool needs_cad(const std::vector<std::string>& all) {
  const std::vector<std::string> args = options_part(all);  // "-- -h" names a file
  if (args.empty()) return false;
  // Help is dicer's own table (dicer help mesh-coarse works without dicer-cad).
  for (const auto& a : args)
    if (a == "--help" || a == "-h") return false;
  if (args[0] == "mesh-coarse") return true;
  if (args[0] != "dice" && args[0] != "verify") return false;
  for (size_t i = 1; i < args.size(); ++i)
    if (args[i] == "--geometry" || args[i].rfind("--geometry=", 0) == 0) return true;
  return false;
}

// dicer-cad beside this executable, or $DICER_CAD.
std::string cad_executable() {
  if (const char* env = std::getenv("DICER_CAD"); env != nullptr && *env != '\0') return env;
  std::string self(4096, '\0');
  const ssize_t n = ::readlink("/proc/self/exe", self.data(), self.size() - 1);
  if (n <= 0) return "dicer-cad";
  self.resize(static_cast<size_t>(n));
  const size_t slash = self.rfind('/');
  return (slash == std::string::npos ? std::string(".") : self.substr(0, slash)) + "/dicer-cad";
}

}  // namespace

void hand_over_if_cad(char** argv, const std::vector<std::string>& args) {
  if (!needs_cad(args)) return;
  const std::string exe = cad_executable();
  const std::string what = args[0] == "mesh-coarse" ? "mesh-coarse" : args[0] + " --geometry";
  if (::access(exe.c_str(), X_OK) != 0)
    throw Error(ErrorKind::Io, exe + ": " + std::strerror(errno) + ": `dicer " + what +
                                   "` needs dicer-cad (the commands built with Gmsh), installed beside dicer; "
                                   "set DICER_CAD to its path");
  // DICER_CAD naming dicer (this one, or another copy that hands over in
  // turn) would exec itself for ever: the mark below, set for the program
  // we start, says the command came back.
  constexpr const char* kMark = "DICER_CAD_HANDED_OVER";
  struct stat self {}, target {};
  const bool same = ::stat("/proc/self/exe", &self) == 0 && ::stat(exe.c_str(), &target) == 0 &&
                    self.st_dev == target.st_dev && self.st_ino == target.st_ino;
  if (same || std::getenv(kMark) != nullptr)
    throw Error(ErrorKind::Io, exe + ": is not dicer-cad (it handed `dicer " + what +
                                   "` back to dicer): set DICER_CAD to dicer-cad, the commands built with Gmsh");
  ::setenv(kMark, "1", 1);
  ::execv(exe.c_str(), argv);
  ::unsetenv(kMark);
  throw Error(ErrorKind::Io, exe + ": cannot run: " + std::strerror(errno));
}

}  // namespace dicer::cli

// The geometry entry points the commands call. Never reached in `dicer`:
// those commands were handed over above.
namespace dicer {
ConformReport conform_to_geometry(FineMesh&, const std::string&, const ConformOptions&) {
  throw std::logic_error("conform_to_geometry in dicer without Gmsh (the command should run in dicer-cad)");
}
void classify_on_geometry(CoarseMesh&, const std::string&, const ConformOptions&) {
  throw std::logic_error("classify_on_geometry in dicer without Gmsh (the command should run in dicer-cad)");
}
GeometryCheck check_geometry(const FineMesh&, const std::string&, const std::function<void(Id, Id)>&) {
  throw std::logic_error("check_geometry in dicer without Gmsh (the command should run in dicer-cad)");
}
CoarseMeshReport mesh_coarse(const std::string&, const std::string&, const CoarseMeshOptions&) {
  throw std::logic_error("mesh_coarse in dicer without Gmsh (the command should run in dicer-cad)");
}
}  // namespace dicer
