#pragma once
// Geometry-conforming dicing: the fine mesh follows the CAD model, not the
// coarse facets (the paper's Figure 2). Library dicer_geometry, the only
// part of dicer that links Gmsh (OpenCASCADE underneath); a store written
// with it is read and queried without Gmsh (the moved nodes are in its
// bounding arrays, tables.hpp).
//
// The steps, in the order the paper requires:
//  1. Owners. Coarse faces that can lie on the CAD (boundary faces,
//     interfaces between blocks, faces whose corners the MSH file classified
//     on surfaces) and their vertices and edges are given the lowest-
//     dimensional CAD entity they lie on. A vertex keeps its MSH
//     classification when that entity exists in the CAD and the vertex is
//     within tolerance of it; otherwise it is matched geometrically (points,
//     then curves, then surfaces within tolerance), so a STEP file whose
//     tags OpenCASCADE renumbered still fits. An edge or face takes the
//     lowest entity common to its corners' closures whose geometry passes
//     through its midpoint. A boundary vertex, edge or face that fits
//     nothing, or a CAD surface with no face on it, is refused
//     (Error{Geometry}) naming the entity and the distance.
//  2. Vertices are snapped onto their entity.
//  3. Edge nodes on curves (and on surfaces) move first, then face nodes;
//     hex interiors need no move: their TFI reads the moved boundary.
//     Method: interpolate in the entity's parameter space between the ends
//     at the sheet's grid parameters (tfi::Series: equal steps, or the
//     sheet's graded series) (edges) or by a Coons patch of the moved
//     boundary's parameters at the face's graded parameters (faces), then
//     evaluate there, which keeps the spacing the TFI would give in the
//     parameters. Periodic parameters (a circle, a cylinder's angle, a
//     torus) are unwrapped across the seam. Where that fails (a degenerate
//     pole such as a sphere's, a face spanning more than half a period, a
//     parametrisation far from arc length), the node's TFI prediction is
//     projected to the closest point instead. The choice is made once per
//     entity from probes at fixed parameters (k/8 along an edge, (i/8, j/8)
//     on a face; parameters within a quarter of the probe spacing of the
//     closest points pass), never from the interval or the grading, so two
//     dicings whose intervals are multiples of each other place every node
//     they share identically (nested levels, transfer.hpp). An entity whose
//     probes already lie on the CAD (within 1e-12 of the diagonal) is not
//     moved. Lines and planes need no move and no storage.
//  4. Every fine element of a coarse element with moved nodes is checked:
//     a non-positive scaled Jacobian is refused (Error{Geometry}) naming the
//     element, never written.
#include <functional>
#include <string>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"

