// CAD -> coarse all-hex (or all-quad) mesh with Gmsh: transfinite where the
// CAD allows, Gmsh's all-hex subdivision otherwise.
#include <gmsh.h>

#include <filesystem>
#include <unistd.h>

#include "cad.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"

namespace dicer {
namespace {

// Whether every entity of dimension `dim` got only hexahedra (5) / quads (3).
bool only(int dim, int type) {
  gmsh::vectorpair ents;
  gmsh::model::getEntities(ents, dim);
  bool any = false;
  for (const auto& [d, t] : ents) {
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> tags, nodes;
    gmsh::model::mesh::getElements(types, tags, nodes, d, t);
    for (int ty : types) {
      if (ty != type) return false;
      any = true;
    }
  }
  return any;
}

// Every surface bounded by 4 curves, and (volume) every volume by 6 surfaces.
bool transfinite_shaped(int dim) {
  gmsh::vectorpair ents;
  gmsh::model::getEntities(ents, dim);
  if (ents.empty()) return false;
  for (const auto& e : ents) {
    gmsh::vectorpair faces;
    gmsh::model::getBoundary({e}, faces, false, false, false);
    if (dim == 3 && faces.size() != 6) return false;
    if (dim == 2 && faces.size() != 4) return false;
    if (dim == 3)
      for (const auto& f : faces) {
        gmsh::vectorpair curves;
        gmsh::model::getBoundary({{2, std::abs(f.second)}}, curves, false, false, false);
        if (curves.size() != 4) return false;
      }
  }
  return true;
}

}  // namespace

CoarseMeshReport mesh_coarse(const std::string& cad_path, const std::string& msh_path, const CoarseMeshOptions& opt) {
  if (!(opt.size > 0)) throw Error(ErrorKind::Usage, "--size must be a positive element size");
  const geometry::Cad cad(cad_path);  // checks the file, loads it as dicing will (same tags)
  const int dim = opt.surface ? 2 : 3;
  if (!opt.surface && cad.entities(3).empty())
    throw Error(ErrorKind::Geometry, cad_path + ": the CAD model has no solid to fill with hexahedra (use --surface for a shell)");
  CoarseMeshReport rep;
  rep.volumes = static_cast<Id>(cad.entities(3).size());
  rep.surfaces = static_cast<Id>(cad.entities(2).size());
  const std::filesystem::path out(msh_path);
  const std::filesystem::path tmp =
      (out.has_parent_path() ? out.parent_path() : std::filesystem::path(".")) /
      ("." + out.filename().string() + ".tmp-" + std::to_string(::getpid()) + ".msh");
  try {
  geometry::gmsh_call(ErrorKind::Geometry, cad_path + ": Gmsh could not mesh the model", [&] {
    gmsh::option::setNumber("Mesh.MeshSizeMax", opt.size);
    gmsh::option::setNumber("Mesh.MeshSizeMin", 0.0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.ElementOrder", 1);
    // Transfinite when every surface is a 4-sided patch and every volume is
    // bounded by 6 of them, decided before meshing: Gmsh 4.8 crashes when
    // asked to clear a failed transfinite attempt.
    if (!opt.subdivide && transfinite_shaped(dim)) {
      gmsh::model::mesh::setTransfiniteAutomatic({}, 2.35, true);
      gmsh::option::setNumber("Mesh.RecombineAll", 1);
      gmsh::option::setNumber("Mesh.SubdivisionAlgorithm", 0);
      gmsh::model::mesh::generate(dim);
      rep.method = "transfinite";
    } else {
      // Triangles / tetrahedra, each split into quads / hexes. (Gmsh 4.8's
      // quad-oriented algorithm 8 segfaults on curved OpenCASCADE faces.)
      gmsh::option::setNumber("Mesh.RecombineAll", opt.surface ? 1 : 0);
      gmsh::option::setNumber("Mesh.Algorithm", 6);
      gmsh::option::setNumber("Mesh.SubdivisionAlgorithm", opt.surface ? 1 : 2);  // all quads / all hexes
      gmsh::model::mesh::generate(dim);
      rep.method = "subdivision";
    }
    if (!(opt.surface ? only(2, 3) : (only(3, 5) && only(2, 3))))
      throw Error(ErrorKind::Geometry, cad_path + ": Gmsh's " + rep.method + " meshing did not give an all-" +
                                           (opt.surface ? "quad" : "hex") + " mesh");
    // Blocks per volume (surface mode: per surface), side sets per surface.
    gmsh::vectorpair ents;
    gmsh::model::getEntities(ents, dim);
    for (const auto& [d, t] : ents) {
      const int pg = gmsh::model::addPhysicalGroup(d, {t}, t);
      gmsh::model::setPhysicalName(d, pg, (d == 3 ? "volume_" : "surface_") + std::to_string(t));
    }
    if (!opt.surface) {
      gmsh::model::getEntities(ents, 2);
      for (const auto& [d, t] : ents) {
        const int pg = gmsh::model::addPhysicalGroup(d, {t}, t);
        gmsh::model::setPhysicalName(d, pg, "surface_" + std::to_string(t));
      }
    }
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::option::setNumber("Mesh.Binary", 0);
    gmsh::option::setNumber("Mesh.SaveAll", 0);
    gmsh::write(tmp.string());
    std::vector<std::size_t> nt;
    std::vector<double> xyz, par;
    gmsh::model::mesh::getNodes(nt, xyz, par, -1, -1, false, false);
    rep.vertices = static_cast<Id>(nt.size());
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> et, en;
    gmsh::model::mesh::getElements(types, et, en, dim, -1);
    for (const auto& v : et) rep.elements += static_cast<Id>(v.size());
  });
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  // Gmsh's subdivision can leave hexes inverted where a coarse size is large
  // against the curvature; dicer's own reader is the judge.
  try {
    (void)read_coarse_mesh(tmp.string());
  } catch (const Error& e) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw Error(ErrorKind::Geometry, cad_path + ": Gmsh's " + rep.method + " mesh at --size " + std::to_string(opt.size) +
                                         " is not valid (" + e.what() + "); try a smaller --size");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw Error(ErrorKind::Io, msh_path + ": cannot write the coarse mesh");
  }
  return rep;
}

}  // namespace dicer
