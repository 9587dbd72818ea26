#include "dicer/verify.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>
#include <unordered_map>

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/quality.hpp"
#include "dicer/rows.hpp"
#include "evaluate.hpp"
#include "verify_coincident.hpp"

namespace dicer {
namespace {

std::uint64_t mix(std::uint64_t h, std::uint64_t v) {
  // splitmix64 step over the running value: order-dependent within a face,
  // summed (order-independent) across faces.
  h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
  h += 0x9e3779b97f4a7c15ull;
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  return h ^ (h >> 31);
}
std::uint64_t bits(double d) { return std::bit_cast<std::uint64_t>(d); }

void note(VerifyReport& r, const std::string& s) {
  if (r.problems.size() < 20) r.problems.push_back(s);
}

struct FaceSide {
  std::uint64_t hash = 0;
  Id count = 0;
  bool seen = false;
};

}  // namespace

VerifyPart verify_part(const FineMesh& mesh, Id first, Id end, const std::function<void(Id, Id)>& progress) {
  VerifyPart part;
  VerifyReport& r = part.report;
  const MeshTables& t = mesh.tables();
  const bool vol = mesh.mode() == Mode::Volume;
  const int nc = mesh.corners();
  MeshCursor cur;
  const RowReader R(t, cur);
  r.nodes = mesh.num_nodes();
  r.elements = mesh.num_elements();
  if (end < 0) end = mesh.num_coarse_elements();
  // What the part sees of each coarse face (two sides at most) and edge,
  // kept only for the entities its elements use.
  std::unordered_map<Id, std::array<FaceSide, 2>> side;
  std::unordered_map<Id, std::array<std::uint64_t, 2>> edge_hash;  // edge -> (first hash, uses disagreed)
  std::unordered_map<Id, std::array<std::int64_t, 2>> edge_use;  // surface: quads, direction sum

  FineBlock b;
  std::vector<std::pair<Id, Id>> ids;          // (id, point)
  std::vector<std::array<double, 4>> coords;   // (x, y, z, id)
  std::vector<std::pair<std::array<Id, 4>, int>> faces;  // sorted ids, boundary side (-1 interior)
  const Id nh = end - first;
  // verify checks a coarse element whole (its fine faces matched by a
  // sort): about 100 bytes per point and 250 per fine element held. An
  // element too large for that is refused by name, before (or when) its
  // allocation fails, not killed by the OS.
  std::array<Id, 3> n_now{};
  Id h_now = first;
  const char* const how = "is checked whole by verify";
  auto need = [&] {
    const auto& n = n_now;
    return 100 * double(n[0] + 1) * double(n[1] + 1) * double(vol ? n[2] + 1 : 1) +
           250 * double(n[0]) * double(n[1]) * double(vol ? n[2] : 1);
  };
  auto too_big = [&] { return element_too_big(mesh, h_now, n_now, how, need()); };
  try {
  for (Id h = first; h < end; ++h) {
    h_now = h, n_now = R.element(h).n;
    // Less what the arrays hold from the last element (reused, not added).
    check_element_memory(mesh, h, n_now, how, need(),
                         static_cast<double>(b.held_bytes() + ids.capacity() * sizeof(ids[0]) +
                                             coords.capacity() * sizeof(coords[0]) + faces.capacity() * sizeof(faces[0])));
    mesh.fill_block(h, b);
    const auto n = b.n;
    const Id ni = n[0] + 1, nj = n[1] + 1, nk = vol ? n[2] + 1 : 1;

    // Ids: range, round trip, bit identity.
    ids.clear();
    coords.clear();
    for (Id k = 0; k < nk; ++k)
      for (Id j = 0; j < nj; ++j)
        for (Id i = 0; i < ni; ++i) {
          const Id g = b.point_index(i, j, k), id = b.node_id[g];
          ids.emplace_back(id, g);
          coords.push_back({b.x[g], b.y[g], b.z[g], static_cast<double>(id)});
          if (id < 0 || id >= r.nodes) {
            ++r.id_errors;
            note(r, "coarse element " + std::to_string(h) + ": node id " + std::to_string(id) + " out of range");
            continue;
          }
          const NodeRef ref = mesh.locate_node(id, cur);
          if (mesh.node_id(ref, cur) != id || !(ref == mesh.grid_node(h, i, j, k, cur))) {
            ++r.id_errors;
            note(r, "node " + std::to_string(id) + " does not round-trip through its owner");
          }
          const bool interior = ref.kind == EntityKind::Cell;
          if (!interior || (i == j && (!vol || j == k))) {
            const Vec3 p = mesh.node(ref, cur);
            if (bits(p.x) != bits(b.x[g]) || bits(p.y) != bits(b.y[g]) || bits(p.z) != bits(b.z[g])) {
              ++r.bit_identity_errors;
              note(r, "node " + std::to_string(id) + ": node(id) differs from the block fill");
            }
          }
        }
    std::sort(ids.begin(), ids.end());
    for (size_t q = 1; q < ids.size(); ++q)
      if (ids[q].first == ids[q - 1].first) {
        ++r.id_errors;
        note(r, "coarse element " + std::to_string(h) + ": node id " + std::to_string(ids[q].first) +
                    " used at two grid points");
      }
    std::sort(coords.begin(), coords.end());
    for (size_t q = 1; q < coords.size(); ++q)
      if (coords[q][0] == coords[q - 1][0] && coords[q][1] == coords[q - 1][1] && coords[q][2] == coords[q - 1][2] &&
          coords[q][3] != coords[q - 1][3]) {
        ++r.coincident_nodes;
        note(r, "coarse element " + std::to_string(h) + ": nodes " + std::to_string(Id(coords[q][3])) + " and " +
                    std::to_string(Id(coords[q - 1][3])) + " coincide");
      }

    // Fine faces (hex) or edges (quad) of every element, with the block side they lie on.
    faces.clear();
    const Id ne = b.num_elements();
    const Vec3 normal = vol ? Vec3{} : block_normal(b);
    for (Id e = 0; e < ne; ++e) {
      const Id i = e % n[0], j = (e / n[0]) % n[1], k = e / (n[0] * n[1]);
      const Id* c = &b.conn[static_cast<size_t>(e) * nc];
      if (vol) {
        for (int lf = 0; lf < 6; ++lf) {
          std::array<Id, 4> key;
          for (int q = 0; q < 4; ++q) key[q] = c[kHexFace[lf][q]];
          std::sort(key.begin(), key.end());
          const int axis = lf / 2;
          const Id p = axis == 0 ? i : axis == 1 ? j : k;
          const bool on = (lf % 2 == 0) ? p == 0 : p == n[axis] - 1;
          faces.emplace_back(key, on ? lf : -1);
        }
      } else {
        for (int s = 0; s < 4; ++s) {
          const Id a = c[kShellSideCorners[s][0]], bb = c[kShellSideCorners[s][1]];
          const std::array<Id, 4> key{std::min(a, bb), std::max(a, bb), -1, -1};
          const SidePlane plane = exodus_side_plane(Mode::Surface, s + 2);
          const Id p = plane.axis == 0 ? i : j;
          const bool on = p == (plane.high ? n[plane.axis] - 1 : 0);
          faces.emplace_back(key, on ? s : -1);
        }
      }
      const double sj = element_scaled_jacobian(b, i, j, k, normal);
      r.min_scaled_jacobian = std::min(r.min_scaled_jacobian, sj);
      if (sj <= 0) {
        ++r.inverted;
        char sjt[32];  // %g: a sliver's -1e-09 is not to_string's "-0.000000"
        std::snprintf(sjt, sizeof sjt, "%.6g", sj);
        note(r, "fine element " + std::to_string(b.first_element + e) + " is inverted (scaled Jacobian " + sjt + ")");
      }
    }
    std::sort(faces.begin(), faces.end());
    r.fine_faces_checked += static_cast<Id>(faces.size());
    for (size_t q = 0; q < faces.size();) {
      size_t q2 = q;
      while (q2 < faces.size() && faces[q2].first == faces[q].first) ++q2;
      const Id count = static_cast<Id>(q2 - q);
      const bool boundary = faces[q].second >= 0;
      if (count != (boundary ? 1 : 2)) {
        ++r.conformity_errors;
        note(r, "coarse element " + std::to_string(h) + ": a fine face is shared by " + std::to_string(count) +
                    " fine elements");
      }
      q = q2;
    }

    // The spatial index: the element's bounds hold every node (so a box
    // query or a point search that skips the element skips none of it).
    const ElementRow row = R.element(h);
    {
      const ElementBounds box = R.bounds(h);
      for (Id g = 0; g < b.num_points(); ++g)
        if (!box.contains({b.x[g], b.y[g], b.z[g]})) {
          ++r.index_errors;
          note(r, "coarse element " + std::to_string(h) + ": node " + std::to_string(b.node_id[g]) +
                      " lies outside topology/element_bounds row " + std::to_string(h));
          break;
        }
      // Neighbours: the element is the owner or the other element of each
      // of its faces (volume) or edges (surface).
      for (int k = 0; k < (vol ? 6 : 4); ++k) {
        Id owner, other;
        if (vol) {
          const FaceRow fr = R.face(row.face[k]);
          owner = fr.owner_element, other = fr.other_element;
        } else {
          const EdgeRow er = R.edge(row.edge[k]);
          owner = er.owner_element, other = er.other_element;
        }
        if (owner != h && other != h && (vol || other != -1)) {  // surface -1: non-manifold
          ++r.index_errors;
          note(r, "coarse element " + std::to_string(h) + ": its " + (vol ? "face " : "edge ") +
                      std::to_string(vol ? row.face[k] : row.edge[k]) + " names elements " + std::to_string(owner) +
                      " and " + std::to_string(other) + ", not it");
        }
      }
    }
    // Coarse faces (volume) / coarse edges (both modes): hash what this block sees.
    if (vol) {
      for (int lf = 0; lf < 6; ++lf) {
        const Id f = row.face[lf];
        auto& both = side[f];
        FaceSide* fs = &both[0];
        if (fs->seen) fs = &both[1];
        if (fs->seen) {
          ++r.conformity_errors;
          note(r, "coarse face " + std::to_string(f) + " is shared by more than two coarse hexes");
          continue;
        }
        fs->seen = true;
        for (const auto& [key, s] : faces) {
          if (s != lf) continue;
          std::uint64_t hv = 0;
          for (Id id : key) {
            const auto it = std::lower_bound(ids.begin(), ids.end(), std::make_pair(id, Id{-1}));
            const Id g = it->second;
            hv = mix(mix(mix(mix(hv, static_cast<std::uint64_t>(id)), bits(b.x[g])), bits(b.y[g])), bits(b.z[g]));
          }
          fs->hash += hv;
          ++fs->count;
        }
      }
    }
    const int epe = R.edges();
    if (!vol)
      for (int s = 0; s < 4; ++s) {  // cyclic side s runs corner s -> s+1
        const Id a = row.corner[kShellSideCorners[s][0]], bb = row.corner[kShellSideCorners[s][1]];
        const int le = quad_edge_at(exodus_side_plane(Mode::Surface, s + 2).axis == 0 ? 1 : 0,
                                    exodus_side_plane(Mode::Surface, s + 2).high);
        auto& u = edge_use[row.edge[le]];
        ++u[0];
        u[1] += a < bb ? 1 : -1;
      }
    for (int le = 0; le < epe; ++le) {
      const Id e = row.edge[le];
      const int axis = vol ? le / 4 : le / 2;
      const int a = vol ? kHexEdge[le][0] : kQuadEdge[le][0];
      std::uint64_t hv = 0;
      const Id ne_ = n[axis];
      for (Id s = 0; s <= ne_; ++s) {
        const Id tt = row.rev(le) ? ne_ - s : s;  // canonical order
        Id p[3] = {kHexCorner[a][0] * n[0], kHexCorner[a][1] * n[1], vol ? kHexCorner[a][2] * n[2] : 0};
        p[axis] = tt;
        const Id g = b.point_index(p[0], p[1], p[2]);
        hv = mix(mix(mix(mix(hv, static_cast<std::uint64_t>(b.node_id[g])), bits(b.x[g])), bits(b.y[g])),
                 bits(b.z[g]));
      }
      // Counted once per edge by verify_finish, so the count is the same
      // however the elements are split into parts.
      const auto [it, fresh] = edge_hash.try_emplace(e, std::array<std::uint64_t, 2>{hv, 0});
      if (!fresh && it->second[0] != hv) it->second[1] = 1;
    }
    if (progress) progress(h + 1 - first, nh);
  }
  } catch (const std::bad_alloc&) {
    throw too_big();
  }
  for (const auto& [f, both] : side)
    for (const FaceSide& fs : both)
      if (fs.seen) part.face_sides.push_back({static_cast<std::uint64_t>(f), static_cast<std::uint64_t>(fs.count), fs.hash});
  for (const auto& [e, hv] : edge_hash) part.edge_hashes.push_back({static_cast<std::uint64_t>(e), hv[0], hv[1]});
  for (const auto& [e, u] : edge_use) part.edge_uses.push_back({e, u[0], u[1]});
  // Deterministic order (the maps' is not): the merge's "first seen" and its notes.
  std::sort(part.face_sides.begin(), part.face_sides.end());
  std::sort(part.edge_hashes.begin(), part.edge_hashes.end());
  std::sort(part.edge_uses.begin(), part.edge_uses.end());
  return part;
}

VerifyReport verify_finish(const FineMesh& mesh, const std::vector<VerifyPart>& parts) {
  VerifyReport r;
  const MeshTables& t = mesh.tables();
  const MeshInfo& info = mesh.info();
  const bool vol = mesh.mode() == Mode::Volume;
  MeshCursor cur;
  const RowReader R(t, cur);
  // The parts' own findings.
  for (const VerifyPart& p : parts) {
    const VerifyReport& q = p.report;
    r.fine_faces_checked += q.fine_faces_checked;
    r.id_errors += q.id_errors, r.bit_identity_errors += q.bit_identity_errors;
    r.coincident_nodes += q.coincident_nodes, r.conformity_errors += q.conformity_errors;
    r.inverted += q.inverted, r.index_errors += q.index_errors;
    r.min_scaled_jacobian = std::min(r.min_scaled_jacobian, q.min_scaled_jacobian);
    for (const auto& s : q.problems) note(r, s);
    for (const auto& s : q.warnings) r.warnings.push_back(s);
  }

  // Closed formula from the edge intervals alone (not from the stored
  // offsets, nor the faces' and elements' own interval columns).
  {
    __int128 nodes = info.coarse_vertices, elems = 0;
    for (Id e = 0; e < t.edges.rows(); ++e) nodes += R.edge(e).n - 1;
    std::vector<__int128> block_elems(info.blocks.size(), 0);
    std::vector<Id> block_coarse(info.blocks.size(), 0);
    // Gradings agree too: opposite sides of every face (face_grading is
    // Corrupt otherwise) and every element's axes with its edges' rows (a
    // straight element's fill reads only its own row), and so does every
    // element's curved flag with its edges' and faces' bounding rows.
    for (Id f = 0; f < t.faces.rows(); ++f) {
      const FaceRow fr = R.face(f);
      nodes += static_cast<__int128>(R.edge(fr.e[0]).n - 1) * (R.edge(fr.e[2]).n - 1);
      R.face_grading(fr);
    }
    for (Id h = 0; h < t.elements.rows(); ++h) {
      const ElementRow row = R.element(h);
      bool moved = false;  // the curved flag's definition (FORMAT.md): a straight element's paths read no rows
      for (int k = 0; k < R.edges(); ++k) {
        const EdgeRow er = R.edge(row.edge[k]);
        if (!(er.grading == row.edge_grading(k, t.mode)))
          R.corrupt(RowTable::Edges, row.edge[k], "grading disagrees with element " + std::to_string(h) + " using the edge");
        moved |= er.bound >= 0;
      }
      for (int k = 0; k < R.faces(); ++k) moved |= R.face(row.face[k]).bound >= 0;
      if (moved != row.curved())
        R.corrupt(RowTable::Elements, h,
                  moved ? "flagged straight, but an edge or face of it has moved nodes (bounding rows)"
                        : "flagged curved, but no edge or face of it has moved nodes (bounding rows)");
      const __int128 n0 = R.edge(row.edge[0]).n, n1 = R.edge(row.edge[vol ? 4 : 2]).n, n2 = vol ? R.edge(row.edge[8]).n : 1;
      if (vol) nodes += (n0 - 1) * (n1 - 1) * (n2 - 1);
      elems += n0 * n1 * n2;
      if (row.block >= 0 && static_cast<size_t>(row.block) < block_elems.size())
        block_elems[row.block] += n0 * n1 * n2, ++block_coarse[row.block];
    }
    auto clamp = [](__int128 v) { return v > INT64_MAX ? INT64_MAX : static_cast<Id>(v); };
    r.nodes_formula = clamp(nodes);
    r.elements_formula = clamp(elems);
    r.nodes = mesh.num_nodes();
    r.elements = mesh.num_elements();
    __int128 by_block = 0;
    for (Id c : info.block_fine_elements) by_block += c;
    // Each block's count as its elements give it (info prints these; the
    // sum alone let two blocks trade elements).
    for (size_t b = 0; b < block_elems.size() && b < info.block_fine_elements.size() && b < info.block_coarse_elements.size();
         ++b)
      if (block_elems[b] != info.block_fine_elements[b] || block_coarse[b] != info.block_coarse_elements[b]) {
        r.id_errors += 1;
        note(r, "block " + std::to_string(info.blocks[b].id) + ": coarse/block_coarse_elements and block_fine_elements say " +
                    std::to_string(info.block_coarse_elements[b]) + " and " + std::to_string(info.block_fine_elements[b]) +
                    ", its elements are " + std::to_string(block_coarse[b]) + " holding " +
                    std::to_string(static_cast<Id>(block_elems[b])));
      }
    if (!r.counts_ok() || by_block != elems) {
      r.id_errors += 1;
      note(r, "counts differ from the closed formula: nodes " + std::to_string(r.nodes) + " vs " +
                  std::to_string(r.nodes_formula) + ", elements " + std::to_string(r.elements) + " vs " +
                  std::to_string(r.elements_formula));
    }
  }

  // The sheets (info prints them, transfer matches levels by them): every
  // edge's interval and grading are its sheet's, the parallel edges of an
  // element lie in one sheet, every sheet holds an edge. A mesh built
  // without its sheet table (sheet_intervals() empty) has none to check.
  if (const auto& si = mesh.sheet_intervals(); !si.empty()) {
    const auto& sg = mesh.sheet_gradings();
    const std::string store = t.origin.empty() ? std::string("in memory") : t.origin;
    if (static_cast<Id>(si.size()) != info.sheets || (!sg.empty() && sg.size() != si.size()))
      throw Error(ErrorKind::Corrupt, store + ": sheets/sheet_interval: not one row per sheet");
    std::vector<std::uint8_t> used(si.size(), 0);
    for (Id e = 0; e < t.edges.rows(); ++e) {
      const EdgeRow er = R.edge(e);  // its sheet is in range (the row's check)
      const auto s = static_cast<size_t>(er.sheet);
      used[s] = 1;
      if (er.n != si[s])
        R.corrupt(RowTable::Edges, e, "interval " + std::to_string(er.n) + ", its sheet " + std::to_string(s) +
                                          "'s (sheets/sheet_interval) " + std::to_string(si[s]));
      if (!sg.empty()) {
        const tfi::Grading& g = sg[s].grading;
        if (er.grading.kind != g.kind || (g.kind != tfi::Spacing::Equal && er.grading.ratio != g.ratio))
          R.corrupt(RowTable::Edges, e, "grading disagrees with its sheet " + std::to_string(s) + "'s (sheets/sheet_grading)");
      }
    }
    for (size_t s = 0; s < used.size(); ++s)
      if (!used[s])
        throw Error(ErrorKind::Corrupt, store + ": sheets/sheet_interval row " + std::to_string(s) + ": no edge lies in the sheet");
    const int per_axis = vol ? 4 : 2;
    for (Id h = 0; h < t.elements.rows(); ++h) {
      const ElementRow row = R.element(h);
      for (int k = 0; k < R.edges(); ++k) {
        const Id first = row.edge[k - k % per_axis], s0 = R.edge(first).sheet, s = R.edge(row.edge[k]).sheet;
        if (s != s0)
          R.corrupt(RowTable::Edges, row.edge[k], "sheet " + std::to_string(s) + ", but edge " + std::to_string(first) +
                                                     ", parallel to it in element " + std::to_string(h) + ", is in sheet " +
                                                     std::to_string(s0));
      }
    }
  }

  // The page index of a store (the searches for ids rely on it): the first
  // row of every page of the elements, as the index says.
  if (!t.node_index.empty() || !t.element_index.empty()) {
    const Id rpp = t.elements.rows_per_page(), pages = t.elements.pages();
    const std::string store = t.origin.empty() ? std::string("in memory") : t.origin;
    if (static_cast<Id>(t.node_index.size()) != pages || static_cast<Id>(t.element_index.size()) != pages)
      throw Error(ErrorKind::Corrupt, store + ": numbering/element_page_node: not one entry per page of topology/elements");
    for (Id p = 0; p < pages; ++p)
      if (t.node_index[p] != R.node_first(p * rpp) || t.element_index[p] != R.element_first(p * rpp))
        throw Error(ErrorKind::Corrupt, store + ": numbering/element_page_node or element_page_element entry " +
                                            std::to_string(p) + " disagrees with the first row of its page");
  }

  // The spatial index: every group's box holds its elements' boxes.
  {
    const Id H = t.elements.rows(), groups = (H + kBoundsGroup - 1) / kBoundsGroup;
    if (static_cast<Id>(t.group_bounds.size()) != 6 * groups)
      throw Error(ErrorKind::Corrupt, (t.origin.empty() ? std::string("in memory") : t.origin) +
                                          ": index/group_bounds: not one box per group of " +
                                          std::to_string(kBoundsGroup) + " coarse elements");
    for (Id h = 0; h < H; ++h) {
      const ElementBounds e = R.bounds(h);
      const double* g = &t.group_bounds[static_cast<size_t>(h / kBoundsGroup) * 6];
      for (int d = 0; d < 3; ++d)
        if (e.lo[d] < g[d] || e.hi[d] > g[3 + d]) {
          ++r.index_errors;
          note(r, "coarse element " + std::to_string(h) + ": its bounds leave index/group_bounds row " +
                      std::to_string(h / kBoundsGroup));
          break;
        }
    }
  }

  // Coincident coarse vertices (the only nodes two blocks can share by position alone).
  {
    std::vector<std::array<double, 3>> pts(static_cast<size_t>(t.num_vertices()));
    for (Id v = 0; v < t.num_vertices(); ++v) {
      const Vec3 p = R.xyz(v);
      pts[v] = {p.x, p.y, p.z};
    }
    std::sort(pts.begin(), pts.end());
    for (size_t i = 1; i < pts.size(); ++i)
      if (pts[i] == pts[i - 1]) r.coincident_coarse_vertices += (i == 1 || pts[i - 1] != pts[i - 2]) ? 2 : 1;
  }

  // Coarse faces and edges as all parts together saw them.
  std::vector<FaceSide> side(static_cast<size_t>(t.faces.rows()) * 2);
  std::vector<std::uint64_t> edge_hash(static_cast<size_t>(t.edges.rows()), 0);
  std::vector<std::uint8_t> edge_seen(static_cast<size_t>(t.edges.rows()), 0),
      edge_bad(static_cast<size_t>(t.edges.rows()), 0);
  std::vector<std::int64_t> edge_uses, edge_dir;
  if (!vol) edge_uses.assign(static_cast<size_t>(t.edges.rows()), 0), edge_dir.assign(edge_uses.size(), 0);
  auto face_id = [&](std::uint64_t f) {
    if (f >= static_cast<std::uint64_t>(t.faces.rows())) throw Error(ErrorKind::Usage, "verify_finish: face id out of range");
    return static_cast<Id>(f);
  };
  for (const VerifyPart& p : parts) {
    for (const auto& [fu, count, hash] : p.face_sides) {
      const Id f = face_id(fu);
      FaceSide* fs = &side[2 * f];
      if (fs->seen) fs = &side[2 * f + 1];
      if (fs->seen) {
        ++r.conformity_errors;
        note(r, "coarse face " + std::to_string(f) + " is shared by more than two coarse hexes");
        continue;
      }
      *fs = FaceSide{hash, static_cast<Id>(count), true};
    }
    for (const auto& [eu, hv, bad] : p.edge_hashes) {
      if (eu >= edge_seen.size()) throw Error(ErrorKind::Usage, "verify_finish: edge id out of range");
      if (!edge_seen[eu]) edge_seen[eu] = 1, edge_hash[eu] = hv;
      edge_bad[eu] |= bad != 0 || edge_hash[eu] != hv;
    }
    for (const auto& [e, uses, dir] : p.edge_uses)
      if (!vol && e >= 0 && e < t.edges.rows()) edge_uses[e] += uses, edge_dir[e] += dir;
  }

  // One finding per coarse edge, in edge order: the same count and notes
  // from one process and from any number of ranks.
  for (size_t e = 0; e < edge_bad.size(); ++e)
    if (edge_bad[e]) {
      ++r.conformity_errors;
      note(r, "coarse edge " + std::to_string(e) + ": neighbours disagree on its fine nodes");
    }
  if (vol) {
    for (Id f = 0; f < t.faces.rows(); ++f) {
      const FaceRow fr = R.face(f);
      const Id want = R.edge(fr.e[0]).n * R.edge(fr.e[2]).n;
      const FaceSide &a = side[2 * f], &c = side[2 * f + 1];
      const bool interior = c.seen;
      if (a.count != want || (interior && (c.count != want || c.hash != a.hash))) {
        ++r.conformity_errors;
        note(r, "coarse face " + std::to_string(f) + ": its fine faces do not match up (" + std::to_string(a.count) +
                    " and " + std::to_string(c.count) + " seen, " + std::to_string(want) + " expected)");
      }
      if (!interior) r.boundary_fine_faces += a.count;
    }
  }

  // Surface mode: the boundary is the edges of one quad; an edge of two
  // quads is traversed both ways (orientable, consistently oriented); an
  // edge of more is non-manifold.
  std::vector<detail::Facet> facets;
  if (!vol) {
    for (Id e = 0; e < t.edges.rows(); ++e) {
      const EdgeRow er = R.edge(e);
      if (edge_uses[e] == 1) {
        r.boundary_fine_faces += er.n;
      } else if (edge_uses[e] == 2 && edge_dir[e] != 0) {
        ++r.misoriented;
        note(r, "coarse edge " + std::to_string(e) + " is traversed the same way by both its quads (inconsistent orientation)");
      } else if (edge_uses[e] > 2) {
        r.conformity_errors += er.n;
        note(r, "coarse edge " + std::to_string(e) + " is shared by " + std::to_string(edge_uses[e]) + " quads (non-manifold)");
      }
    }
  }
  // The coarse boundary facets, where alone distinct fine nodes can meet.
  {
    if (vol) {
      for (Id f = 0; f < t.faces.rows(); ++f)
        if (!side[2 * f + 1].seen) {
          const FaceRow fr = R.face(f);
          const ElementRow h = R.element(fr.owner_element);
          for (int k = 0; k < 6; ++k)
            if (h.face[k] == f) facets.push_back({fr.owner_element, k});
        }
    } else {
      for (Id e = 0; e < t.edges.rows(); ++e)
        if (edge_uses[e] == 1) {
          const EdgeRow er = R.edge(e);
          const ElementRow h = R.element(er.owner_element);
          for (int k = 0; k < 4; ++k)
            if (h.edge[k] == e) facets.push_back({er.owner_element, k});
        }
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (Id v = 0; v < t.num_vertices(); ++v) {
      const Vec3 p = R.xyz(v);
      const double c[3] = {p.x, p.y, p.z};
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], c[d]), hi[d] = std::max(hi[d], c[d]);
    }
    double diag = 0;
    for (int d = 0; d < 3 && t.num_vertices() > 0; ++d) diag += (hi[d] - lo[d]) * (hi[d] - lo[d]);
    const Id before = r.coincident_nodes;
    detail::find_coincident_nodes(mesh, facets, 1e-9 * std::sqrt(diag), r, [&](const std::string& s) {
      (r.coincident_nodes > r.coincident_interface ? r.problems : r.warnings).push_back(s);
    });
    if (r.coincident_nodes > before) {
      const Id bad = r.coincident_nodes - r.coincident_interface;
      if (r.coincident_interface > 0)
        r.warnings.push_back(std::to_string(r.coincident_interface) + " fine nodes coincide on an interface of " +
                             std::to_string(r.coincident_coarse_vertices) + " coincident coarse vertices (kept apart on purpose?)");
      if (bad > 0)
        note(r, std::to_string(bad) + " fine nodes coincide where the coarse mesh does not conform (hanging vertices?)");
    }
    if (r.near_coincident > 0)
      r.warnings.push_back(std::to_string(r.near_coincident) + " fine nodes lie within 1e-9 of the diagonal of another node");
  }
  return r;
}

VerifyReport verify(const FineMesh& mesh, const std::function<void(Id, Id)>& progress) {
  return verify_finish(mesh, {verify_part(mesh, 0, mesh.num_coarse_elements(), progress)});
}

}  // namespace dicer
