// Geometry-conforming dicing: owners, snapping, projection (edges before
// faces), inversion check. The method and its justification are in
// include/dicer/geometry.hpp.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "cad.hpp"
#include "dicer/error.hpp"
#include "dicer/geometry.hpp"
#include "dicer/quality.hpp"
#include "dicer/rows.hpp"
#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"

namespace dicer {
namespace {

using geometry::Cad;
using geometry::CadEntity;
using geometry::fmt;  // and fmt(Vec3) below

double dist(const Vec3& a, const Vec3& b) { return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z); }
Vec3 at(const std::vector<double>& v, size_t i) { return {v[3 * i], v[3 * i + 1], v[3 * i + 2]}; }
void push(std::vector<double>& v, const Vec3& p) { v.push_back(p.x), v.push_back(p.y), v.push_back(p.z); }

const char* dim_name(int d) {
  static const char* k[4] = {"point", "curve", "surface", "volume"};
  return d >= 0 && d <= 3 ? k[d] : "entity";
}
std::string fmt(const Vec3& p) {
  std::ostringstream s;
  s.precision(10);
  s << "(" << p.x << ", " << p.y << ", " << p.z << ")";
  return s.str();
}

// Records of a distributed phase (ConformOptions::share): plain bytes of
// trivially copyable values, read back in the same process image.
struct Bytes {
  std::string s;
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void points(const std::vector<Vec3>& p) {
    put<std::uint64_t>(p.size());
    s.append(reinterpret_cast<const char*>(p.data()), p.size() * sizeof(Vec3));
  }
};
struct Cursor {
  const std::string& s;
  size_t at = 0;
  explicit Cursor(const std::string& bytes) : s(bytes) {}
  bool done() const { return at >= s.size(); }
  void need(size_t n) const {
    if (n > s.size() - at) throw std::logic_error("conform: a shared record is truncated");
  }
  template <class T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T));
    T v;
    std::memcpy(&v, s.data() + at, sizeof v);
    at += sizeof v;
    return v;
  }
  std::string text(std::uint64_t n) {
    need(n);
    std::string t = s.substr(at, n);
    at += n;
    return t;
  }
  std::vector<Vec3> points() {
    const auto n = get<std::uint64_t>();
    need(n * sizeof(Vec3));
    std::vector<Vec3> p(n);
    std::memcpy(p.data(), s.data() + at, n * sizeof(Vec3));
    at += n * sizeof(Vec3);
    return p;
  }
};

// Every part's records of a phase, in part order, once all parts are
// done with it. A failure on any part (err, at entity index `at`) is
// thrown by every part after the exchange: the one at the lowest index.
std::vector<std::string> exchange(const ConformOptions& opt, const std::string& records, std::exception_ptr err,
                                std::uint64_t at) {
  Bytes head;
  std::int32_t kind = -1;
  std::string what;
  if (err) {
    try {
      std::rethrow_exception(err);
    } catch (const Error& e) {
      kind = static_cast<std::int32_t>(e.kind()), what = e.what();
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
      what = "unknown error";
    }
  }
  head.put<std::uint8_t>(err ? 1 : 0), head.put(at), head.put(kind), head.put<std::uint64_t>(what.size());
  head.s += what;
  std::vector<std::string> all = opt.share(head.s + records);
  if (static_cast<int>(all.size()) != opt.parts) throw std::logic_error("conform: share gave the wrong number of parts");
  bool any = false;
  std::uint64_t best = 0;
  std::int32_t best_kind = -1;
  std::string best_what;
  for (std::string& part : all) {
    Cursor c(part);
    const bool f = c.get<std::uint8_t>() != 0;
    const auto i = c.get<std::uint64_t>();
    const auto k = c.get<std::int32_t>();
    const std::string w = c.text(c.get<std::uint64_t>());
    if (f && (!any || i < best)) any = true, best = i, best_kind = k, best_what = w;
    part.erase(0, c.at);
  }
  if (any) {
    if (best_kind < 0) throw std::runtime_error(best_what);
    throw Error(static_cast<ErrorKind>(best_kind), best_what);
  }
  return all;
}


struct Owner {
  int dim = -1, tag = -1;
  bool operator<(const Owner& o) const { return dim != o.dim ? dim < o.dim : tag < o.tag; }
  bool operator==(const Owner& o) const { return dim == o.dim && tag == o.tag; }
};

// The entities whose closure holds `o`: o itself and everything above it.
class Closure {
 public:
  explicit Closure(const Cad& cad) : cad_(cad) {}
  const std::set<Owner>& of(Owner o) {
    auto it = memo_.find(o);
    if (it != memo_.end()) return it->second;
    std::set<Owner> s{o};
    if (const CadEntity* e = cad_.find(o.dim, o.tag))
      for (int up : e->up) {
        const auto& u = of({o.dim + 1, up});
        s.insert(u.begin(), u.end());
      }
    return memo_[o] = std::move(s);
  }

 private:
  const Cad& cad_;
  std::map<Owner, std::set<Owner>> memo_;
};

// Distances of points to one entity (batched kernel call).
std::vector<double> distances(const Cad& cad, Owner o, const std::vector<Vec3>& pts, std::vector<Vec3>* on = nullptr) {
  std::vector<double> xyz, c, p;
  for (const Vec3& q : pts) push(xyz, q);
  cad.closest(o.dim, o.tag, xyz, c, p);
  std::vector<double> d(pts.size());
  if (on) on->resize(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    d[i] = dist(pts[i], at(c, i));
    if (on) (*on)[i] = at(c, i);
  }
  return d;
}

bool in_box(const CadEntity& e, const Vec3& p, double pad) {
  return p.x >= e.box[0] - pad && p.y >= e.box[1] - pad && p.z >= e.box[2] - pad && p.x <= e.box[3] + pad &&
         p.y <= e.box[4] + pad && p.z <= e.box[5] + pad;
}

// Moves parameters of a periodic entity to within half a period of `ref`.
void unwrap(const CadEntity& e, double* uv, const double* ref) {
  for (int k = 0; k < e.dim && k < 2; ++k) {
    if (!e.periodic[k]) continue;
    const double P = e.pmax[k] - e.pmin[k];
    while (uv[k] - ref[k] > 0.5 * P) uv[k] -= P;
    while (ref[k] - uv[k] > 0.5 * P) uv[k] += P;
  }
}

