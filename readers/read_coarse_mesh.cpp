// Reading dispatch: the format is chosen by content, not by file name.
#include <cctype>
#include <string>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "input_file.hpp"

namespace dicer {
namespace {

// An MSH file is a sequence of "$Section" ... "$EndSection" blocks, and
// Gmsh skips any it does not know, before $MeshFormat too ($Comments
// first is common). So a first line "$Word" is enough to hand the file to
// the MSH reader, which says precisely what is wrong if it is not one.
bool starts_like_msh(const std::string& head) {
  std::size_t i = 0;
  while (i < head.size() && std::isspace(static_cast<unsigned char>(head[i]))) ++i;
  return i + 1 < head.size() && head[i] == '$' && std::isalpha(static_cast<unsigned char>(head[i + 1]));
}

}  // namespace

CoarseMesh read_coarse_mesh(const std::string& path) {
  const std::string h = InputFile(path).head(256);
  CoarseMesh mesh;
  // netCDF classic/64-bit ("CDF\1", "CDF\2", "CDF\5") or netCDF-4 (HDF5).
  if (h.rfind("CDF", 0) == 0 || h.rfind("\x89HDF", 0) == 0) {
    mesh = read_exodus(path);
  } else if (starts_like_msh(h)) {
    mesh = read_msh(path);
  } else if (h.empty()) {
    throw Error(ErrorKind::BadInput, path + ": file is empty");
  } else {
    throw Error(ErrorKind::BadInput,
                path + ": not an Exodus II (netCDF) or Gmsh MSH file (unrecognised first bytes)");
  }
  if (mesh.source.empty()) mesh.source = path;
  validate_coarse_mesh(mesh);
  return mesh;
}

}  // namespace dicer
