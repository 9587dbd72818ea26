// Second-order coarse meshes: fine nodes on the quadratic edges and faces
// (the method and why serendipity faces need nothing: quadratic.hpp).
#include "dicer/quadratic.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/quality.hpp"
#include "dicer/rows.hpp"
#include "dicer/tfi.hpp"

namespace dicer {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 half_sum(const Vec3& a, const Vec3& b) { return {0.5 * (a.x + b.x), 0.5 * (a.y + b.y), 0.5 * (a.z + b.z)}; }
double norm(const Vec3& a) { return std::hypot(a.x, a.y, a.z); }
Vec3 plus_scaled(const Vec3& p, double w, const Vec3& d) { return {p.x + w * d.x, p.y + w * d.y, p.z + w * d.z}; }

class Quadratic {
 public:
  explicit Quadratic(FineMesh& mesh) : mesh_(mesh), T_(mesh.tables()), c_(*mesh.coarse()) {}

  SecondOrderReport run() {
    rep_.second_order = true;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    const std::vector<double>* X[3] = {&c_.x, &c_.y, &c_.z};
    for (int d = 0; d < 3; ++d)
      for (double v : *X[d]) lo[d] = std::min(lo[d], v), hi[d] = std::max(hi[d], v);
    tiny_ = 1e-12 * std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    gather();
    move_edges();
    move_faces();
    mesh_.finish_moves();
    check_inversion();
    rep_.bounding_nodes = mesh_.num_bounding_nodes();
    return rep_;
  }

 private:
  FineMesh& mesh_;
  const MeshTables& T_;
  const CoarseMesh& c_;
  SecondOrderReport rep_;
  double tiny_ = 0;
  MeshCursor cur_;
  // Per coarse edge / face: its mid node (index into c_.mid_*) and the
  // element that gave it, -1 when none did; an edge's effective midpoint
  // after the moves (the mid node, or the chord's midpoint when straight).
  std::vector<Id> edge_mid_, edge_from_, face_mid_, face_from_;
  std::vector<Vec3> edge_midpoint_;

  std::string src() const { return c_.source.empty() ? std::string("mesh") : c_.source; }
  std::string element(Id h) const {
    return "element " + std::to_string(c_.element_file_id[h]) + " (block " +
           std::to_string(c_.blocks[c_.element_block[h]].id) + ")";
  }
  std::string node_name(Id m) const { return "node " + std::to_string(c_.mid_file_id[m]); }
  Vec3 vertex(Id v) { return RowReader(T_, cur_).xyz(v); }
  Vec3 node(EntityKind k, Id ent, Id a, Id b = 0) {
    NodeRef r;
    r.kind = k, r.entity = ent, r.local = {a, b, 0};
    return mesh_.node(r, cur_);
  }

  // Records mid node m of an entity given by element h; the entity's
  // earlier giver must agree (the same point), and m must shape one entity.
  void record(std::vector<Id>& mid, std::vector<Id>& from, Id ent, Id m, Id h, const char* what,
              std::vector<std::int8_t>& used_by, std::int8_t kind, std::vector<Id>& used_ent) {
    if (used_by[m] != 0 && (used_by[m] != kind || used_ent[m] != ent))
      throw Error(ErrorKind::BadInput, src() + ": " + node_name(m) + " is the mid node of two different " +
                                           (used_by[m] == kind ? std::string(what) + "s" : "entities") +
                                           " (second-order connectivity of " + element(h) + ")");
    used_by[m] = kind, used_ent[m] = ent;
    if (mid[ent] < 0) {
      mid[ent] = m, from[ent] = h;
      return;
    }
    const Id o = mid[ent];
    if (o == m) return;
    const Vec3 a = c_.mid_node(o), b = c_.mid_node(m);
    if (a.x == b.x && a.y == b.y && a.z == b.z) return;  // duplicated node, same point
    std::ostringstream os;
    os.precision(10);
    os << src() << ": " << element(from[ent]) << " and " << element(h) << " disagree on the mid node of their common "
       << what << ": " << node_name(o) << " at (" << a.x << ", " << a.y << ", " << a.z << ") vs " << node_name(m)
       << " at (" << b.x << ", " << b.y << ", " << b.z << ")";
    throw Error(ErrorKind::BadInput, os.str());
  }