class Conformer {
 public:
  Conformer(FineMesh& mesh, const Cad& cad, const ConformOptions& opt)
      : mesh_(mesh), cad_(cad), opt_(opt), T_(mesh.tables()), closure_(cad) {
    rep_.diagonal = cad.diagonal();
    tol_ = opt.tolerance * rep_.diagonal;
    tiny_ = 1e-12 * rep_.diagonal;
  }

  // `early`: a part's failure before this (loading the CAD), shared at the
  // first exchange.
  ConformReport run(std::exception_ptr early = nullptr) {
    std::exception_ptr failed = early;
    if (!failed) {
      try {
        find_candidate_faces();
        assign_vertices();
        assign_edges();
        assign_faces();
        check_coverage();
        snap_vertices();
      } catch (...) {
        if (!distributed()) throw;
        failed = std::current_exception();
      }
    }
    move_edges(failed);
    move_faces();
    mesh_.finish_moves();
    check_inversion();
    mesh_.set_geometry_source(cad_.path());
    rep_.bounding_nodes = mesh_.num_bounding_nodes();
    return rep_;
  }

  // Only the vertices' owners (the first two steps of run()), for
  // classify_on_geometry: (dim, tag) per vertex of the mesh's tables, dim
  // -1 where none.
  std::vector<std::pair<int, int>> vertex_owners() {
    find_candidate_faces();
    assign_vertices();
    std::vector<std::pair<int, int>> out;
    for (const Owner& o : vowner_) out.emplace_back(o.dim, o.tag);
    return out;
  }

 private:
  FineMesh& mesh_;
  const Cad& cad_;
  const ConformOptions& opt_;
  const MeshTables& T_;
  Closure closure_;
  ConformReport rep_;
  double tol_ = 0, tiny_ = 0;
  MeshCursor cur_;
  std::vector<char> cand_face_, boundary_face_, need_vertex_, boundary_vertex_;
  std::vector<Owner> vowner_, eowner_, fowner_;
  std::vector<Vec3> snap_;
  std::vector<Id> cand_edges_;

  void progress(const char* stage, Id done, Id total) {
    if (opt_.progress) opt_.progress(stage, done, total);
  }
  std::string src() const { return mesh_.info().source.empty() ? std::string("mesh") : mesh_.info().source; }
  Id vfile(Id v) const {
    const CoarseMesh* c = mesh_.coarse();
    return c && v < static_cast<Id>(c->vertex_file_id.size()) ? c->vertex_file_id[v] : v + 1;
  }
  Vec3 vertex(Id v) { return RowReader(T_, cur_).xyz(v); }
  EdgeRow edge(Id e) { return RowReader(T_, cur_).edge(e); }
  FaceRow face(Id f) { return RowReader(T_, cur_).face(f); }
  Vec3 node(EntityKind k, Id ent, Id a, Id b = 0) {
    NodeRef r;
    r.kind = k, r.entity = ent, r.local = {a, b, 0};
    return mesh_.node(r, cur_);
  }

  void find_candidate_faces() {
    const Id F = T_.faces.rows(), H = T_.elements.rows();
    const RowReader R(T_, cur_);
    std::vector<int> count(static_cast<size_t>(F), 0);
    std::vector<std::int64_t> block(static_cast<size_t>(F), -1);
    std::vector<char> mixed(static_cast<size_t>(F), 0);
    for (Id h = 0; h < H; ++h) {
      const ElementRow r = R.element(h);
      for (int k = 0; k < R.faces(); ++k) {
        const Id f = r.face[k];
        ++count[f];
        if (block[f] >= 0 && block[f] != r.block) mixed[f] = 1;
        block[f] = r.block;
      }
    }
    const bool vol = mesh_.mode() == Mode::Volume;
    cand_face_.assign(static_cast<size_t>(F), 0);
    boundary_face_.assign(static_cast<size_t>(F), 0);
    need_vertex_.assign(static_cast<size_t>(T_.num_vertices()), 0);
    boundary_vertex_.assign(static_cast<size_t>(T_.num_vertices()), 0);
    for (Id f = 0; f < F; ++f) {
      const FaceRow r = face(f);
      bool classified = true;
      for (int k = 0; k < 4; ++k) {
        const std::int64_t o = R.vertex_geo(r.v[k]);
        classified &= owner_dim(o) >= 0 && owner_dim(o) <= 2 && cad_.find(owner_dim(o), owner_tag(o)) != nullptr;
      }
      boundary_face_[f] = !vol || count[f] == 1;
      cand_face_[f] = boundary_face_[f] || mixed[f] || classified;
      if (!cand_face_[f]) continue;
      for (int k = 0; k < 4; ++k) {
        need_vertex_[r.v[k]] = 1;
        if (boundary_face_[f]) boundary_vertex_[r.v[k]] = 1;
      }
    }
  }