namespace dicer {

struct ConformOptions {
  // A coarse vertex must lie within tolerance * (CAD bounding-box diagonal)
  // of its entity.
  double tolerance = 1e-4;
  std::function<void(const char* stage, Id done, Id total)> progress;
  // Shared out over `parts` processes (mpirun): every part runs with the
  // same mesh and CAD, places every parts-th candidate edge and face and
  // checks every parts-th coarse element, and `share` hands each part the
  // bytes of all parts in part order (mpi::allgather_bytes). Every part
  // ends with the same moves, report and store bits as one process. An
  // error on any part is kept until the next exchange, so no part waits
  // for one that failed, and every part throws the one at the lowest
  // entity. Three exchanges: edges, faces, the quality check.
  int part = 0, parts = 1;
  std::function<std::vector<std::string>(const std::string&)> share;
};

struct ConformReport {
  double diagonal = 0;                 // of the CAD's bounding box
  Id vertices_on_cad = 0;              // coarse vertices given a point, curve or surface
  double max_vertex_snap = 0;          // largest distance a coarse vertex moved
  Id edges_on_curves = 0, edges_on_surfaces = 0, faces_on_surfaces = 0;
  Id edges_moved = 0, faces_moved = 0; // non-flat entities whose nodes moved
  Id closest_point_fallbacks = 0;      // entities projected instead of interpolated in parameters
  Id bounding_nodes = 0;
  double min_scaled_jacobian = 1;      // over the elements of coarse elements with moved nodes
  Id elements_checked = 0;
  bool tags_matched = false;           // every classified vertex kept its MSH entity
  // What OpenCASCADE reported reading the CAD file (one line; empty for a
  // sound file): a complaint means the model may be missing parts.
  std::string cad_reader_said;
};

// Moves the boundary of a mesh diced in this process onto the CAD file
// (STEP or BREP). Throws Error{Geometry} for a mismatch or an inversion,
// Error{Io|BadInput|Unsupported} for an unreadable CAD file.
ConformReport conform_to_geometry(FineMesh& mesh, const std::string& cad_path, const ConformOptions& options = {});

// The CAD's classification of a coarse mesh, for intervals by entity
// (intervals.hpp): boundary vertices get the CAD entity conform_to_geometry
// would give them (vertex_geo_dim/tag), interior ones the CAD's volume
// when it has one (else the file's volume classification, if the CAD has
// that volume), and geo_entities the CAD's topology, so that tags name the
// CAD's entities. Costs what conform's vertex matching costs. Errors as
// conform_to_geometry's for a mesh that does not fit.
void classify_on_geometry(CoarseMesh& mesh, const std::string& cad_path, const ConformOptions& options = {});

struct GeometryCheck {
  double diagonal = 0;
  double max_distance = 0;   // largest distance of a fine node on a curve or surface from it
  Id worst_node = -1;        // fine node id where it is
  std::string worst_entity;  // e.g. "surface 3"
  Id nodes_checked = 0;
  double tolerance = 0;      // documented bound: max(1e-9 * diagonal, kKernelTolerance)
  // Boundary coarse faces (volume; surface: every face) the store puts on
  // no CAD surface (a store diced without the CAD): their fine nodes are
  // measured against the nearest surface.
  Id unplaced_faces = 0;
  std::string cad_reader_said;  // as ConformReport's
  bool ok() const { return max_distance <= tolerance && nodes_checked > 0; }
};
// OpenCASCADE's Precision::Confusion(), the distance under which its
// projections call two points the same.
inline constexpr double kKernelTolerance = 1e-7;

// Distance of every fine node on a CAD curve or surface (owners as stored)
// from that entity, and of the interior nodes of boundary faces the store
// puts on no surface from the nearest one (bounding boxes pick the candidates; every
// surface for a node outside them all). Works on a store.
// progress(done, total) in coarse entities.
GeometryCheck check_geometry(const FineMesh& mesh, const std::string& cad_path,
                             const std::function<void(Id, Id)>& progress = {});

struct CoarseMeshOptions {
  double size = 0;         // target coarse element size (> 0)
  bool surface = false;    // all-quad surface mesh instead of all-hex volume mesh
  bool subdivide = false;  // skip the transfinite attempt
};
struct CoarseMeshReport {
  std::string method;      // "transfinite" or "subdivision"
  Id vertices = 0, elements = 0, volumes = 0, surfaces = 0;
  Id interfaces_left_out = 0;  // surface mode: surfaces between two volumes, not meshed
  std::string cad_reader_said;  // as ConformReport's
};
// CAD -> coarse all-hex (or all-quad) mesh with Gmsh, written as MSH 4.1
// with a physical group per volume (blocks) and per surface (side sets) and
// node classification, ready for `dicer dice --geometry` with the same CAD.
// Transfinite where every volume (surface) admits it, else Gmsh's all-hex
// (all-quad) subdivision. Surface mode meshes the model's skin: a surface
// between two volumes is left out (its edges would have three quads).
// Error{Usage} for a size that would make more than 5e6 coarse elements
// (estimated from the model's volume or area and the method, before Gmsh
// runs), Error{Io} for an
// output folder that cannot be written, Error{Geometry} where Gmsh fails
// or its mesh is not valid for dicing. Gmsh keeps state between models: a
// second call in one process may size curves otherwise (Gmsh 4.11 put 3
// elements on every curve of a box meshed a second time, whatever the
// size); dicer-cad makes one call per process.
CoarseMeshReport mesh_coarse(const std::string& cad_path, const std::string& msh_path, const CoarseMeshOptions& options);

// For a crash handler and a watchdog (both async-signal-safe). While
// OpenCASCADE reads a CAD file, the standard streams (fds 1 and 2) go to an
// in-memory file, as its readers print their complaints there in colour
// and not through Gmsh; dicer's messages then say them (an unreadable
// file's error, the reports' cad_reader_said), so a handler must write to
// a copy of fd 2 it made before. cad_reader_said() copies what OpenCASCADE
// said in the read under way, or else the last one, cleaned to one line,
// into buf (NUL-terminated) and returns its length.
size_t cad_reader_said(char* buf, size_t cap) noexcept;
// For a watchdog. Gmsh and OpenCASCADE calls that can run for ever on a
// damaged model are timed, and nothing stops them from inside:
// OpenCASCADE's BREP reader looped for hours on truncated files, Gmsh's
// meshing of a cylinder whose STEP file lost one edge did not end. A CAD
// file's read gets 30 s + 60 s per MiB of the file (DICER_CAD_READ_SECONDS
// sets it), mesh_coarse's meshing 60 s + 1 ms per coarse element it expects
// (DICER_CAD_MESH_SECONDS). When the call under way has run past its limit,
// claims it and returns true with the error in words (naming the file, the
// time, the limit, what OpenCASCADE reported) and its kind (BadInput for a
// read, Geometry for meshing): the call then never returns (it waits for
// the process to end), so the caller must say so and end the process
// (dicer-cad's watchdog thread, cli/cad/with.cpp). Thread-safe.
bool cad_claim_overdue(std::string& message, ErrorKind& kind);

}  // namespace dicer
