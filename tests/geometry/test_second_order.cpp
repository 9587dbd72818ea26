// Second-order coarse meshes made by Gmsh inside the test (HEX20, HEX27,
// QUAD8, QUAD9 of a cylinder: an O-grid, transfinite and extruded, whose
// second-order nodes Gmsh puts on the circle), read from MSH 4.1, 2.2 and
// 1 and from Exodus files written here with the Exodus library. The
// expected positions are Gmsh's own basis functions of each element
// (getBasisFunctions) and the true cylinder, never dicer's arithmetic; the
// node orders in orientation.hpp are checked against Gmsh's
// getElementProperties and the Exodus library's side node lists.
#include <exodusII.h>
#include <gmsh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "access_paths.hpp"
#include "cad.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"
#include "dicer/orientation.hpp"
#include "dicer/quadratic.hpp"
#include "dicer/quality.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/verify.hpp"
#include "test_support.hpp"

namespace dicer {
namespace {

using test::TempDir;

// ---------------------------------------------------------------- node orders

// Where a slot sits in the unit element, in halves (orientation.hpp's
// slot layout from its corner tables).
std::array<int, 3> slot_position(Mode mode, int s) {
  std::vector<int> corners;
  if (mode == Mode::Surface) {
    corners = s < 4 ? std::vector<int>{kQuadEdge[s][0], kQuadEdge[s][1]} : std::vector<int>{0, 1, 2, 3};
  } else if (s < 12) {
    corners = {kHexEdge[s][0], kHexEdge[s][1]};
  } else if (s < 18) {
    corners.assign(kHexFace[s - 12], kHexFace[s - 12] + 4);
  } else {
    corners = {0, 1, 2, 3, 4, 5, 6, 7};
  }
  std::array<int, 3> r{0, 0, 0};
  for (int c : corners)
    for (int d = 0; d < 3; ++d) r[d] += 2 * kHexCorner[c][d];
  for (int& v : r) v /= static_cast<int>(corners.size());
  return r;
}

TEST(SecondOrderNodeOrder, GmshTypesAsGmshPlacesTheirNodes) {
  geometry::gmsh_start();
  for (const int type : {17, 12, 16, 10}) {
    SCOPED_TRACE("type " + std::to_string(type));
    std::string name;
    int dim = 0, order = 0, nodes = 0, primary = 0;
    std::vector<double> local;
    gmsh::model::mesh::getElementProperties(type, name, dim, order, nodes, local, primary);
    const Mode mode = dim == 3 ? Mode::Volume : Mode::Surface;
    ASSERT_EQ(order, 2);
    // Gmsh's reference element is [-1, 1]^dim; in halves of [0, 1]: x + 1.
    auto at = [&](int k) {
      std::array<int, 3> r{0, 0, 0};
      for (int d = 0; d < dim; ++d) r[d] = static_cast<int>(std::lround(local[dim * k + d])) + 1;
      return r;
    };
    for (int k = 0; k < primary; ++k) {
      const std::array<int, 3> c{2 * kHexCorner[k][0], 2 * kHexCorner[k][1], dim == 3 ? 2 * kHexCorner[k][2] : 0};
      EXPECT_EQ(at(k), c) << "corner " << k;
    }
    for (int k = primary; k < nodes; ++k) {
      const int s = mid_slot(NodeOrder::Gmsh, mode, k);
      ASSERT_GE(s, 0) << "node " << k;
      EXPECT_EQ(slot_position(mode, s), at(k)) << "node " << k;
    }
    EXPECT_EQ(mid_slot(NodeOrder::Gmsh, mode, mode == Mode::Volume ? 27 : 9), -1);
  }
}

// The Exodus library's own tables: the nodes of each side of an element
// whose connectivity is 1..N are the side's local node numbers, corners in
// order with the mid-edge nodes between them, then the face's centre.
TEST(SecondOrderNodeOrder, ExodusTypesAsTheExodusLibraryListsTheirSides) {
  TempDir tmp;
  struct T {
    const char* type;
    int nodes, sides, first_side;  // Exodus sides to ask about (1-based)
  };
  // (Exodus 6.02 lists only the corners of a SHELL9's faces and sides: its
  // order is QUAD9's, checked here.)
  for (const T t : {T{"HEX20", 20, 6, 1}, T{"HEX27", 27, 6, 1}, T{"QUAD8", 8, 4, 1}, T{"QUAD9", 9, 4, 1},
                    T{"SHELL8", 8, 6, 1}}) {
    SCOPED_TRACE(t.type);
    const bool vol = t.nodes >= 20;
    const Mode mode = vol ? Mode::Volume : Mode::Surface;
    const std::string path = tmp.path(std::string(t.type) + ".e");
    int cpu = 8, io = 8;
    int id = ex_create(path.c_str(), EX_CLOBBER, &cpu, &io);
    ASSERT_GE(id, 0);
    std::vector<double> x(t.nodes), y(t.nodes, 0.0), z(t.nodes, 0.0);
    for (int i = 0; i < t.nodes; ++i) x[i] = i;
    ASSERT_EQ(ex_put_init(id, "order", 3, t.nodes, 1, 1, 0, t.sides - t.first_side + 1), 0);
    ASSERT_EQ(ex_put_coord(id, x.data(), y.data(), z.data()), 0);
    ASSERT_EQ(ex_put_block(id, EX_ELEM_BLOCK, 1, t.type, 1, t.nodes, 0, 0, 0), 0);
    std::vector<int> conn(t.nodes);
    for (int i = 0; i < t.nodes; ++i) conn[i] = i + 1;
    ASSERT_EQ(ex_put_conn(id, EX_ELEM_BLOCK, 1, conn.data(), nullptr, nullptr), 0);
    for (int s = t.first_side; s <= t.sides; ++s) {
      int e = 1, side = s;
      ASSERT_EQ(ex_put_set_param(id, EX_SIDE_SET, s, 1, 0), 0);
      ASSERT_EQ(ex_put_set(id, EX_SIDE_SET, s, &e, &side), 0);
    }
    ex_close(id);
    float version = 0;
    id = ex_open(path.c_str(), EX_READ, &cpu, &io, &version);
    ASSERT_GE(id, 0);
    int checked = 0;
    for (int s = t.first_side; s <= t.sides; ++s) {
      int count[2] = {0, 0}, nodes[16] = {};
      ASSERT_EQ(ex_get_side_set_node_list(id, s, count, nodes), 0);
      const int n = count[0];
      // A hex or quad-shell face: 4 corners, 4 mid-edge nodes, maybe a
      // centre; an edge (quad sides, shell sides 3..6): 2 corners, 1 middle.
      const int corners = n >= 8 ? 4 : n == 3 ? 2 : 0;
      ASSERT_GT(corners, 0) << "side " << s << " lists " << n << " nodes";
      for (int q = 0; q < corners && corners == 4; ++q) {
        const int a = nodes[q] - 1, b = nodes[(q + 1) % 4] - 1, m = nodes[4 + q] - 1;
        const int slot = mid_slot(NodeOrder::Exodus, mode, m);
        ASSERT_GE(slot, 0) << "side " << s << " node " << m;
        std::array<int, 3> want{kHexCorner[a][0] + kHexCorner[b][0], kHexCorner[a][1] + kHexCorner[b][1],
                                kHexCorner[a][2] + kHexCorner[b][2]};
        EXPECT_EQ(slot_position(mode, slot), want) << "side " << s << " node " << m;
        ++checked;
      }
      if (corners == 2) {
        const int a = nodes[0] - 1, b = nodes[1] - 1, m = nodes[2] - 1;
        const int slot = mid_slot(NodeOrder::Exodus, mode, m);
        ASSERT_GE(slot, 0);
        EXPECT_EQ(slot_position(mode, slot), (std::array<int, 3>{kHexCorner[a][0] + kHexCorner[b][0],
                                                                kHexCorner[a][1] + kHexCorner[b][1], 0}));
        ++checked;
      }
      if (n == 9) {  // the face's centre
        std::array<int, 3> want{0, 0, 0};
        for (int q = 0; q < 4; ++q)
          for (int d = 0; d < 3; ++d) want[d] += kHexCorner[nodes[q] - 1][d];
        for (int& v : want) v /= 2;
        EXPECT_EQ(slot_position(mode, mid_slot(NodeOrder::Exodus, mode, nodes[8] - 1)), want) << "side " << s;
        ++checked;
      }
    }
    ex_close(id);
    EXPECT_GT(checked, 3);
  }
  // The one node no side lists: the HEX27's centre.
  EXPECT_EQ(mid_slot(NodeOrder::Exodus, Mode::Volume, 20), 18);
}

// ---------------------------------------------------------------- the cylinder

// A unit cylinder (z in [0, 2]) as a Gmsh O-grid: a square core and four
// blocks out to the circle, n cells per quarter circle, n / 2 radially,
// n layers; transfinite, recombined, extruded: all hexes (surface: the
// side wall only, all quads). Element order 2 (incomplete: HEX20, QUAD8)
// puts the new nodes on the circle. Left in the current Gmsh model.
void cylinder_mesh(int n, bool surface, bool incomplete) {
  namespace g = gmsh::model::geo;
  gmsh::model::add("cylinder");
  const double a = 0.45, pi = std::acos(-1.0);
  const int c = g::addPoint(0, 0, 0);
  std::vector<int> sq, ci, sides, arcs, rad;
  for (int k = 0; k < 4; ++k) {
    const double t = pi / 4 + k * pi / 2;
    sq.push_back(g::addPoint(a * std::sqrt(2.0) * std::cos(t), a * std::sqrt(2.0) * std::sin(t), 0));
    ci.push_back(g::addPoint(std::cos(t), std::sin(t), 0));
  }
  for (int k = 0; k < 4; ++k) {
    arcs.push_back(g::addCircleArc(ci[k], c, ci[(k + 1) % 4]));
    g::mesh::setTransfiniteCurve(arcs.back(), n + 1);
  }
  gmsh::vectorpair base, out;
  if (surface) {
    for (int l : arcs) base.push_back({1, l});
  } else {
    for (int k = 0; k < 4; ++k) {
      sides.push_back(g::addLine(sq[k], sq[(k + 1) % 4]));
      rad.push_back(g::addLine(sq[k], ci[k]));
      g::mesh::setTransfiniteCurve(sides.back(), n + 1);
      g::mesh::setTransfiniteCurve(rad.back(), n / 2 + 1);
    }
    std::vector<int> surfaces{g::addPlaneSurface({g::addCurveLoop(sides)})};
    for (int k = 0; k < 4; ++k)
      surfaces.push_back(g::addPlaneSurface({g::addCurveLoop({sides[k], rad[(k + 1) % 4], -arcs[k], -rad[k]})}));
    for (int s : surfaces) {
      g::mesh::setTransfiniteSurface(s);
      g::mesh::setRecombine(2, s);
      base.push_back({2, s});
    }
  }
  g::extrude(base, 0, 0, 2, out, {n}, {}, true);
  g::synchronize();
  gmsh::vectorpair top;
  gmsh::model::getEntities(top, surface ? 2 : 3);
  std::vector<int> tags;
  for (const auto& [d, t] : top) tags.push_back(t);
  gmsh::model::addPhysicalGroup(surface ? 2 : 3, tags, 1);
  gmsh::option::setNumber("Mesh.ElementOrder", 2);
  gmsh::option::setNumber("Mesh.SecondOrderIncomplete", incomplete ? 1 : 0);
  gmsh::model::mesh::generate(surface ? 2 : 3);
}

void write_msh(const std::string& path, double version, bool binary) {
  gmsh::option::setNumber("Mesh.MshFileVersion", version);
  gmsh::option::setNumber("Mesh.Binary", binary ? 1 : 0);
  gmsh::write(path);
}

// Writes the current model as ASCII MSH 4.1 and replaces it by that file,
// so Gmsh then holds the coordinates as written (ASCII keeps 16 digits,
// not always the double Gmsh computed).
void write_and_reopen(const std::string& path) {
  write_msh(path, 4.1, false);
  gmsh::model::remove();
  gmsh::open(path);
}

// The model's elements of the mesh's dimension, as Gmsh holds them.
struct GmshElements {
  int type = 0, nodes = 0, dim = 0;
  std::vector<double> local;                 // reference coordinates of the element's nodes
  std::map<std::size_t, std::vector<std::size_t>> node_tags;  // element tag -> its node tags
  std::map<std::size_t, Vec3> xyz;           // node tag -> coordinates
};

GmshElements gmsh_elements(int dim) {
  GmshElements g;
  g.dim = dim;
  std::vector<int> types;
  gmsh::model::mesh::getElementTypes(types, dim);
  EXPECT_EQ(types.size(), 1u);
  g.type = types.at(0);
  std::string name;
  int edim = 0, order = 0, primary = 0;
  gmsh::model::mesh::getElementProperties(g.type, name, edim, order, g.nodes, g.local, primary);
  std::vector<std::size_t> tags, nodes;
  gmsh::model::mesh::getElementsByType(g.type, tags, nodes);
  for (size_t e = 0; e < tags.size(); ++e)
    g.node_tags[tags[e]].assign(nodes.begin() + static_cast<std::ptrdiff_t>(e * g.nodes),
                                nodes.begin() + static_cast<std::ptrdiff_t>((e + 1) * g.nodes));
  std::vector<std::size_t> ntags;
  std::vector<double> coord, param;
  gmsh::model::mesh::getNodes(ntags, coord, param, -1, -1, true, false);
  for (size_t i = 0; i < ntags.size(); ++i) g.xyz[ntags[i]] = {coord[3 * i], coord[3 * i + 1], coord[3 * i + 2]};
  return g;
}

struct BoundaryCheck {
  double worst_vs_gmsh = 0;   // largest distance of a fine boundary node from Gmsh's element map
  double worst_radius = 0;    // largest | r - 1 | of fine nodes on coarse faces on the side wall
  double worst_position = 0;  // largest distance of those from the exact point at their parameters
  Id points = 0, wall_points = 0;
};

// Every grid point on the boundary of every coarse element against Gmsh's
// own map of that element (its Lagrange / serendipity basis at the point's
// reference coordinates), and the side wall's against the true cylinder.
BoundaryCheck check_boundary(const FineMesh& f, const GmshElements& g) {
  BoundaryCheck out;
  const bool vol = f.mode() == Mode::Volume;
  const int nc = vol ? 8 : 4;
  MeshCursor cur;
  const RowReader R(f.tables(), cur);
  FineBlock b;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    const Id tag = R.element(h).file_id;
    const auto& tags = g.node_tags.at(static_cast<std::size_t>(tag));
    // Which Gmsh corner each of dicer's corners is (dicer may have
    // reoriented a left-handed file): by position.
    Vec3 corner[8];
    R.corner_xyz(h, corner);
    int gc[8];
    for (int q = 0; q < nc; ++q) {
      gc[q] = -1;
      for (int k = 0; k < nc; ++k) {
        const Vec3 p = g.xyz.at(tags[k]);
        if (p.x == corner[q].x && p.y == corner[q].y && p.z == corner[q].z) gc[q] = k;
      }
      EXPECT_GE(gc[q], 0);
      if (gc[q] < 0) return out;
    }
    auto ref = [&](int k, int d) { return d < g.dim ? g.local[g.dim * k + d] : 0.0; };
    f.fill_block(h, b);
    std::vector<double> pts;
    std::vector<Id> index;
    for (Id k = 0; k <= (vol ? b.n[2] : 0); ++k)
      for (Id j = 0; j <= b.n[1]; ++j)
        for (Id i = 0; i <= b.n[0]; ++i) {
          if (!(i == 0 || i == b.n[0] || j == 0 || j == b.n[1] || (vol && (k == 0 || k == b.n[2])))) continue;
          // dicer's local parameters -> Gmsh's reference coordinates: the
          // affine map taking dicer's corners 0, 1, 3, 4 to Gmsh's.
          const double u = static_cast<double>(i) / b.n[0], v = static_cast<double>(j) / b.n[1],
                       w = vol ? static_cast<double>(k) / b.n[2] : 0.0;
          for (int d = 0; d < 3; ++d)
            pts.push_back(ref(gc[0], d) + u * (ref(gc[1], d) - ref(gc[0], d)) + v * (ref(gc[3], d) - ref(gc[0], d)) +
                          (vol ? w * (ref(gc[4], d) - ref(gc[0], d)) : 0.0));
          index.push_back(b.point_index(i, j, k));
        }
    int components = 0, orientations = 0;
    std::vector<double> basis;
    gmsh::model::mesh::getBasisFunctions(g.type, pts, "Lagrange", components, basis, orientations);
    for (size_t p = 0; p < index.size(); ++p) {
      Vec3 want{0, 0, 0};
      for (int a = 0; a < g.nodes; ++a) {
        const double wgt = basis[p * g.nodes + a];
        const Vec3 x = g.xyz.at(tags[a]);
        want = {want.x + wgt * x.x, want.y + wgt * x.y, want.z + wgt * x.z};
      }
      const Id q = index[p];
      out.worst_vs_gmsh = std::max(out.worst_vs_gmsh, std::hypot(b.x[q] - want.x, b.y[q] - want.y, b.z[q] - want.z));
      ++out.points;
    }
    // The side wall: coarse facets whose corners are all on the circle. A
    // point's exact place there is where the facet's parameters put it in
    // (angle, z), bilinear between the corners (the wall is flat in them).
    for (int lf = 0; lf < (vol ? 6 : 1); ++lf) {
      int h4[4] = {0, 1, 2, 3};  // surface: the quad's corners
      if (vol) std::copy(kHexFace[lf], kHexFace[lf] + 4, h4);
      bool round = true;
      double phi[4], z[4];
      for (int m = 0; m < 4; ++m) {
        const Vec3 p = corner[h4[m]];
        round = round && std::abs(std::hypot(p.x, p.y) - 1) < 1e-9;
        phi[m] = std::atan2(p.y, p.x), z[m] = p.z;
        const double pi = std::acos(-1.0);
        while (phi[m] - phi[0] > pi) phi[m] -= 2 * pi;
        while (phi[0] - phi[m] > pi) phi[m] += 2 * pi;
      }
      if (!round) continue;
      const int A = vol ? kHexFaceAxes[lf][0] : 0, B = vol ? kHexFaceAxes[lf][1] : 1;
      const Id na = b.n[A], nb = b.n[B];
      for (Id pb = 0; pb <= nb; ++pb)
        for (Id pa = 0; pa <= na; ++pa) {
          Id ijk[3] = {0, 0, 0};
          if (vol) ijk[lf / 2] = lf % 2 ? b.n[lf / 2] : 0;
          ijk[A] = pa, ijk[B] = pb;
          const double s = static_cast<double>(pa) / na, t = static_cast<double>(pb) / nb;
          const double w[4] = {(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t};
          double ph = 0, zz = 0;
          for (int m = 0; m < 4; ++m) ph += w[m] * phi[m], zz += w[m] * z[m];
          const Id q = b.point_index(ijk[0], ijk[1], ijk[2]);
          out.worst_radius = std::max(out.worst_radius, std::abs(std::hypot(b.x[q], b.y[q]) - 1));
          out.worst_position = std::max(
              out.worst_position, std::hypot(b.x[q] - std::cos(ph), b.y[q] - std::sin(ph), b.z[q] - zz));
          ++out.wall_points;
        }
    }
  }
  return out;
}

struct CylinderCase {
  bool surface, incomplete;
  const char* name;
};

class Cylinder : public ::testing::TestWithParam<int> {};

CylinderCase cylinder_case(int k) {
  static const CylinderCase cases[] = {{false, false, "Hex27"}, {false, true, "Hex20"}, {true, false, "Quad9"},
                                       {true, true, "Quad8"}};
  return cases[k];
}

// The fine nodes on coarse edges and faces lie on Gmsh's quadratic
// elements, exactly (to rounding). Against the true cylinder: the distance
// of a fine node from the point its parameters give on the wall falls ~8x
// when the coarse size halves (P2 interpolation, O(h^3)), where a
// first-order dice of the same corners falls ~4x (chords, O(h^2)); its
// distance from the wall falls faster still (~16x: along a circle the P2
// error is tangential to leading order).
TEST_P(Cylinder, FineBoundaryOnTheQuadraticElementsAndThirdOrderConvergence) {
  const CylinderCase cc = cylinder_case(GetParam());
  TempDir tmp;
  geometry::gmsh_start();
  BoundaryCheck quadratic[2], linear[2];
  for (int level = 0; level < 2; ++level) {
    const int n = 4 << level;
    SCOPED_TRACE(std::string(cc.name) + " n " + std::to_string(n));
    const std::string msh = tmp.path("cyl" + std::to_string(n) + ".msh");
    GmshElements g;
    geometry::gmsh_call(ErrorKind::Io, "meshing the cylinder", [&] {
      cylinder_mesh(n, cc.surface, cc.incomplete);
      write_and_reopen(msh);
      g = gmsh_elements(cc.surface ? 2 : 3);
      gmsh::model::remove();
    });
    EXPECT_EQ(g.type, cc.surface ? (cc.incomplete ? 16 : 10) : (cc.incomplete ? 17 : 12));
    const CoarseMesh coarse = read_coarse_mesh(msh);
    ASSERT_TRUE(coarse.second_order());
    IntervalRequest req;
    req.global = 3;
    FineMesh f = FineMesh::dice(coarse, req);
    const SecondOrderReport rep = apply_second_order(f);
    EXPECT_GT(rep.edges_curved, 0);
    EXPECT_EQ(rep.faces_curved, 0);  // a cylinder's faces are ruled: their centres are the serendipity centres
    EXPECT_GT(rep.min_scaled_jacobian, 0.0);
    quadratic[level] = check_boundary(f, g);
    EXPECT_GT(quadratic[level].wall_points, 0);
    // To rounding, and to the documented straightness tolerance (1e-12 of
    // the diagonal, ~3.5e-12 here: a mid node Gmsh wrote within it of its
    // chord's midpoint leaves the edge straight).
    EXPECT_LE(quadratic[level].worst_vs_gmsh, 3.5e-12) << "over " << quadratic[level].points << " points";
    CoarseMesh corners_only = coarse;
    corners_only.mid.clear();
    linear[level] = check_boundary(FineMesh::dice(corners_only, req), g);
    EXPECT_GT(linear[level].worst_vs_gmsh, 1e-3);  // the check sees a straight edge
    EXPECT_TRUE(verify(f).ok());
    if (level == 0) test::expect_paths_bit_identical(f, tmp.path("cyl.dice.h5"));
  }
  const double qp = quadratic[0].worst_position / quadratic[1].worst_position,
               qr = quadratic[0].worst_radius / quadratic[1].worst_radius,
               lp = linear[0].worst_position / linear[1].worst_position;
  RecordProperty("quadratic_position_ratio", std::to_string(qp));
  RecordProperty("quadratic_radius_ratio", std::to_string(qr));
  RecordProperty("linear_position_ratio", std::to_string(lp));
  std::printf("%s: position error %.3g -> %.3g (x%.2f), distance to the wall %.3g -> %.3g (x%.2f); first order "
              "%.3g -> %.3g (x%.2f)\n",
              cc.name, quadratic[0].worst_position, quadratic[1].worst_position, qp, quadratic[0].worst_radius,
              quadratic[1].worst_radius, qr, linear[0].worst_position, linear[1].worst_position, lp);
  EXPECT_GT(qp, 6.5);
  EXPECT_LT(qp, 9.5);
  EXPECT_GT(qr, 6.5);  // at least third order
  EXPECT_GT(lp, 3.2);
  EXPECT_LT(lp, 4.8);
  EXPECT_LT(quadratic[0].worst_position, 0.05 * linear[0].worst_position);
}

std::string cylinder_name(const ::testing::TestParamInfo<int>& info) { return cylinder_case(info.param).name; }
INSTANTIATE_TEST_SUITE_P(SecondOrder, Cylinder, ::testing::Range(0, 4), cylinder_name);

// ---------------------------------------------------------------- formats

// Exodus's node order for Gmsh's reference coordinates (PATRAN's, from the
// Exodus documentation; the side-list test above checks it against the
// Exodus library): corners, mid-edge nodes, then (HEX27) the centre and the
// faces -z, +z, -x, +x, -y, +y; quads: corners, mid-edges, centre.
std::vector<std::array<int, 3>> exodus_reference(int nodes) {
  std::vector<std::array<int, 3>> r;
  if (nodes <= 9) {
    r = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0, -1, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, 0, 0}};
  } else {
    r = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1},
         {0, -1, -1},  {1, 0, -1},  {0, 1, -1}, {-1, 0, -1}, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0},
         {0, -1, 1},   {1, 0, 1},   {0, 1, 1},  {-1, 0, 1},  {0, 0, 0},   {0, 0, -1}, {0, 0, 1}, {-1, 0, 0},
         {1, 0, 0},    {0, -1, 0},  {0, 1, 0}};
  }
  r.resize(static_cast<size_t>(nodes));
  return r;
}