  void assign_vertices() {
    const Id V = T_.num_vertices();
    vowner_.assign(static_cast<size_t>(V), Owner{});
    snap_.assign(static_cast<size_t>(V), Vec3{});
    std::vector<double> best(static_cast<size_t>(V), INFINITY);
    std::vector<Owner> nearest(static_cast<size_t>(V));
    // 1. The MSH classification, where the CAD has that entity and agrees.
    std::map<Owner, std::vector<Id>> by_tag;
    Id classified = 0;
    for (Id v = 0; v < V; ++v) {
      if (!need_vertex_[v]) continue;
      const std::int64_t o = RowReader(T_, cur_).vertex_geo(v);
      const int d = owner_dim(o), tag = owner_tag(o);
      if (d >= 0 && d <= 2 && cad_.find(d, tag)) by_tag[{d, tag}].push_back(v), ++classified;
    }
    Id kept = 0;
    for (const auto& [o, vs] : by_tag) {
      std::vector<Vec3> pts, on;
      for (Id v : vs) pts.push_back(vertex(v));
      const auto d = distances(cad_, o, pts, &on);
      for (size_t i = 0; i < vs.size(); ++i)
        if (d[i] <= tol_) vowner_[vs[i]] = o, snap_[vs[i]] = on[i], best[vs[i]] = d[i], ++kept;
    }
    rep_.tags_matched = classified > 0 && kept == classified;
    // 2. Geometric matching for the rest: lowest dimension within tolerance.
    for (int d = 0; d <= 2; ++d) {
      Id done = 0;
      for (const CadEntity& e : cad_.entities(d)) {
        progress("matching vertices", done++, static_cast<Id>(cad_.entities(d).size()));
        std::vector<Id> vs;
        std::vector<Vec3> pts, on;
        for (Id v = 0; v < V; ++v)
          if (need_vertex_[v] && vowner_[v].dim < 0 && in_box(e, vertex(v), std::max(tol_, 1e-3 * rep_.diagonal)))
            vs.push_back(v), pts.push_back(vertex(v));
        if (vs.empty()) continue;
        const auto dd = distances(cad_, {d, e.tag}, pts, &on);
        for (size_t i = 0; i < vs.size(); ++i) {
          const Id v = vs[i];
          if (dd[i] < best[v]) best[v] = dd[i], nearest[v] = {d, e.tag}, snap_[v] = on[i];
        }
      }
      for (Id v = 0; v < V; ++v)
        if (need_vertex_[v] && vowner_[v].dim < 0 && best[v] <= tol_) vowner_[v] = nearest[v];
    }
    for (Id v = 0; v < V; ++v) {
      if (!need_vertex_[v]) continue;
      if (vowner_[v].dim >= 0) {
        ++rep_.vertices_on_cad;
        continue;
      }
      if (!boundary_vertex_[v]) continue;  // an interface that is no CAD surface: stays interior
      std::string near = nearest[v].dim >= 0 ? std::string(" from the nearest, CAD ") + dim_name(nearest[v].dim) + " " +
                                                   std::to_string(nearest[v].tag)
                                             : std::string(" from every CAD entity (none within 1e-3 of the diagonal)");
      throw Error(ErrorKind::Geometry,
                  src() + ": coarse vertex " + std::to_string(vfile(v)) + " at " + fmt(vertex(v)) + " on the boundary is " +
                      (std::isfinite(best[v]) ? fmt(best[v]) : std::string("far")) + near + ", more than the tolerance " +
                      fmt(tol_) + " (" + fmt(opt_.tolerance) + " of the model's diagonal " + fmt(rep_.diagonal) +
                      "): the mesh does not fit " + cad_.path());
    }
  }

  // Lowest common entity of the corners' closures (dim <= max_dim) whose
  // geometry passes near `mid`, within `slack`.
  Owner common(const std::vector<Id>& corners, const Vec3& mid, double slack, int min_dim, int max_dim) {
    std::set<Owner> s;
    bool first = true;
    for (Id v : corners) {
      if (vowner_[v].dim < 0) return {};
      const auto& c = closure_.of(vowner_[v]);
      if (first) s = c, first = false;
      else {
        std::set<Owner> t;
        std::set_intersection(s.begin(), s.end(), c.begin(), c.end(), std::inserter(t, t.begin()));
        s.swap(t);
      }
    }
    for (int d = min_dim; d <= max_dim; ++d) {
      Owner best;
      double bd = INFINITY;
      for (const Owner& o : s) {
        if (o.dim != d || !cad_.find(o.dim, o.tag)) continue;
        const double dd = distances(cad_, o, {mid})[0];
        if (dd < bd) bd = dd, best = o;
      }
      if (best.dim >= 0 && bd <= slack) return best;
    }
    return {};
  }

  void assign_edges() {
    const Id E = T_.edges.rows(), F = T_.faces.rows();
    eowner_.assign(static_cast<size_t>(E), Owner{});
    std::vector<char> cand(static_cast<size_t>(E), 0), on_boundary(static_cast<size_t>(E), 0);
    for (Id f = 0; f < F; ++f)
      if (cand_face_[f])
        for (int k = 0; k < 4; ++k) {
          const Id e = face(f).e[k];
          cand[e] = 1;
          on_boundary[e] |= boundary_face_[f];
        }
    for (Id e = 0; e < E; ++e) {
      if (!cand[e]) continue;
      progress("matching edges", e, E);
      cand_edges_.push_back(e);
      const EdgeRow er = edge(e);
      const Id lo = er.lo, hi = er.hi;
      const Vec3 a = vertex(lo), b = vertex(hi);
      const Vec3 mid{0.5 * (a.x + b.x), 0.5 * (a.y + b.y), 0.5 * (a.z + b.z)};
      // A chord across a curved surface's corner must not be taken for the
      // curve: the curve has to pass within half the edge's length.
      const Owner o = common({lo, hi}, mid, 0.5 * dist(a, b) + tol_, 1, 2);
      eowner_[e] = o;
      if (o.dim == 1) ++rep_.edges_on_curves;
      else if (o.dim == 2) ++rep_.edges_on_surfaces;
      else if (on_boundary[e] && vowner_[lo].dim >= 0 && vowner_[hi].dim >= 0)
        throw Error(ErrorKind::Geometry, src() + ": coarse edge (" + std::to_string(vfile(lo)) + ", " +
                                             std::to_string(vfile(hi)) + ") on the boundary lies on no CAD curve or surface "
                                             "common to its ends: the mesh does not fit " + cad_.path());
      mesh_.set_owner(EntityKind::Edge, e, o.dim >= 0 ? pack_owner(o.dim, o.tag) : -1);
    }
  }