  void gather() {
    const Id E = T_.edges.rows(), F = T_.faces.rows(), H = T_.elements.rows();
    const int slots = mid_slots(mesh_.mode());
    const bool vol = mesh_.mode() == Mode::Volume;
    edge_mid_.assign(static_cast<size_t>(E), -1), edge_from_.assign(static_cast<size_t>(E), -1);
    face_mid_.assign(static_cast<size_t>(F), -1), face_from_.assign(static_cast<size_t>(F), -1);
    const size_t M = c_.mid_x.size();
    std::vector<std::int8_t> used_by(M, 0);
    std::vector<Id> used_ent(M, -1);
    const RowReader R(T_, cur_);
    for (Id h = 0; h < H; ++h) {
      const ElementRow r = R.element(h);
      const Id* s = &c_.mid[static_cast<size_t>(h) * slots];
      for (int k = 0; k < R.edges(); ++k)
        if (s[k] >= 0) record(edge_mid_, edge_from_, r.edge[k], s[k], h, "edge", used_by, 1, used_ent);
      for (int k = 0; k < R.faces(); ++k) {
        const Id m = s[vol ? 12 + k : 4];
        if (m >= 0) record(face_mid_, face_from_, r.face[k], m, h, "face", used_by, 2, used_ent);
      }
    }
  }

  void move_edges() {
    const Id E = T_.edges.rows();
    edge_midpoint_.resize(static_cast<size_t>(E));
    std::vector<Vec3> pts;
    for (Id e = 0; e < E; ++e) {
      const EdgeRow r = RowReader(T_, cur_).edge(e);
      const Vec3 chord_mid = half_sum(vertex(r.lo), vertex(r.hi));
      edge_midpoint_[e] = chord_mid;
      if (edge_mid_[e] < 0) continue;
      const Vec3 m = c_.mid_node(edge_mid_[e]);
      const Vec3 d = sub(m, chord_mid);
      if (!(norm(d) > tiny_)) continue;  // straight: the TFI's own nodes
      edge_midpoint_[e] = m;
      if (r.n < 2) continue;  // no fine node inside; the faces still see m
      pts.clear();
      for (Id t = 1; t < r.n; ++t) {
        const double s = tfi::param(t, r.n, r.grading);  // the TFI's (graded) parameter
        pts.push_back(plus_scaled(node(EntityKind::Edge, e, t), 4.0 * s * (1.0 - s), d));
      }
      mesh_.move_nodes(EntityKind::Edge, e, pts);
      ++rep_.edges_curved;
    }
  }

  void move_faces() {
    const Id F = T_.faces.rows();
    std::vector<Vec3> pts;
    for (Id f = 0; f < F; ++f) {
      if (face_mid_[f] < 0) continue;
      const FaceRow r = RowReader(T_, cur_).face(f);
      // The serendipity surface's centre: (sum of side midpoints) / 2 - (sum of corners) / 4.
      Vec3 centre{0, 0, 0};
      for (int k = 0; k < 4; ++k) {
        const Vec3 m = edge_midpoint_[r.e[k]], v = vertex(r.v[k]);
        centre = {centre.x + (0.5 * m.x - 0.25 * v.x), centre.y + (0.5 * m.y - 0.25 * v.y),
                  centre.z + (0.5 * m.z - 0.25 * v.z)};
      }
      const Vec3 d = sub(c_.mid_node(face_mid_[f]), centre);
      if (!(norm(d) > tiny_) || r.nu < 2 || r.nv < 2) continue;
      pts.clear();
      const auto g = RowReader(T_, cur_).face_grading(r);
      for (Id v = 1; v < r.nv; ++v)
        for (Id u = 1; u < r.nu; ++u) {
          const double s = tfi::param(u, r.nu, g[0]), t = tfi::param(v, r.nv, g[1]);
          pts.push_back(plus_scaled(node(EntityKind::Face, f, u, v), 16.0 * (s * (1.0 - s)) * (t * (1.0 - t)), d));
        }
      mesh_.move_nodes(EntityKind::Face, f, pts);
      ++rep_.faces_curved;
    }
  }

  void check_inversion() {
    const QualityReport q = check_moved_quality(mesh_);
    rep_.min_scaled_jacobian = q.min_scaled_jacobian;
    rep_.elements_checked = q.elements_checked;
    if (q.inverted == 0) return;
    std::ostringstream os;
    os.precision(3);
    os << src() << ": the second-order geometry of " << element(q.worst_coarse_element) << " would invert "
       << q.inverted << " fine element(s); the worst is fine element " << q.worst_element << " (scaled Jacobian "
       << q.min_scaled_jacobian << "): its mid nodes bend it too far for its intervals (move them, refine the "
       << "coarse mesh there or use fewer intervals); nothing was written";
    throw Error(ErrorKind::Geometry, os.str());
  }
};

}  // namespace

SecondOrderReport apply_second_order(FineMesh& mesh) {
  const CoarseMesh* c = mesh.coarse();
  if (!c || !c->second_order()) return {};
  if (c->mid.size() != static_cast<size_t>(mesh.tables().elements.rows()) * mid_slots(mesh.mode()))
    throw Error(ErrorKind::Usage, "apply_second_order: the mesh's mid-node table does not match its elements");
  return Quadratic(mesh).run();
}

}  // namespace dicer