// The Gmsh model's mesh as an Exodus file: node and element ids kept
// (id maps), connectivity in Exodus's order found by reference position.
void write_exodus_from_gmsh(const std::string& path, const GmshElements& g, const char* type) {
  std::vector<int> gmsh_of_exodus(static_cast<size_t>(g.nodes), -1);
  const auto er = exodus_reference(g.nodes);
  for (int k = 0; k < g.nodes; ++k)
    for (int q = 0; q < g.nodes; ++q) {
      bool same = true;
      for (int d = 0; d < g.dim; ++d) same = same && std::lround(g.local[g.dim * q + d]) == er[k][d];
      if (same) gmsh_of_exodus[k] = q;
    }
  for (int k : gmsh_of_exodus) ASSERT_GE(k, 0);
  std::map<std::size_t, int> number;  // node tag -> 1-based Exodus node number
  std::vector<double> x, y, z;
  std::vector<std::int64_t> node_map, elem_map, conn;
  for (const auto& [tag, p] : g.xyz) {
    number[tag] = static_cast<int>(x.size()) + 1;
    x.push_back(p.x), y.push_back(p.y), z.push_back(p.z), node_map.push_back(static_cast<std::int64_t>(tag));
  }
  for (const auto& [tag, nodes] : g.node_tags) {
    elem_map.push_back(static_cast<std::int64_t>(tag));
    for (int k = 0; k < g.nodes; ++k) conn.push_back(number.at(nodes[gmsh_of_exodus[k]]));
  }
  int cpu = 8, io = 8;
  const int id = ex_create(path.c_str(), EX_CLOBBER, &cpu, &io);
  ASSERT_GE(id, 0);
  ex_set_int64_status(id, EX_ALL_INT64_API);
  ASSERT_EQ(ex_put_init(id, "gmsh cylinder", 3, static_cast<std::int64_t>(x.size()),
                        static_cast<std::int64_t>(elem_map.size()), 1, 0, 0), 0);
  ASSERT_EQ(ex_put_coord(id, x.data(), y.data(), z.data()), 0);
  ASSERT_EQ(ex_put_id_map(id, EX_NODE_MAP, node_map.data()), 0);
  ASSERT_EQ(ex_put_id_map(id, EX_ELEM_MAP, elem_map.data()), 0);
  ASSERT_EQ(ex_put_block(id, EX_ELEM_BLOCK, 1, type, static_cast<std::int64_t>(elem_map.size()), g.nodes, 0, 0, 0), 0);
  ASSERT_EQ(ex_put_conn(id, EX_ELEM_BLOCK, 1, conn.data(), nullptr, nullptr), 0);
  ex_close(id);
}