  void assign_faces() {
    const Id F = T_.faces.rows();
    fowner_.assign(static_cast<size_t>(F), Owner{});
    for (Id f = 0; f < F; ++f) {
      if (!cand_face_[f]) continue;
      progress("matching faces", f, F);
      const FaceRow r = face(f);
      std::vector<Id> vs{r.v[0], r.v[1], r.v[2], r.v[3]};
      Vec3 c{0, 0, 0};
      double diam = 0;
      for (Id v : vs) {
        const Vec3 p = vertex(v);
        c = {c.x + 0.25 * p.x, c.y + 0.25 * p.y, c.z + 0.25 * p.z};
      }
      diam = std::max(dist(vertex(vs[0]), vertex(vs[2])), dist(vertex(vs[1]), vertex(vs[3])));
      const Owner o = common(vs, c, 0.5 * diam + tol_, 2, 2);
      fowner_[f] = o;
      if (o.dim == 2) ++rep_.faces_on_surfaces;
      else if (boundary_face_[f] && std::all_of(vs.begin(), vs.end(), [&](Id v) { return vowner_[v].dim >= 0; }))
        throw Error(ErrorKind::Geometry, src() + ": coarse face (" + std::to_string(vfile(vs[0])) + ", " +
                                             std::to_string(vfile(vs[1])) + ", " + std::to_string(vfile(vs[2])) + ", " +
                                             std::to_string(vfile(vs[3])) +
                                             ") on the boundary lies on no CAD surface: the mesh does not fit " + cad_.path());
      mesh_.set_owner(EntityKind::Face, f, o.dim >= 0 ? pack_owner(o.dim, o.tag) : -1);
    }
  }

  void check_coverage() {
    std::set<int> covered;
    for (const Owner& o : fowner_)
      if (o.dim == 2) covered.insert(o.tag);
    // A surface mesh is of the model's skin (mesh-coarse --surface leaves a
    // surface between two volumes out): such a surface needs no face.
    const bool skin = mesh_.mode() == Mode::Surface;
    for (const CadEntity& e : cad_.entities(2))
      if (!covered.count(e.tag) && !(skin && e.up.size() >= 2))
        throw Error(ErrorKind::Geometry, cad_.path() + ": CAD surface " + std::to_string(e.tag) + " (" + e.type +
                                             ") has no coarse face of " + src() +
                                             " on it: the mesh does not cover this CAD model");
  }

  void snap_vertices() {
    for (Id v = 0; v < T_.num_vertices(); ++v) {
      if (vowner_[v].dim < 0 || vowner_[v].dim > 2) continue;
      rep_.max_vertex_snap = std::max(rep_.max_vertex_snap, dist(vertex(v), snap_[v]));
      mesh_.set_vertex(v, snap_[v], vowner_[v].dim, vowner_[v].tag);
    }
  }

  // Points in parameter space -> xyz; false when a parameter is degenerate
  // (a pole: the surface does not move with that parameter).
  bool degenerate(const CadEntity& e, const std::vector<double>& params) {
    std::vector<double> sp;
    cad_.speed(e.dim, e.tag, params, sp);
    for (double s : sp)
      if (!(s > 1e-9 * rep_.diagonal)) return true;
    return false;
  }

  // How an entity's nodes are placed. Decided once per entity from probes
  // at fixed parameters (kProbes), never from its interval, so two dicings
  // whose intervals are multiples of each other (nested levels, transfer.hpp)
  // make the same choice and place every node they share bit for bit alike.
  enum class Place : std::uint8_t { Predicted, Parametric, Closest };
  static constexpr int kProbes = 8;  // probes at k / kProbes, 0 < k < kProbes (per axis on faces)
  struct EdgePlan {
    Place how = Place::Predicted;
    Owner o;
    double p[4] = {0, 0, 0, 0};  // end parameters (dim of o each), unwrapped
  };
  std::vector<EdgePlan> eplan_;

  // Accepts points interpolated in parameters when each probe is within
  // `reach` (a quarter of the probe spacing) of the closest point of its
  // TFI prediction: the parameters then only even out the spacing. A
  // parametrisation far from arc length (the longitudes near a sphere's
  // pole, a face across more than half a period) fails this and the closest
  // points are used instead.
  static bool plausible(const std::vector<Vec3>& got, const std::vector<Vec3>& closest, double reach) {
    for (size_t i = 0; i < got.size(); ++i)
      if (!(dist(got[i], closest[i]) <= reach)) return false;
    return true;
  }
  // Placed probes within tiny_ of their prediction: the entity already lies
  // on the CAD (a ruling of a cylinder, say): nothing is moved or stored.
  Place settle(Place how, const std::vector<Vec3>& placed, const std::vector<Vec3>& pred) const {
    for (size_t i = 0; i < placed.size(); ++i)
      if (dist(placed[i], pred[i]) > tiny_) return how;
    return Place::Predicted;
  }

  std::vector<Vec3> project(const CadEntity& e, const std::vector<Vec3>& pred) {
    std::vector<Vec3> on;
    distances(cad_, {e.dim, e.tag}, pred, &on);
    return on;
  }
  static Vec3 lerp(const Vec3& a, const Vec3& b, double s) {
    return {tfi::edge(a.x, b.x, s), tfi::edge(a.y, b.y, s), tfi::edge(a.z, b.z, s)};
  }

  // Edge e's points at canonical parameters s in [0, 1] as its plan places
  // them: the nodes (s = t / n) or probes.
  std::vector<Vec3> edge_points(Id e, const std::vector<double>& s) {
    const EdgeRow r = edge(e);
    const Vec3 a = vertex(r.lo), b = vertex(r.hi);
    const EdgePlan& pl = eplan_[static_cast<size_t>(e)];
    std::vector<Vec3> pred;
    for (double x : s) pred.push_back(lerp(a, b, x));
    if (pl.how == Place::Predicted) return pred;
    if (pl.how == Place::Closest) return project(*cad_.find(pl.o.dim, pl.o.tag), pred);
    const int D = pl.o.dim;
    std::vector<double> q, xyz;
    for (double x : s)
      for (int k = 0; k < D; ++k) q.push_back(tfi::edge(pl.p[k], pl.p[D + k], x));
    cad_.value(D, pl.o.tag, q, xyz);
    std::vector<Vec3> out;
    for (size_t i = 0; i < s.size(); ++i) out.push_back(at(xyz, i));
    return out;
  }

  static std::vector<double> probes() {
    std::vector<double> s;
    for (int k = 1; k < kProbes; ++k) s.push_back(static_cast<double>(k) / kProbes);
    return s;
  }

