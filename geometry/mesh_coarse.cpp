// CAD -> coarse all-hex (or all-quad) mesh with Gmsh: transfinite where the
// CAD allows, Gmsh's all-hex subdivision otherwise.
#include <gmsh.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "cad.hpp"
#include "dicer/atomic_output.hpp"
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

// Distinct entities of a boundary.
size_t distinct(const gmsh::vectorpair& b) {
  std::set<int> tags;
  for (const auto& [d, t] : b) tags.insert(std::abs(t));
  return tags.size();
}

// Four sides: a seam may be two of them (a tube's side: two circles and its
// seam, twice), but a pole's degenerate curve is none (a sphere's one face
// lists its seam twice and two poles) and two seams are not four sides (a
// torus's face). `tiny`: a curve whose box is smaller is degenerate.
bool four_sided(int surface, double tiny) {
  gmsh::vectorpair curves;
  gmsh::model::getBoundary({{2, surface}}, curves, false, false, false);
  if (curves.size() != 4 || distinct(curves) < 3) return false;
  for (const auto& [d, t] : curves) {
    double x0, y0, z0, x1, y1, z1;
    gmsh::model::getBoundingBox(1, std::abs(t), x0, y0, z0, x1, y1, z1);
    if (std::max({x1 - x0, y1 - y0, z1 - z0}) < tiny) return false;
  }
  return true;
}

// Every surface 4-sided, and (volume) every volume bounded by 6 of them.
bool transfinite_shaped(int dim, double tiny) {
  gmsh::vectorpair ents;
  gmsh::model::getEntities(ents, dim);
  if (ents.empty()) return false;
  for (const auto& e : ents) {
    if (dim == 2 && !four_sided(e.second, tiny)) return false;
    if (dim == 3) {
      gmsh::vectorpair faces;
      gmsh::model::getBoundary({e}, faces, false, false, false);
      if (faces.size() != 6 || distinct(faces) != 6) return false;
      for (const auto& f : faces)
        if (!four_sided(std::abs(f.second), tiny)) return false;
    }
  }
  return true;
}

// At most this many coarse elements, estimated before Gmsh runs: a coarse
// mesh is small by purpose (dice refines it), and Gmsh asked for 1e9
// elements grows by hundreds of MB a second (1e7 quads took it a minute),
// while a size far below the model's tolerance gave one hex silently.
constexpr double kMaxCoarseElements = 5e6;
// Elements per size^3 (size^2) of the model's volume (area) when Gmsh
// subdivides: ~6 tetrahedra of edge `size` per size^3, 4 hexes each
// (measured: 18-19 on a sphere and a box); ~2.3 triangles per size^2, 3
// quads each (7.9 on a sphere). Transfinite: ~1.
constexpr double kSubdividedHexesPerCube = 20, kSubdividedQuadsPerSquare = 8;
}  // namespace

