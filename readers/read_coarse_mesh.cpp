// Reading dispatch: the format is chosen by content, not by file name.
#include <fstream>
#include <string>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"

namespace dicer {

CoarseMesh read_coarse_mesh(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorKind::Io, path + ": cannot open file for reading");
  char head[16] = {};
  in.read(head, sizeof head);
  const std::string h(head, static_cast<size_t>(in.gcount()));
  CoarseMesh mesh;
  // netCDF classic/64-bit ("CDF\1", "CDF\2", "CDF\5") or netCDF-4 (HDF5).
  if (h.rfind("CDF", 0) == 0 || h.rfind("\x89HDF", 0) == 0) {
    mesh = read_exodus(path);
  } else if (h.find("$Mesh") != std::string::npos) {
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