  // ---- distributed conforming (ConformOptions::parts > 1)
  bool distributed() const { return opt_.parts > 1; }
  bool mine(size_t i) const { return !distributed() || static_cast<int>(i % static_cast<size_t>(opt_.parts)) == opt_.part; }

  // What placing one edge decided: its plan, and its nodes when they move.
  struct EdgeDone {
    Id e = -1;
    EdgePlan plan;
    bool closest = false;
    std::vector<Vec3> pts;  // empty: not moved
  };
  void apply(const EdgeDone& d) {
    eplan_[static_cast<size_t>(d.e)] = d.plan;
    if (d.closest) ++rep_.closest_point_fallbacks;
    if (d.pts.empty()) return;
    mesh_.move_nodes(EntityKind::Edge, d.e, d.pts);
    ++rep_.edges_moved;
  }

  void move_edges(std::exception_ptr failed) {
    eplan_.assign(static_cast<size_t>(T_.edges.rows()), EdgePlan{});
    const std::vector<double> probe = probes();
    Bytes out;
    std::uint64_t failed_at = 0;
    if (!failed) {
      size_t i = 0;
      try {
        for (; i < cand_edges_.size(); ++i) {
          if (!mine(i)) continue;
          progress("moving edge nodes", static_cast<Id>(i), static_cast<Id>(cand_edges_.size()));
          EdgeDone d;
          if (!place_edge(cand_edges_[i], probe, d)) continue;
          if (!distributed()) {
            apply(d);
            continue;
          }
          out.put<std::uint64_t>(i), out.put(d.e), out.put(d.plan), out.put<std::uint8_t>(d.closest), out.points(d.pts);
        }
      } catch (...) {
        if (!distributed()) throw;
        failed = std::current_exception(), failed_at = i;
      }
    }
    if (!distributed()) return;
    // Every part's edges, applied in candidate order as one process does.
    std::vector<std::pair<std::uint64_t, EdgeDone>> all;
    for (const std::string& part : exchange(opt_, out.s, failed, failed_at)) {
      Cursor c(part);
      while (!c.done()) {
        const auto i = c.get<std::uint64_t>();
        EdgeDone d;
        d.e = c.get<Id>(), d.plan = c.get<EdgePlan>(), d.closest = c.get<std::uint8_t>() != 0, d.pts = c.points();
        all.emplace_back(i, std::move(d));
      }
    }
    std::sort(all.begin(), all.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    for (const auto& [i, d] : all) apply(d);
  }

  // Decides how candidate edge e is placed; false when it is left alone
  // (no curve or surface, flat, no interior nodes).
  bool place_edge(Id e, const std::vector<double>& probe, EdgeDone& d) {
      const Owner o = eowner_[e];
      const CadEntity* ent = o.dim >= 1 ? cad_.find(o.dim, o.tag) : nullptr;
      if (!ent || ent->flat) return false;
      const EdgeRow r = edge(e);
      if (r.n < 2) return false;  // no nodes; a face using it has none either
      const Vec3 a = vertex(r.lo), b = vertex(r.hi);
      std::vector<double> ends, p;
      push(ends, a), push(ends, b);
      cad_.param(o.dim, o.tag, ends, p);
      const int D = o.dim;
      unwrap(*ent, &p[D], &p[0]);
      EdgePlan& pl = eplan_[static_cast<size_t>(e)];
      pl.o = o;
      std::copy(p.begin(), p.end(), pl.p);
      // The plan, from the probes.
      std::vector<Vec3> pred;
      for (double s : probe) pred.push_back(lerp(a, b, s));
      const std::vector<Vec3> proj = project(*ent, pred);
      std::vector<Vec3> par;
      if (D == 1 || !degenerate(*ent, p)) {
        pl.how = Place::Parametric;
        par = edge_points(e, probe);
      }
      const bool param = !par.empty() && plausible(par, proj, 0.25 * dist(a, b) / kProbes + tol_);
      pl.how = settle(param ? Place::Parametric : Place::Closest, param ? par : proj, pred);
      d.e = e, d.plan = pl;
      if (pl.how == Place::Predicted) return true;
      d.closest = pl.how == Place::Closest;
      // The sheet's spacing (equal or graded) in the curve's parameters.
      const tfi::Series series(r.n, r.grading);
      std::vector<double> s;
      for (Id t = 1; t < r.n; ++t) s.push_back(series.at(t));
      d.pts = edge_points(e, s);
      return true;
  }

  // Side k of face r (0 v0v1, 1 v3v2 at u; 2 v0v3, 3 v1v2 at v) at face
  // parameters s, through its edge's plan.
  std::vector<Vec3> side_points(const FaceRow& r, int k, const std::vector<double>& s) {
    const bool rev = r.v[kQuadEdge[k][0]] > r.v[kQuadEdge[k][1]];
    std::vector<double> c;
    for (double x : s) c.push_back(rev ? 1.0 - x : x);
    return edge_points(r.e[k], c);
  }

  void apply_face(Id f, bool closest, const std::vector<Vec3>& pts) {
    if (closest) ++rep_.closest_point_fallbacks;
    mesh_.move_nodes(EntityKind::Face, f, pts);
    ++rep_.faces_moved;
  }

  void move_faces() {
    const Id F = T_.faces.rows();
    const std::vector<double> probe = probes();
    Bytes out;
    std::exception_ptr failed;
    Id f = 0;
    try {
      for (std::uint64_t c = 0; f < F; ++f) {
        if (!cand_face_[f] || !mine(c++)) continue;
        progress("moving face nodes", f, F);
        bool closest = false;
        std::vector<Vec3> pts;
        if (!place_face(f, probe, closest, pts)) continue;
        if (!distributed()) apply_face(f, closest, pts);
        else out.put(f), out.put<std::uint8_t>(closest), out.points(pts);
      }
    } catch (...) {
      if (!distributed()) throw;
      failed = std::current_exception();
    }
    if (!distributed()) return;
    struct Done {
      Id f;
      bool closest;
      std::vector<Vec3> pts;
    };
    std::vector<Done> all;
    for (const std::string& part : exchange(opt_, out.s, failed, static_cast<std::uint64_t>(f))) {
      Cursor c(part);
      while (!c.done()) {
        Done d;
        d.f = c.get<Id>(), d.closest = c.get<std::uint8_t>() != 0, d.pts = c.points();
        all.push_back(std::move(d));
      }
    }
    std::sort(all.begin(), all.end(), [](const Done& x, const Done& y) { return x.f < y.f; });
    for (const Done& d : all) apply_face(d.f, d.closest, d.pts);
  }

  // Places candidate face f's nodes; false when they stay where the TFI
  // of the moved sides puts them (no surface, flat, no interior nodes, or
  // already on the CAD).
  bool place_face(Id f, const std::vector<double>& probe, bool& closest, std::vector<Vec3>& pts) {
      const size_t np = probe.size();
      const Owner o = fowner_[f];
      const CadEntity* ent = o.dim == 2 ? cad_.find(2, o.tag) : nullptr;
      if (!ent || ent->flat) return false;
      const FaceRow r = face(f);
      const Id nu = r.nu, nv = r.nv;
      if (nu < 2 || nv < 2) return false;
      const Vec3 c[4] = {vertex(r.v[0]), vertex(r.v[1]), vertex(r.v[2]), vertex(r.v[3])};
      const double diam = std::max(dist(c[0], c[2]), dist(c[1], c[3]));
      // The plan, from probes (s, t) = (i, j) / kProbes: the TFI prediction
      // there (the Coons patch of the moved sides), its closest points, and
      // the Coons patch of the sides' parameters.
      std::vector<Vec3> side[4];
      for (int k = 0; k < 4; ++k) side[k] = side_points(r, k, probe);
      std::vector<Vec3> pred;
      for (size_t j = 0; j < np; ++j)
        for (size_t i = 0; i < np; ++i) pred.push_back(coons(probe[i], probe[j], side[0][i], side[1][i], side[2][j], side[3][j], c));
      const std::vector<Vec3> proj = project(*ent, pred);
      std::vector<double> bxyz;  // corners, then the four sides' probes
      for (const Vec3& x : c) push(bxyz, x);
      for (const auto& sd : side)
        for (const Vec3& x : sd) push(bxyz, x);
      std::vector<double> uv;
      cad_.param(2, o.tag, bxyz, uv);
      const double ref[2] = {uv[0], uv[1]};
      for (size_t i = 0; i < uv.size() / 2; ++i) unwrap(*ent, &uv[2 * i], ref);
      std::vector<Vec3> par;
      const auto grading = RowReader(T_, cur_).face_grading(r);
      const tfi::Series su(nu, grading[0]), sv(nv, grading[1]);
      if (!degenerate(*ent, uv)) {
        auto P = [&](size_t i, int k) { return uv[2 * i + k]; };  // 0..3 corners, then sides from 4 + k np
        std::vector<double> q, xyz;
        for (size_t j = 0; j < np; ++j)
          for (size_t i = 0; i < np; ++i)
            for (int k = 0; k < 2; ++k)
              q.push_back(tfi::coons(probe[i], probe[j], P(4 + i, k), P(4 + np + i, k), P(4 + 2 * np + j, k),
                                     P(4 + 3 * np + j, k), P(0, k), P(1, k), P(2, k), P(3, k)));
        cad_.value(2, o.tag, q, xyz);
        for (size_t i = 0; i < pred.size(); ++i) par.push_back(at(xyz, i));
      }
      const bool param = !par.empty() && plausible(par, proj, 0.25 * diam / kProbes + tol_);
      const Place how = settle(param ? Place::Parametric : Place::Closest, param ? par : proj, pred);
      if (how == Place::Predicted) return false;
      closest = how == Place::Closest;
      // The nodes: from the face's current nodes (Coons of moved sides, or
      // bilinear where none moved: within rounding of move_nodes' prediction).
      std::vector<Vec3> npred;
      for (Id v = 1; v < nv; ++v)
        for (Id u = 1; u < nu; ++u) npred.push_back(node(EntityKind::Face, f, u, v));
      if (how == Place::Closest) {
        pts = project(*ent, npred);
      } else {
        // The moved boundary: bottom, top (u = 0..nu), left, right (v = 0..nv).
        std::vector<double> nb;
        for (Id u = 0; u <= nu; ++u) push(nb, node(EntityKind::Face, f, u, 0));
        for (Id u = 0; u <= nu; ++u) push(nb, node(EntityKind::Face, f, u, nv));
        for (Id v = 0; v <= nv; ++v) push(nb, node(EntityKind::Face, f, 0, v));
        for (Id v = 0; v <= nv; ++v) push(nb, node(EntityKind::Face, f, nu, v));
        std::vector<double> buv;
        cad_.param(2, o.tag, nb, buv);
        for (size_t i = 0; i < buv.size() / 2; ++i) unwrap(*ent, &buv[2 * i], ref);
        const size_t B = 0, Tp = static_cast<size_t>(nu + 1), Lf = 2 * Tp, R = Lf + static_cast<size_t>(nv + 1);
        auto P = [&](size_t i, int k) { return buv[2 * i + k]; };
        std::vector<double> q, xyz;
        for (Id v = 1; v < nv; ++v)
          for (Id u = 1; u < nu; ++u) {
            const double s = su.at(u), t = sv.at(v);
            for (int k = 0; k < 2; ++k)
              q.push_back(tfi::coons(s, t, P(B + u, k), P(Tp + u, k), P(Lf + v, k), P(R + v, k), P(B, k),
                                     P(B + nu, k), P(Tp + nu, k), P(Tp, k)));
          }
        cad_.value(2, o.tag, q, xyz);
        for (size_t i = 0; i < npred.size(); ++i) pts.push_back(at(xyz, i));
      }
      return true;
  }

  static Vec3 coons(double s, double t, const Vec3& b, const Vec3& tp, const Vec3& l, const Vec3& r, const Vec3* c) {
    return {tfi::coons(s, t, b.x, tp.x, l.x, r.x, c[0].x, c[1].x, c[2].x, c[3].x),
            tfi::coons(s, t, b.y, tp.y, l.y, r.y, c[0].y, c[1].y, c[2].y, c[3].y),
            tfi::coons(s, t, b.z, tp.z, l.z, r.z, c[0].z, c[1].z, c[2].z, c[3].z)};
  }

  void check_inversion() {
    auto bar = [&](Id d, Id t) { progress("checking elements", d, t); };
    QualityReport q;
    if (!distributed()) {
      q = check_moved_quality(mesh_, bar);
    } else {
      // Every parts-th coarse element here, the reports merged in element order.
      QualityReport mine_q;
      std::exception_ptr failed;
      try {
        MeshCursor cur;
        const RowReader R(T_, cur);
        const auto P = static_cast<Id>(opt_.parts);
        mine_q = check_quality(mesh_, [&](Id h) { return h % P == opt_.part && R.element(h).curved(); }, bar);
      } catch (...) {
        failed = std::current_exception();
      }
      Bytes out;
      out.put(mine_q);
      for (const std::string& part : exchange(opt_, out.s, failed, 0)) merge_quality(q, Cursor(part).get<QualityReport>());
    }
    rep_.min_scaled_jacobian = q.min_scaled_jacobian;
    rep_.elements_checked = q.elements_checked;
    if (q.inverted > 0) {
      const CoarseMesh* c = mesh_.coarse();
      const Id file_id = c ? c->element_file_id[q.worst_coarse_element] : q.worst_coarse_element + 1;
      throw Error(ErrorKind::Geometry,
                  src() + ": moving the boundary onto " + cad_.path() + " would invert " + std::to_string(q.inverted) +
                      " fine element(s); the worst is fine element " + std::to_string(q.worst_element) +
                      " (the store's id) in coarse element " + std::to_string(file_id) + " (" + src() +
                      "'s element id; scaled Jacobian " + fmt(q.min_scaled_jacobian) +
                      "): refine the coarse mesh there or check that it matches the CAD; nothing was written");
    }
  }
};

}  // namespace