// The same second-order mesh from every format and flavour dicer reads
// gives the same fine mesh: the same sweep checksum (ids, coordinate bits,
// connectivity), whatever the node order of the format.
TEST_P(Cylinder, EveryFormatGivesTheSameFineMesh) {
  const CylinderCase cc = cylinder_case(GetParam());
  TempDir tmp;
  geometry::gmsh_start();
  std::vector<std::string> files;
  GmshElements g;
  geometry::gmsh_call(ErrorKind::Io, "meshing the cylinder", [&] {
    cylinder_mesh(4, cc.surface, cc.incomplete);
    files.push_back(tmp.path("first.msh"));
    write_and_reopen(files.back());
    for (const auto& [v, bin, name] : {std::tuple{4.1, false, "a41"}, std::tuple{4.1, true, "b41"},
                                       std::tuple{2.2, false, "a22"}, std::tuple{2.2, true, "b22"},
                                       std::tuple{1.0, false, "a1"}}) {
      files.push_back(tmp.path(std::string(name) + ".msh"));
      write_msh(files.back(), v, bin);
    }
    g = gmsh_elements(cc.surface ? 2 : 3);
    gmsh::model::remove();
  });
  const std::vector<const char*> exodus_types =
      cc.surface ? (cc.incomplete ? std::vector<const char*>{"QUAD8", "SHELL8"} : std::vector<const char*>{"QUAD9", "SHELL9"})
                 : (cc.incomplete ? std::vector<const char*>{"HEX20", "HEX"} : std::vector<const char*>{"HEX27", "HEX"});
  for (const char* t : exodus_types) {
    files.push_back(tmp.path(std::string(t) + ".e"));
    write_exodus_from_gmsh(files.back(), g, t);
  }
  IntervalRequest req;
  req.global = 3;
  std::string first;
  for (const auto& file : files) {
    SCOPED_TRACE(file);
    const CoarseMesh m = read_coarse_mesh(file);
    ASSERT_TRUE(m.second_order());
    FineMesh f = FineMesh::dice(m, req);
    EXPECT_GT(apply_second_order(f).edges_curved, 0);
    const std::string sum = std::to_string(sweep(f, 1).checksum);
    if (first.empty()) first = sum;
    EXPECT_EQ(sum, first);
  }
}