namespace {
// Everything after the CAD is read: its errors gain what OpenCASCADE said.
CoarseMeshReport mesh_from(const geometry::Cad& cad, const std::string& cad_path, const std::string& msh_path,
                           AtomicOutput& output, const CoarseMeshOptions& opt) {
  const int dim = opt.surface ? 2 : 3;
  if (!opt.surface && cad.entities(3).empty())
    throw Error(ErrorKind::Geometry, cad_path + ": the CAD model has no solid to fill with hexahedra (use --surface for a shell)");
  CoarseMeshReport rep;
  rep.volumes = static_cast<Id>(cad.entities(3).size());
  rep.surfaces = static_cast<Id>(cad.entities(2).size());
  // In surface mode a surface between two volumes would give edges of three
  // or four quads, which no dicing of a shell takes: the model's skin only.
  std::vector<int> skin;
  for (const auto& e : cad.entities(2))
    if (!opt.surface || e.up.size() < 2) skin.push_back(e.tag);
  rep.interfaces_left_out = static_cast<Id>(cad.entities(2).size() - skin.size());
  // Transfinite when every surface is a 4-sided patch and every volume is
  // bounded by 6 of them, decided before meshing: Gmsh 4.8 crashes when
  // asked to clear a failed transfinite attempt. Then the element count
  // expected from the model's volume (area), refused when huge.
  bool transfinite = false;
  double measure = 0;
  geometry::gmsh_call(ErrorKind::Geometry, cad_path + ": measuring the model", [&] {
    transfinite = !opt.subdivide && transfinite_shaped(dim, 1e-6 * std::max(cad.diagonal(), 1.0));
    std::vector<int> meshed = skin;
    if (!opt.surface) {
      meshed.clear();
      for (const auto& e : cad.entities(3)) meshed.push_back(e.tag);
    }
    for (const int t : meshed) {
      double m = 0;
      gmsh::model::occ::getMass(dim, t, m);
      measure += m;
    }
  });
  const double per = transfinite ? 1 : opt.surface ? kSubdividedQuadsPerSquare : kSubdividedHexesPerCube;
  const double estimate = std::max(1.0, per * std::abs(measure) / std::pow(opt.size, dim));
  if (estimate > kMaxCoarseElements)
    throw Error(ErrorKind::Usage, "--size " + geometry::fmt(opt.size) + " would make about " + geometry::fmt(estimate) + " coarse " +
                                      (opt.surface ? "quads" : "hexes") + " of " + cad_path + " (its " +
                                      (opt.surface ? "area " : "volume ") + geometry::fmt(std::abs(measure)) + " / size^" +
                                      std::to_string(dim) + (transfinite ? "" : ", times ~" + geometry::fmt(per) + " by Gmsh's subdivision") +
                                      "), more than " + geometry::fmt(kMaxCoarseElements) +
                                      ": a coarse mesh is meant to be small; give a larger --size and refine "
                                      "with dice --interval");
  // Gmsh's meshing of a damaged model may not end (a cylinder whose STEP
  // file lost one edge ran for minutes in its Delaunay): 300 s + 1 ms of
  // CPU time per expected element (Gmsh made 1.24e6 hexes in 61 s on a
  // 2-core VM, 0.05 ms each). The floor is large because the estimate
  // comes from the volume: a thin plate makes far more elements than its
  // volume says.
  const geometry::TimeLimit limit = geometry::time_limit(
      "DICER_CAD_MESH_SECONDS", 300.0 + 1e-3 * estimate,
      "300 s + 1 ms per expected element, about " + geometry::fmt(estimate) + " here");
  const auto generate = [&] {
    const geometry::TimedCall timed(ErrorKind::Geometry, limit.seconds,
                                    cad_path + ": Gmsh did not finish meshing the model at --size " + geometry::fmt(opt.size),
                                    limit.how, "Gmsh loops on some damaged models; check the model in Gmsh, or try another --size");
    gmsh::model::mesh::generate(dim);
  };
  // Gmsh needs the .msh extension to write MSH; the file is moved onto the
  // output's temporary once written.
  const std::string scratch = output.temp_path() + ".msh";
  try {
  geometry::gmsh_call(ErrorKind::Geometry, cad_path + ": Gmsh could not mesh the model", [&] {
    gmsh::option::setNumber("Mesh.MeshSizeMax", opt.size);
    gmsh::option::setNumber("Mesh.MeshSizeMin", 0.0);
    // Gmsh gives imported CAD points a size of its own (a fraction of the
    // model), which capped every larger --size.
    gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::option::setNumber("Mesh.ElementOrder", 1);
    if (transfinite) {
      gmsh::model::mesh::setTransfiniteAutomatic({}, 2.35, true);
      gmsh::option::setNumber("Mesh.RecombineAll", 1);
      gmsh::option::setNumber("Mesh.SubdivisionAlgorithm", 0);
      generate();
      rep.method = "transfinite";
    } else {
      // Triangles / tetrahedra, each split into quads / hexes. (Gmsh 4.8's
      // quad-oriented algorithm 8 segfaults on curved OpenCASCADE faces.)
      gmsh::option::setNumber("Mesh.RecombineAll", opt.surface ? 1 : 0);
      gmsh::option::setNumber("Mesh.Algorithm", 6);
      gmsh::option::setNumber("Mesh.SubdivisionAlgorithm", opt.surface ? 1 : 2);  // all quads / all hexes
      generate();
      rep.method = "subdivision";
    }
    if (!(opt.surface ? only(2, 3) : (only(3, 5) && only(2, 3))))
      throw Error(ErrorKind::Geometry, cad_path + ": Gmsh's " + rep.method + " meshing did not give an all-" +
                                           (opt.surface ? "quad" : "hex") + " mesh");
    // Blocks per volume (surface mode: per surface of the skin), side sets
    // per surface. Only elements of physical groups are written (SaveAll 0).
    if (!opt.surface) {
      gmsh::vectorpair ents;
      gmsh::model::getEntities(ents, 3);
      for (const auto& [d, t] : ents) {
        const int pg = gmsh::model::addPhysicalGroup(d, {t}, t);
        gmsh::model::setPhysicalName(d, pg, "volume_" + std::to_string(t));
      }
    }
    for (const int t : skin) {
      const int pg = gmsh::model::addPhysicalGroup(2, {t}, t);
      gmsh::model::setPhysicalName(2, pg, "surface_" + std::to_string(t));
    }
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::option::setNumber("Mesh.Binary", 0);
    gmsh::option::setNumber("Mesh.SaveAll", 0);
    gmsh::write(scratch);
    // Gmsh does not check its writes: past the file size limit (ulimit -f,
    // with SIGXFSZ ignored) the file is cut short without a word, and dicer's
    // reader then blamed the mesh.
    struct rlimit fsize {};
    std::error_code ec;
    const auto written = std::filesystem::file_size(scratch, ec);
    if (!ec && ::getrlimit(RLIMIT_FSIZE, &fsize) == 0 && fsize.rlim_cur != RLIM_INFINITY && written >= fsize.rlim_cur)
      throw Error(ErrorKind::Io, msh_path + ": cannot write the coarse mesh: it reached the file size limit (ulimit -f) of " +
                                     std::to_string(static_cast<unsigned long long>(fsize.rlim_cur)) + " bytes");
  });
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(scratch, ec);
    throw;
  }
  {
    std::error_code ec;
    std::filesystem::rename(scratch, output.temp_path(), ec);
    if (ec) {
      std::filesystem::remove(scratch, ec);
      throw Error(ErrorKind::Io, msh_path + ": cannot write the coarse mesh (" + ec.message() + ")");
    }
  }
  // Gmsh's subdivision can leave hexes inverted where a coarse size is large
  // against the curvature; dicer's own reader is the judge, and counts what
  // was written.
  try {
    const CoarseMesh written = read_coarse_mesh(output.temp_path());
    rep.vertices = written.num_vertices();
    rep.elements = written.num_elements();
  } catch (const Error& e) {
    std::string why = e.what();
    for (size_t at = why.find(output.temp_path()); at != std::string::npos; at = why.find(output.temp_path()))
      why.replace(at, output.temp_path().size(), "the mesh");
    throw Error(ErrorKind::Geometry, cad_path + ": Gmsh's " + rep.method + " mesh at --size " + geometry::fmt(opt.size) +
                                         " is not valid (" + why + "); try a smaller --size");
  }
  return rep;
}
}  // namespace

CoarseMeshReport mesh_coarse(const std::string& cad_path, const std::string& msh_path, const CoarseMeshOptions& opt) {
  if (!(opt.size > 0) || !std::isfinite(opt.size))
    throw Error(ErrorKind::Usage, "--size must be a positive element size");
  AtomicOutput output(msh_path);  // a folder that cannot be written is said before Gmsh runs
  const geometry::Cad cad(cad_path);  // checks the file, loads it as dicing will (same tags)
  CoarseMeshReport rep = cad.with_reader_said([&] { return mesh_from(cad, cad_path, msh_path, output, opt); });
  rep.cad_reader_said = cad.reader_said();
  output.commit();
  return rep;
}

}  // namespace dicer
