#include "gmsh_transfinite.hpp"

#include "dicer/rows.hpp"

#include <gmsh.h>

#include <exception>
#include <stdexcept>
#include <unordered_map>

namespace dicer::bench {
namespace {

// Gmsh 4.8 reports errors by throwing (General.AbortOnError = 2 under the
// API); what it throws has varied between versions.
template <class F>
void gmsh_call(const char* what, F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("gmsh ") + what + ": " + e.what());
  } catch (const std::string& s) {
    throw std::runtime_error(std::string("gmsh ") + what + ": " + s);
  } catch (...) {
    throw std::runtime_error(std::string("gmsh ") + what + " failed");
  }
}

}  // namespace

TransfiniteInput transfinite_input(const FineMesh& mesh, Id first_coarse, Id end_coarse) {
  if (mesh.mode() != Mode::Volume) throw std::runtime_error("transfinite_input: volume meshes only");
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  TransfiniteInput in;
  std::unordered_map<Id, int> point_of, line_of, face_of;  // table row -> 0-based local index
  auto point = [&](Id v) {
    auto [it, fresh] = point_of.try_emplace(v, static_cast<int>(point_of.size()));
    if (fresh) {
      const Vec3 p = R.xyz(v);
      in.xyz.insert(in.xyz.end(), {p.x, p.y, p.z});
    }
    return it->second;
  };
  auto edge_row = [&](Id e) { return R.edge(e); };
  auto line = [&](Id e) {
    auto [it, fresh] = line_of.try_emplace(e, static_cast<int>(in.lines.size()));
    if (fresh) {
      const EdgeRow r = edge_row(e);
      in.lines.push_back({point(r.lo), point(r.hi), r.n});
    }
    return it->second;
  };
  // Signed 1-based tag of line e traversed from vertex a to vertex b.
  auto signed_line = [&](Id e, Id a, Id b) {
    const EdgeRow r = edge_row(e);
    const int tag = line(e) + 1;
    if (r.lo == a && r.hi == b) return tag;
    if (r.lo == b && r.hi == a) return -tag;
    throw std::runtime_error("transfinite_input: edge " + std::to_string(e) + " does not join its face's corners");
  };
  auto face = [&](Id f) {
    auto [it, fresh] = face_of.try_emplace(f, static_cast<int>(in.faces.size()));
    if (fresh) {
      const FaceRow r = R.face(f);
      const auto& v = r.v;
      const auto& e = r.e;
      // sides: e0 = v0v1, e1 = v3v2, e2 = v0v3, e3 = v1v2; loop v0 v1 v2 v3
      in.faces.push_back({signed_line(e[0], v[0], v[1]), signed_line(e[3], v[1], v[2]), signed_line(e[1], v[2], v[3]),
                          signed_line(e[2], v[3], v[0])});
    }
    return it->second;
  };
  for (Id h = first_coarse; h < end_coarse; ++h) {
    const ElementRow r = R.element(h);
    const auto& n = r.n;
    std::array<int, 6> hex{};
    for (int q = 0; q < 6; ++q) hex[q] = face(r.face[q]);
    in.hexes.push_back(hex);
    in.fine_hexes += n[0] * n[1] * n[2];
  }
  return in;
}

GmshSession::GmshSession() {
  gmsh_call("initialize", [] {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("General.Verbosity", 1);
    gmsh::option::setNumber("General.NumThreads", 1);
    gmsh::model::add("dicer-bench");
  });
}

GmshSession::~GmshSession() {
  try {
    gmsh::finalize();
  } catch (...) {
  }
}

void GmshSession::build(const TransfiniteInput& in) {
  gmsh_call("build", [&] {
    namespace geo = gmsh::model::geo;
    for (size_t p = 0; p < in.xyz.size() / 3; ++p)
      geo::addPoint(in.xyz[3 * p], in.xyz[3 * p + 1], in.xyz[3 * p + 2], 0.0, static_cast<int>(p) + 1);
    for (size_t l = 0; l < in.lines.size(); ++l) {
      const int tag = static_cast<int>(l) + 1;
      geo::addLine(static_cast<int>(in.lines[l][0]) + 1, static_cast<int>(in.lines[l][1]) + 1, tag);
      geo::mesh::setTransfiniteCurve(tag, static_cast<int>(in.lines[l][2]) + 1);
    }
    for (size_t f = 0; f < in.faces.size(); ++f) {
      const int tag = static_cast<int>(f) + 1;
      const auto& loop = in.faces[f];
      geo::addCurveLoop({loop[0], loop[1], loop[2], loop[3]}, tag);
      geo::addSurfaceFilling({tag}, tag);  // coarse faces need not be planar
      geo::mesh::setTransfiniteSurface(tag);
      geo::mesh::setRecombine(2, tag);
    }
    for (size_t h = 0; h < in.hexes.size(); ++h) {
      const int tag = static_cast<int>(h) + 1;
      std::vector<int> shell;
      for (int f : in.hexes[h]) shell.push_back(f + 1);
      geo::addSurfaceLoop(shell, tag);
      geo::addVolume({tag}, tag);
      geo::mesh::setTransfiniteVolume(tag);
    }
    geo::synchronize();
  });
}

void GmshSession::generate() {
  gmsh_call("generate", [] { gmsh::model::mesh::generate(3); });
}

void GmshSession::write_msh(const std::string& path, bool binary) {
  gmsh_call("write", [&] {
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::option::setNumber("Mesh.Binary", binary ? 1 : 0);
    gmsh::write(path);
  });
}

GmshSession::Counts GmshSession::counts() const {
  Counts c;
  gmsh_call("counts", [&] {
    gmsh::vectorpair entities;
    gmsh::model::getEntities(entities);
    std::vector<std::size_t> node_tags;
    std::vector<double> coord, param;
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> elem_tags, elem_nodes;
    for (const auto& [dim, tag] : entities) {
      gmsh::model::mesh::getNodes(node_tags, coord, param, dim, tag, false, false);
      c.nodes += static_cast<std::int64_t>(node_tags.size());
      gmsh::model::mesh::getElements(types, elem_tags, elem_nodes, dim, tag);
      for (size_t i = 0; i < types.size(); ++i) {
        c.elements += static_cast<std::int64_t>(elem_tags[i].size());
        if (types[i] == 5) c.hexes += static_cast<std::int64_t>(elem_tags[i].size());  // 8-node hexahedron
      }
    }
  });
  return c;
}

}  // namespace dicer::bench