ConformReport conform_to_geometry(FineMesh& mesh, const std::string& cad_path, const ConformOptions& options) {
  if (!(options.tolerance > 0 && options.tolerance < 1))
    throw Error(ErrorKind::Usage, "geometry tolerance (--geometry-tol) " + fmt(options.tolerance) +
                                      " must be in (0, 1): a fraction of the CAD model's diagonal");
  if (options.parts > 1 && !options.share) throw Error(ErrorKind::Usage, "conform: parts > 1 without share");
  auto run = [&](const Cad& cad) {
    ConformReport r = cad.with_reader_said([&] { return Conformer(mesh, cad, options).run(); });
    r.cad_reader_said = cad.reader_said();
    return r;
  };
  if (options.parts <= 1) return run(Cad(cad_path));
  // A part that cannot load the CAD still takes part in the first
  // exchange, where every part throws (the others wait there otherwise).
  std::unique_ptr<Cad> cad;
  std::exception_ptr early;
  try {
    cad = std::make_unique<Cad>(cad_path);
  } catch (...) {
    early = std::current_exception();
  }
  if (cad) return run(*cad);
  exchange(options, {}, early, 0);
  std::rethrow_exception(early);  // not reached: the exchange throws it
}

void classify_on_geometry(CoarseMesh& mesh, const std::string& cad_path, const ConformOptions& options) {
  if (!(options.tolerance > 0 && options.tolerance < 1))
    throw Error(ErrorKind::Usage, "geometry tolerance (--geometry-tol) " + fmt(options.tolerance) +
                                      " must be in (0, 1): a fraction of the CAD model's diagonal");
  const Cad cad(cad_path);
  // The owners as conform_to_geometry finds them, on the mesh diced once
  // (interval 1: its tables are the coarse mesh's), mapped back by file id.
  FineMesh once = FineMesh::dice(mesh, IntervalRequest{});
  const auto owners = cad.with_reader_said([&] { return Conformer(once, cad, options).vertex_owners(); });
  const Id V = mesh.num_vertices();
  std::map<Id, Id> vertex_of_file_id;
  for (Id v = 0; v < V; ++v) vertex_of_file_id.emplace(mesh.vertex_file_id[v], v);
  std::vector<std::int8_t> dim(static_cast<size_t>(V), -1);
  std::vector<std::int32_t> tag(static_cast<size_t>(V), -1);
  const auto& volumes = cad.entities(3);
  for (Id v = 0; v < V; ++v)  // not on the boundary: the only volume, or the file's volume
    if (volumes.size() == 1) dim[v] = 3, tag[v] = volumes[0].tag;
    else if (static_cast<size_t>(v) < mesh.vertex_geo_dim.size() && mesh.vertex_geo_dim[v] == 3 &&
             cad.find(3, mesh.vertex_geo_tag[v]))
      dim[v] = 3, tag[v] = mesh.vertex_geo_tag[v];
  const CoarseMesh& ordered = *once.coarse();
  for (size_t w = 0; w < owners.size(); ++w) {
    if (owners[w].first < 0) continue;
    const Id v = vertex_of_file_id.at(ordered.vertex_file_id[w]);
    dim[v] = static_cast<std::int8_t>(owners[w].first), tag[v] = owners[w].second;
  }
  mesh.vertex_geo_dim = std::move(dim), mesh.vertex_geo_tag = std::move(tag);
  mesh.geo_entities.clear();
  for (int d = 1; d <= 3; ++d)
    for (const CadEntity& e : cad.entities(d)) {
      GeoEntity g{d, e.tag, {}};
      for (const CadEntity& b : cad.entities(d - 1))
        if (std::find(b.up.begin(), b.up.end(), e.tag) != b.up.end()) g.bounding.push_back(b.tag);
      mesh.geo_entities.push_back(std::move(g));
    }
}