// The command line: `dice` applies the quadratic geometry by itself, says
// so, and `info` tells the source's order; with --geometry the CAD wins.
TEST(SecondOrderCli, DiceAppliesItInfoTellsItGeometryWinsWithANote) {
  TempDir tmp;
  geometry::gmsh_start();
  const std::string msh = tmp.path("cyl.msh"), cad = tmp.path("cyl.brep");
  geometry::gmsh_call(ErrorKind::Io, "meshing the cylinder", [&] {
    cylinder_mesh(4, false, false);
    write_msh(msh, 4.1, false);
    gmsh::model::remove();
    gmsh::model::add("cad");
    gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1);
    gmsh::model::occ::synchronize();
    gmsh::write(cad);
    gmsh::model::remove();
  });
  const std::string store = tmp.path("cyl.dice.h5");
  auto r = test::run_cli({"dice", msh, "--interval", "3", "-o", store});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("second order " + msh + ": "), std::string::npos) << r.out;
  r = test::run_cli({"info", store, "--json"});
  EXPECT_NE(r.out.find("\"source_order\":2"), std::string::npos) << r.out;
  r = test::run_cli({"info", store});
  EXPECT_NE(r.out.find("(second order"), std::string::npos) << r.out;
  const FineMesh s = read_store(store);
  EXPECT_GT(s.num_bounding_nodes(), 0);
  EXPECT_TRUE(verify(s).ok());
  // --geometry: one note, the mid nodes ignored, the wall on the CAD.
  const std::string with_cad = tmp.path("cad.dice.h5");
  r = test::run_cli({"dice", msh, "--interval", "3", "--geometry", cad, "-o", with_cad});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("note: " + msh + " is second order; with --geometry the CAD places the boundary"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.out.find("second order"), std::string::npos) << r.out;
  // The wall's fine nodes: on the circle (CAD), not on the quadratic
  // elements (~4e-5 away at this size).
  auto wall_distance = [](const FineMesh& m) {
    double worst = 0;
    for (Id id = 0; id < m.num_nodes(); ++id) {
      const Vec3 p = m.node(id);
      const double d = std::abs(std::hypot(p.x, p.y) - 1);
      if (d < 0.01) worst = std::max(worst, d);
    }
    return worst;
  };
  EXPECT_LE(wall_distance(read_store(with_cad)), 1e-12);
  EXPECT_GT(wall_distance(s), 1e-6);
  r = test::run_cli({"dice", "--help"});
  EXPECT_NE(r.out.find("Second-order input (HEX20, HEX27; QUAD8, QUAD9"), std::string::npos);
}

}  // namespace
}  // namespace dicer