// ---------------------------------------------------------------- verify

namespace {
GeometryCheck check_with(const FineMesh& mesh, const Cad& cad, const std::string& cad_path,
                         const std::function<void(Id, Id)>& progress) {
  GeometryCheck g;
  g.diagonal = cad.diagonal();
  g.tolerance = std::max(1e-9 * g.diagonal, kKernelTolerance);
  const MeshTables& T = mesh.tables();
  MeshCursor cur;
  auto check = [&](int dim, int tag, const std::vector<Vec3>& pts, const std::vector<Id>& ids) {
    if (pts.empty() || dim < 0 || dim > 2) return;
    if (!cad.find(dim, tag))
      throw Error(ErrorKind::Geometry, cad_path + ": the store names CAD " + dim_name(dim) + " " + std::to_string(tag) +
                                           ", which this CAD file does not have (a different CAD file?)");
    const auto d = distances(cad, {dim, tag}, pts);
    for (size_t i = 0; i < d.size(); ++i) {
      ++g.nodes_checked;
      if (d[i] > g.max_distance || g.worst_node < 0)
        g.max_distance = std::max(g.max_distance, d[i]), g.worst_node = ids[i],
        g.worst_entity = std::string(dim_name(dim)) + " " + std::to_string(tag);
    }
  };
  // Nodes of unplaced faces, a batch at a time: each against the surfaces
  // whose box holds it (every surface when none does), the nearest counts.
  std::vector<Vec3> loose;
  std::vector<Id> loose_ids;
  auto measure_loose = [&] {
    if (loose.empty()) return;
    std::vector<double> best(loose.size(), INFINITY);
    std::vector<int> best_tag(loose.size(), -1);
    auto against = [&](const CadEntity& e, const std::vector<size_t>& which) {
      if (which.empty()) return;
      std::vector<Vec3> pts;
      for (size_t i : which) pts.push_back(loose[i]);
      const auto d = distances(cad, {2, e.tag}, pts);
      for (size_t k = 0; k < which.size(); ++k)
        if (d[k] < best[which[k]]) best[which[k]] = d[k], best_tag[which[k]] = e.tag;
    };
    for (const CadEntity& e : cad.entities(2)) {
      std::vector<size_t> which;
      for (size_t i = 0; i < loose.size(); ++i)  // a node already on a surface needs no other
        if (!(best[i] <= g.tolerance) && in_box(e, loose[i], g.tolerance)) which.push_back(i);
      against(e, which);
    }
    std::vector<size_t> far;
    for (size_t i = 0; i < loose.size(); ++i)
      if (best_tag[i] < 0) far.push_back(i);
    for (const CadEntity& e : cad.entities(2)) against(e, far);
    for (size_t i = 0; i < loose.size(); ++i) {
      ++g.nodes_checked;
      if (best[i] > g.max_distance || g.worst_node < 0)
        g.max_distance = std::max(g.max_distance, best[i]), g.worst_node = loose_ids[i],
        g.worst_entity = "surface " + std::to_string(best_tag[i]) + " (the nearest; the store names none)";
    }
    loose.clear(), loose_ids.clear();
  };
  const Id V = T.num_vertices(), E = T.edges.rows(), F = T.faces.rows();
  const Id total = V + E + F;
  // Vertices, grouped per entity for batched projections.
  std::map<std::pair<int, int>, std::pair<std::vector<Vec3>, std::vector<Id>>> groups;
  for (Id v = 0; v < V; ++v) {
    const std::int64_t o = mesh.owner(EntityKind::Vertex, v, cur);
    if (owner_dim(o) < 0 || owner_dim(o) > 2) continue;
    auto& gr = groups[{owner_dim(o), owner_tag(o)}];
    NodeRef r;
    r.kind = EntityKind::Vertex, r.entity = v;
    gr.first.push_back(mesh.node(r, cur));
    gr.second.push_back(mesh.node_id(r, cur));
  }
  for (const auto& [k, gr] : groups) check(k.first, k.second, gr.first, gr.second);
  for (Id e = 0; e < E; ++e) {
    if (progress && (e & 255) == 0) progress(V + e, total);
    const std::int64_t o = mesh.owner(EntityKind::Edge, e, cur);
    if (owner_dim(o) < 1 || owner_dim(o) > 2) continue;
    const Id n = RowReader(T, cur).edge(e).n;
    std::vector<Vec3> pts;
    std::vector<Id> ids;
    for (Id t = 1; t < n; ++t) {
      NodeRef r;
      r.kind = EntityKind::Edge, r.entity = e, r.local = {t, 0, 0};
      pts.push_back(mesh.node(r, cur)), ids.push_back(mesh.node_id(r, cur));
    }
    check(owner_dim(o), owner_tag(o), pts, ids);
  }
  for (Id f = 0; f < F; ++f) {
    if (progress && (f & 255) == 0) progress(V + E + f, total);
    const std::int64_t o = mesh.owner(EntityKind::Face, f, cur);
    const FaceRow r = RowReader(T, cur).face(f);
    // A boundary face the store puts on no CAD surface (a store diced
    // without --geometry): its nodes were never placed, so they are measured
    // against the nearest surface instead (a planar part passes, a curved
    // one does not).
    const bool unplaced = owner_dim(o) != 2 && (mesh.mode() == Mode::Surface || r.other_element < 0);
    if (owner_dim(o) != 2 && !unplaced) continue;
    const Id nu = r.nu, nv = r.nv;
    std::vector<Vec3> pts;
    std::vector<Id> ids;
    for (Id v = 1; v < nv; ++v)
      for (Id u = 1; u < nu; ++u) {
        NodeRef q;
        q.kind = EntityKind::Face, q.entity = f, q.local = {u, v, 0};
        pts.push_back(mesh.node(q, cur)), ids.push_back(mesh.node_id(q, cur));
      }
    if (!unplaced) {
      check(2, owner_tag(o), pts, ids);
      continue;
    }
    ++g.unplaced_faces;
    loose.insert(loose.end(), pts.begin(), pts.end());
    loose_ids.insert(loose_ids.end(), ids.begin(), ids.end());
    if (loose.size() >= (1u << 16)) measure_loose();
  }
  measure_loose();
  if (progress) progress(total, total);
  return g;
}
}  // namespace

GeometryCheck check_geometry(const FineMesh& mesh, const std::string& cad_path, const std::function<void(Id, Id)>& progress) {
  const Cad cad(cad_path);
  GeometryCheck g = cad.with_reader_said([&] { return check_with(mesh, cad, cad_path, progress); });
  g.cad_reader_said = cad.reader_said();
  return g;
}

}  // namespace dicer
