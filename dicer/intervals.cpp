#include "dicer/intervals.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <unordered_map>

#include "dicer/error.hpp"
#include "dicer/tables.hpp"

namespace dicer {

Id checked_interval(const std::string& what, long double n) {
  // As given ("0", "2.5", "1099511627777"), not std::to_string's "0.000000".
  char given[48];
  std::snprintf(given, sizeof given, "%.15Lg", n);
  if (!(n >= 1) || n != std::floor(n))
    throw Error(ErrorKind::Usage, what + ": interval must be a whole number >= 1 (got " + given + ")");
  if (n > kMaxInterval) throw Error(ErrorKind::Overflow, what + ": interval " + given + " is too large (limit 2^40)");
  return static_cast<Id>(n);
}

namespace {

std::string num(double x) {
  char b[40];
  std::snprintf(b, sizeof b, "%.6g", x);
  return b;
}

std::string entity_label(const EntityTag& e) {
  static const char* kDim[4] = {"point", "curve", "surface", "volume"};
  return std::string(e.first >= 0 && e.first <= 3 ? kDim[e.first] : "entity") + " " + std::to_string(e.second);
}

}  // namespace

void check_bias(const std::string& what, const BiasRequest& b) {
  if (b.kind != tfi::Spacing::Geometric && b.kind != tfi::Spacing::Dual)
    throw Error(ErrorKind::Usage, what + ": a bias is geometric or dual");
  if (!(b.first_cell >= 0) || !(b.last_cell >= 0) || !std::isfinite(b.first_cell) || !std::isfinite(b.last_cell))
    throw Error(ErrorKind::Usage, what + ": a cell length must be a positive number");
  if (b.first_cell > 0 && b.last_cell > 0)
    throw Error(ErrorKind::Usage, what + ": give the first or the last cell's length, not both");
  if (b.last_cell > 0 && b.kind == tfi::Spacing::Dual)
    throw Error(ErrorKind::Usage, what + ": a dual bias is symmetric: give its end cells as first:h");
  if (b.start && b.kind == tfi::Spacing::Dual)
    throw Error(ErrorKind::Usage, what + ": a dual bias is symmetric and has no start node");
  if (b.first_cell == 0 && b.last_cell == 0 && !(b.ratio >= 1 / tfi::kMaxRatio && b.ratio <= tfi::kMaxRatio))
    throw Error(ErrorKind::Usage, what + ": the ratio must be between " + num(1 / tfi::kMaxRatio) + " and " +
                                      num(tfi::kMaxRatio) + " (got " + num(b.ratio) + ")");
}

double parse_real(const std::string& what, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  // The whole text: a NUL inside (from Python) ended strtod's reading early.
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
    throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a finite number");
  return v;
}

std::int64_t parse_whole(const std::string& what, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  // Leading blanks are strtoll's, not a number's; a NUL inside ends it early.
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0])) || end != text.c_str() + text.size())
    throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a whole number");
  // A bad value (2), like any other: exit 6 is for counts the mesh would overflow.
  if (errno == ERANGE) throw Error(ErrorKind::Usage, what + ": \"" + text + "\" does not fit in 64 bits");
  return v;
}

BiasRequest parse_bias(const std::string& what, const std::string& text, tfi::Spacing kind) {
  BiasRequest b;
  b.kind = kind;
  std::string body = text;
  if (const auto at = text.find('@'); at != std::string::npos) {
    const std::string v = text.substr(at + 1);
    char* end = nullptr;
    const long long id = std::strtoll(v.c_str(), &end, 10);
    if (v.empty() || std::isspace(static_cast<unsigned char>(v[0])) || end != v.c_str() + v.size())
      throw Error(ErrorKind::Usage, what + ": \"" + v + "\" after @ is not a node id");
    b.start = id;
    body = text.substr(0, at);
  }
  if (body.rfind("first:", 0) == 0) b.first_cell = parse_real(what, body.substr(6));
  else if (body.rfind("last:", 0) == 0) b.last_cell = parse_real(what, body.substr(5));
  else b.ratio = parse_real(what, body);
  if ((body.rfind("first:", 0) == 0 && !(b.first_cell > 0)) || (body.rfind("last:", 0) == 0 && !(b.last_cell > 0)))
    throw Error(ErrorKind::Usage, what + ": a cell length must be a positive number");
  check_bias(what, b);
  return b;
}

EntityTag parse_entity(const std::string& what, const std::string& text) {
  const auto colon = text.find(':');
  char* end = nullptr;
  const long dim = colon == 1 ? std::strtol(text.substr(0, 1).c_str(), &end, 10) : 0;
  const std::string tag = colon == std::string::npos ? "" : text.substr(colon + 1);
  char* tend = nullptr;
  const long long t = std::strtoll(tag.c_str(), &tend, 10);
  // The tag as Gmsh writes it: strtoll's blanks, '+' and leading zeros
  // would make "2:05" and "2:5" two keys of an intervals file for one
  // entity (both applied, the last winning).
  const size_t digits = !tag.empty() && tag[0] == '-' ? 1 : 0;
  const bool canonical = tag.size() > digits && std::isdigit(static_cast<unsigned char>(tag[digits])) &&
                         !(tag[digits] == '0' && tag.size() > digits + 1);
  if (dim < 1 || dim > 3 || !canonical || tend != tag.c_str() + tag.size() || t < -2147483647LL || t > 2147483647LL)
    throw Error(ErrorKind::Usage, what + ": \"" + text +
                                      "\" is not DIM:TAG (DIM 1 curve, 2 surface, 3 volume; TAG a whole number as "
                                      "Gmsh writes it: no '+', blank or leading zero)");
  return {static_cast<int>(dim), static_cast<int>(t)};
}

IntervalRequest parse_interval_options(const IntervalOptionText& text) {
  IntervalRequest r;
  // KEY=VALUE at the first '=' (a block name may hold one: block options
  // split at the last; a value holds none).
  auto split = [](const std::string& flag, const std::string& kv, const char* shape, bool last) {
    const auto eq = last ? kv.rfind('=') : kv.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == kv.size())
      throw Error(ErrorKind::Usage, flag + ": \"" + kv + "\" is not " + shape);
    return std::pair{kv.substr(0, eq), kv.substr(eq + 1)};
  };
  for (const auto& kv : text.block_interval) {
    const auto [k, v] = split("--block-interval", kv, "BLOCK=N", true);
    r.blocks.emplace_back(k, parse_whole("--block-interval " + kv, v));
  }
  for (const auto& kv : text.sheet_interval) {
    const auto [k, v] = split("--sheet-interval", kv, "SHEET=N", false);
    r.sheets.emplace_back(parse_whole("--sheet-interval " + kv, k), parse_whole("--sheet-interval " + kv, v));
  }
  for (const auto& kv : text.entity_interval) {
    const auto [k, v] = split("--entity-interval", kv, "DIM:TAG=N", false);
    r.entities.emplace_back(parse_entity("--entity-interval " + kv, k), parse_whole("--entity-interval " + kv, v));
  }
  for (const auto& kv : text.sheet_bias) {
    const auto [k, v] = split("--sheet-bias", kv, "S=R[@V]", false);
    r.sheet_bias.emplace_back(parse_whole("--sheet-bias " + kv, k),
                              parse_bias("--sheet-bias " + kv, v, tfi::Spacing::Geometric));
  }
  for (const auto& kv : text.sheet_dual_bias) {
    const auto [k, v] = split("--sheet-dual-bias", kv, "S=R", false);
    const Id s = parse_whole("--sheet-dual-bias " + kv, k);
    for (const auto& [other, b] : r.sheet_bias)
      if (other == s && b.kind == tfi::Spacing::Geometric)
        throw Error(ErrorKind::Usage, "--sheet-dual-bias " + kv + ": sheet " + k + " also has a --sheet-bias; give one");
    r.sheet_bias.emplace_back(s, parse_bias("--sheet-dual-bias " + kv, v, tfi::Spacing::Dual));
  }
  for (const auto& kv : text.block_bias) {
    const auto [k, v] = split("--block-bias", kv, "B=R[@V]", true);
    r.block_bias.emplace_back(k, parse_bias("--block-bias " + kv, v, tfi::Spacing::Geometric));
  }
  for (const auto& kv : text.entity_bias) {
    const auto [k, v] = split("--entity-bias", kv, "DIM:TAG=R[@V]", false);
    r.entity_bias.emplace_back(parse_entity("--entity-bias " + kv, k),
                               parse_bias("--entity-bias " + kv, v, tfi::Spacing::Geometric));
  }
  return r;
}

std::string bias_text(const BiasRequest& b) {
  std::string s = b.kind == tfi::Spacing::Dual ? "dual bias " : "bias ";
  if (b.first_cell > 0) s += (b.kind == tfi::Spacing::Dual ? "end cells " : "first cell ") + num(b.first_cell);
  else if (b.last_cell > 0) s += "last cell " + num(b.last_cell);
  else s += num(b.ratio);
  if (b.start) s += " from node " + std::to_string(*b.start);
  return s;
}

IntervalRequest merge(IntervalRequest base, const IntervalRequest& over) {
  if (over.global) base.global = over.global;
  if (over.size) base.size = over.size;
  auto keyed = [](auto& into, const auto& from) {
    for (const auto& x : from) {
      std::erase_if(into, [&](const auto& y) { return y.first == x.first; });
      into.push_back(x);
    }
  };
  keyed(base.blocks, over.blocks), keyed(base.sheets, over.sheets), keyed(base.entities, over.entities);
  keyed(base.block_bias, over.block_bias), keyed(base.sheet_bias, over.sheet_bias);
  keyed(base.entity_bias, over.entity_bias);
  return base;
}

// ---------------------------------------------------------------- entities

namespace {

// The model topology: the entities each entity bounds (up) and is bounded
// by (down), one dimension apart.
struct Model {
  std::map<EntityTag, std::vector<EntityTag>> up, down;
  std::map<EntityTag, std::set<EntityTag>> up_memo;
  explicit Model(const CoarseMesh& m) {
    for (const GeoEntity& g : m.geo_entities)
      for (int b : g.bounding) {
        up[{g.dim - 1, b}].push_back({g.dim, g.tag});
        down[{g.dim, g.tag}].push_back({g.dim - 1, b});
      }
  }
  // e and every entity whose closure holds e (dimensions only grow: no cycle).
  const std::set<EntityTag>& above(const EntityTag& e) {
    if (auto it = up_memo.find(e); it != up_memo.end()) return it->second;
    std::set<EntityTag> s{e};
    if (auto it = up.find(e); it != up.end())
      for (const EntityTag& u : it->second)
        if (u.first > e.first) {
          const auto& a = above(u);
          s.insert(a.begin(), a.end());
        }
    return up_memo[e] = std::move(s);
  }
  // e and its closure (what bounds it, recursively).
  std::set<EntityTag> below(const EntityTag& e) const {
    std::set<EntityTag> s{e};
    std::vector<EntityTag> todo{e};
    while (!todo.empty()) {
      const EntityTag x = todo.back();
      todo.pop_back();
      if (auto it = down.find(x); it != down.end())
        for (const EntityTag& d : it->second)
          if (d.first < x.first && s.insert(d).second) todo.push_back(d);
    }
    return s;
  }
};

}  // namespace

std::vector<std::int64_t> edge_entities(const CoarseMesh& mesh, const Topology& topo) {
  const Id ne = topo.num_edges();
  std::vector<std::int64_t> out(static_cast<size_t>(ne), -1);
  const size_t nv = static_cast<size_t>(mesh.num_vertices());
  if (mesh.vertex_geo_dim.size() != nv || mesh.vertex_geo_tag.size() != nv) return out;
  Model model(mesh);
  const bool topology = !mesh.geo_entities.empty();
  std::set<int> curve_with_vertex;  // a curve met by one coarse edge alone has no vertex on it
  for (size_t v = 0; v < nv; ++v)
    if (mesh.vertex_geo_dim[v] == 1) curve_with_vertex.insert(mesh.vertex_geo_tag[v]);
  for (Id e = 0; e < ne; ++e) {
    const Id a = topo.edge_v[2 * e], b = topo.edge_v[2 * e + 1];
    const EntityTag A{mesh.vertex_geo_dim[a], mesh.vertex_geo_tag[a]}, B{mesh.vertex_geo_dim[b], mesh.vertex_geo_tag[b]};
    if (A.first < 0 || B.first < 0 || A.first > 3 || B.first > 3) continue;
    if (!topology) {
      const EntityTag& hi = A.first >= B.first ? A : B;
      if ((A == B || A.first != B.first) && hi.first >= 1) out[e] = pack_owner(hi.first, hi.second);
      continue;
    }
    const auto& ca = model.above(A);
    const auto& cb = model.above(B);
    std::vector<EntityTag> common;
    std::set_intersection(ca.begin(), ca.end(), cb.begin(), cb.end(), std::back_inserter(common));
    for (int d = 1; d <= 3; ++d) {
      std::vector<EntityTag> at;
      for (const EntityTag& c : common)
        if (c.first == d) at.push_back(c);
      if (at.empty()) continue;
      if (at.size() > 1 && d == 1) std::erase_if(at, [&](const EntityTag& c) { return curve_with_vertex.count(c.second) > 0; });
      if (at.size() == 1) out[e] = pack_owner(at[0].first, at[0].second);
      break;  // the lowest dimension decides; several there: unknown
    }
  }
  return out;
}

// ---------------------------------------------------------------- resolve

namespace {

// The cell at one end of a series: first (s_1) or last (1 - s_(n-1)).
double end_cell(Id n, const tfi::Grading& g, bool last) {
  const tfi::Series s(n, g);
  return last ? 1.0 - s.at(n - 1) : s.at(1);
}

double largest_cell(Id n, const tfi::Grading& g) {
  const tfi::Series s(n, g);
  double m = 0;
  for (const Id t : {Id{1}, n, n / 2, n / 2 + 1})
    if (t >= 1 && t <= n) m = std::max(m, s.at(t) - s.at(t - 1));
  return m;
}

// The ratio whose first (last) cell is the fraction q of the edge at
// interval n; false when no ratio in [1/kMaxRatio, kMaxRatio] reaches it.
// A first cell shrinks as R grows, a last one grows: bisection on ln R.
bool ratio_for_cell(tfi::Spacing kind, Id n, double q, bool last, double& ratio) {
  auto cell = [&](double x) {
    const double R = std::exp(x);
    if (R == 1.0) return 1.0 / static_cast<double>(n);
    return end_cell(n, {kind, false, R}, last);
  };
  double lo = -std::log(tfi::kMaxRatio), hi = std::log(tfi::kMaxRatio);
  const double c_lo = cell(lo), c_hi = cell(hi);
  if (!(std::min(c_lo, c_hi) <= q && q <= std::max(c_lo, c_hi))) return false;
  const bool rising = c_hi > c_lo;
  for (int it = 0; it < 200 && hi - lo > 1e-15; ++it) {
    const double mid = 0.5 * (lo + hi);
    ((cell(mid) < q) == rising ? lo : hi) = mid;
  }
  ratio = std::exp(0.5 * (lo + hi));
  return true;
}

struct Candidate {
  std::string label;  // "block 2 (wall)", "surface 5"
  Id n = 0;
  std::optional<BiasRequest> bias;
};

}  // namespace

IntervalPlan resolve_intervals(const CoarseMesh& mesh, const Topology& topo, const Sheets& sheets,
                               const IntervalRequest& req) {
  const Id ns = sheets.num_sheets(), ne = topo.num_edges();
  IntervalPlan plan;
  plan.sheet_interval.assign(static_cast<size_t>(ns), 0);
  plan.sheet_grading.assign(static_cast<size_t>(ns), tfi::Grading{});
  plan.sheet_start.assign(static_cast<size_t>(ns), -1);
  plan.edge_flip.assign(static_cast<size_t>(ne), 0);

  auto block_label = [&](std::int32_t b) {
    return "block " + std::to_string(mesh.blocks[b].id) +
           (mesh.blocks[b].name.empty() ? "" : " (" + mesh.blocks[b].name + ")");
  };
  auto find_block = [&](const std::string& key) {
    for (size_t b = 0; b < mesh.blocks.size(); ++b)
      if (std::to_string(mesh.blocks[b].id) == key) {
        // An id wins over a name; a block that the key names too is said.
        for (size_t o = 0; o < mesh.blocks.size(); ++o)
          if (o != b && mesh.blocks[o].name == key)
            plan.notes.push_back("\"" + key + "\" is the id of " + block_label(static_cast<std::int32_t>(b)) +
                                 " and the name of " + block_label(static_cast<std::int32_t>(o)) + ": " +
                                 block_label(static_cast<std::int32_t>(b)) + " was taken");
        return static_cast<int>(b);
      }
    // A name two blocks share (Exodus allows it) is not guessed at.
    int named = -1;
    for (size_t b = 0; b < mesh.blocks.size(); ++b)
      if (!mesh.blocks[b].name.empty() && mesh.blocks[b].name == key) {
        if (named >= 0)
          throw Error(ErrorKind::Usage, mesh.source + ": \"" + key + "\" names more than one block (" +
                                            block_label(named) + ", " + block_label(static_cast<std::int32_t>(b)) +
                                            "); give the block's id");
        named = static_cast<int>(b);
      }
    if (named >= 0) return named;
    std::string known;
    for (const auto& b : mesh.blocks)
      known += (known.empty() ? "" : ", ") + std::to_string(b.id) + (b.name.empty() ? "" : " (" + b.name + ")");
    throw Error(ErrorKind::Usage, mesh.source + ": no block with id or name \"" + key + "\" (blocks: " + known + ")");
  };
  auto check_sheet = [&](Id s) {
    if (s < 0 || s >= ns)
      throw Error(ErrorKind::Usage, mesh.source + ": no sheet " + std::to_string(s) + " (the mesh has " +
                                        std::to_string(ns) + " sheets, ids 0.." + std::to_string(ns - 1) + ")");
  };

  // Requests by block, by sheet.
  std::vector<Id> block_n(mesh.blocks.size(), 0);
  std::vector<std::optional<BiasRequest>> block_b(mesh.blocks.size());
  for (const auto& [key, n] : req.blocks) {
    checked_interval("block " + key, static_cast<long double>(n));
    block_n[find_block(key)] = n;
  }
  for (const auto& [key, b] : req.block_bias) {
    check_bias("block " + key, b);
    block_b[find_block(key)] = b;
  }
  std::vector<Id> sheet_n(static_cast<size_t>(ns), 0);
  std::vector<std::optional<BiasRequest>> sheet_b(static_cast<size_t>(ns));
  for (const auto& [s, n] : req.sheets) {
    checked_interval("sheet " + std::to_string(s), static_cast<long double>(n));
    check_sheet(s);
    sheet_n[s] = n;
  }
  for (const auto& [s, b] : req.sheet_bias) {
    check_bias("sheet " + std::to_string(s), b);
    check_sheet(s);
    sheet_b[s] = b;
  }
  if (req.global) checked_interval("--interval", static_cast<long double>(*req.global));
  if (req.size && !(*req.size > 0 && std::isfinite(*req.size)))
    throw Error(ErrorKind::Usage, "--size must be a positive number");

  // Requests by entity, in (dim, tag) order: the sheets with an edge on
  // each (on the entity or in its closure).
  std::map<EntityTag, Candidate> entity_req;
  for (const auto& [e, n] : req.entities) {
    checked_interval(entity_label(e), static_cast<long double>(n));
    entity_req[e].n = n;
  }
  for (const auto& [e, b] : req.entity_bias) {
    check_bias(entity_label(e), b);
    entity_req[e].bias = b;
  }
  std::vector<std::vector<const Candidate*>> sheet_entities(static_cast<size_t>(ns));
  if (!entity_req.empty()) {
    const std::vector<std::int64_t> on = edge_entities(mesh, topo);
    if (std::all_of(on.begin(), on.end(), [](std::int64_t o) { return o < 0; }))
      throw Error(ErrorKind::Usage, mesh.source + ": intervals by entity need a mesh classified on geometric entities "
                                                  "(MSH 4.1 with $Entities) or the CAD given with --geometry; "
                                                  "this mesh has no classified edge");
    const Model model(mesh);
    for (auto& [e, c] : entity_req) {
      if (e.first < 1 || e.first > 3)
        throw Error(ErrorKind::Usage, entity_label(e) + ": intervals by entity take a curve (1), surface (2) or volume (3)");
      c.label = entity_label(e);
      std::set<std::int64_t> closure;
      for (const EntityTag& x : model.below(e)) closure.insert(pack_owner(x.first, x.second));
      std::vector<std::uint8_t> hit(static_cast<size_t>(ns), 0);
      for (Id k = 0; k < ne; ++k)
        if (on[k] >= 0 && closure.count(on[k])) hit[sheets.edge_sheet[k]] = 1;
      bool any = false;
      for (Id s = 0; s < ns; ++s)
        if (hit[s]) sheet_entities[s].push_back(&c), any = true;
      if (!any)
        throw Error(ErrorKind::Usage, mesh.source + ": no coarse edge lies on " + c.label +
                                          " (check the tag: `dicer sheets --edges` lists the sheets, and the "
                                          "mesh's classification comes from its MSH entities or --geometry)");
    }
  }

  // Length of the longest edge of each sheet: --size and cell lengths.
  std::vector<double> longest(static_cast<size_t>(ns), 0.0);
  for (Id e = 0; e < ne; ++e) {
    const Vec3 a = mesh.vertex(topo.edge_v[2 * e]), b = mesh.vertex(topo.edge_v[2 * e + 1]);
    const double len = std::sqrt((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) + (b.z - a.z) * (b.z - a.z));
    longest[sheets.edge_sheet[e]] = std::max(longest[sheets.edge_sheet[e]], len);
  }
  const bool any_bias = !req.sheet_bias.empty() || !req.block_bias.empty() || !req.entity_bias.empty();
  SheetDirections dirs;
  std::vector<Id> first_edge(static_cast<size_t>(ns), -1);
  std::unordered_map<Id, Id> vertex_of_file_id;
  if (any_bias) {
    dirs = orient_sheets(topo, sheets);
    for (Id e = ne - 1; e >= 0; --e) first_edge[sheets.edge_sheet[e]] = e;
    for (Id v = 0; v < mesh.num_vertices(); ++v)
      vertex_of_file_id.emplace(static_cast<size_t>(v) < mesh.vertex_file_id.size() ? mesh.vertex_file_id[v] : v + 1, v);
  }
  std::vector<std::uint8_t> toggle(static_cast<size_t>(ns), 0);
  const std::string sheet_word = "sheet ";

  for (Id s = 0; s < ns; ++s) {
    const std::string sheet = sheet_word + std::to_string(s);
    // The block and entity requests touching this sheet, blocks first.
    std::vector<Candidate> touching;
    for (Id i = sheets.block_offset[s]; i < sheets.block_offset[s + 1]; ++i) {
      const std::int32_t b = sheets.block_index[i];
      if (block_n[b] != 0 || block_b[b]) touching.push_back({block_label(b), block_n[b], block_b[b]});
    }
    for (const Candidate* c : sheet_entities[s]) touching.push_back(*c);

    // Interval.
    Id bmax = 0;
    std::string asks;
    bool differ = false;
    for (const Candidate& c : touching) {
      if (c.n == 0) continue;
      if (bmax != 0 && c.n != bmax) differ = true;
      bmax = std::max(bmax, c.n);
      asks += (asks.empty() ? "" : ", ") + c.label + " asks " + std::to_string(c.n);
    }
    // Grading request: the sheet's own, else the first block or entity bias.
    std::optional<BiasRequest> bias = sheet_b[s];
    std::string bias_from = sheet;
    {
      std::string others;
      const BiasRequest* first = nullptr;
      bool disagree = false;
      for (const Candidate& c : touching) {
        if (!c.bias) continue;
        if (first && !(*first == *c.bias)) disagree = true;
        if (!first) first = &*c.bias, bias_from = c.label;
        others += (others.empty() ? "" : ", ") + c.label + " asks " + bias_text(*c.bias);
      }
      if (bias && first && (disagree || !(*bias == *first)))
        plan.notes.push_back(sheet + ": its " + bias_text(*bias) + " overrides its blocks and entities (" + others + ")");
      else if (!bias && first) {
        bias = *first;
        if (disagree)
          plan.notes.push_back(sheet + " touches blocks or entities with different biases (" + others +
                               "): using the first, " + bias_from + "'s");
      }
      if (sheet_b[s]) bias_from = sheet;
    }

    // The grading at interval n, ratio derived from a cell length if asked:
    // false when no ratio reaches that cell.
    auto grading_at = [&](Id n, tfi::Grading& g) {
      g = {bias->kind, false, bias->ratio};
      if (bias->first_cell > 0 || bias->last_cell > 0) {
        const double q = (bias->first_cell > 0 ? bias->first_cell : bias->last_cell) / longest[s];
        if (!ratio_for_cell(bias->kind, n, q, bias->last_cell > 0, g.ratio)) return false;
      }
      if (g.ratio == 1.0) g = {};  // ratio 1: equal spacing
      return true;
    };
    auto no_effect = [&](Id n) { return n == 1 || (bias->kind == tfi::Spacing::Dual && n == 2); };
    const std::string from = bias_from == sheet ? "" : " (from " + bias_from + ")";

    Id n = 0;
    if (sheet_n[s] > 0) {
      n = sheet_n[s];
      if (bmax > 0 && (differ || bmax != n))
        plan.notes.push_back(sheet + ": sheet interval " + std::to_string(n) + " overrides its blocks and entities (" +
                             asks + ")");
    } else if (bmax > 0) {
      n = bmax;
      if (differ)
        plan.notes.push_back(sheet + " touches blocks or entities with different intervals (" + asks +
                             "): using the largest, " + std::to_string(n));
    } else if (req.size && bias) {
      // The smallest n whose cells on the longest edge are all within H.
      const double H = *req.size, L = longest[s];
      auto fits = [&](Id m) {
        tfi::Grading g;
        if (no_effect(m)) return L / static_cast<double>(m) <= H;
        return grading_at(m, g) && largest_cell(m, g) * L <= H;
      };
      Id lo = std::max<Id>(1, static_cast<Id>(std::min<long double>(std::ceil(L / H), kMaxInterval)));
      if (!fits(lo)) {
        Id hi = lo;
        while (!fits(hi)) {
          if (hi >= kMaxInterval)
            throw Error(ErrorKind::Usage, sheet + ": with its " + bias_text(*bias) + ", no interval up to 2^40 keeps "
                                              "every cell of its longest edge (" + num(L) + " long) within --size " +
                                              num(H) + ": give the sheet an interval, or a ratio nearer 1");
          lo = hi, hi = std::min(2 * hi, kMaxInterval);
        }
        while (hi - lo > 1) {
          const Id mid = lo + (hi - lo) / 2;
          (fits(mid) ? hi : lo) = mid;
        }
        lo = hi;
      }
      n = lo;
    } else if (req.size) {
      const long double q = std::ceil(static_cast<long double>(longest[s]) / *req.size);
      // The size may come from --size or an intervals file: name its value.
      n = checked_interval(sheet + " at size " + num(*req.size) + " (its longest edge " + num(longest[s]) + ")",
                           std::max<long double>(q, 1));
    } else if (req.global) {
      n = *req.global;
    } else {
      n = 1;
    }
    plan.sheet_interval[s] = n;
    if (!bias) continue;

    // Grading.
    if (no_effect(n)) {
      plan.notes.push_back(sheet + " has interval " + std::to_string(n) + ": its " + bias_text(*bias) +
                           from + " changes nothing; equal spacing");
      continue;
    }
    tfi::Grading g;
    if (!grading_at(n, g))
      throw Error(ErrorKind::Usage, sheet + ": no ratio between " + num(1 / tfi::kMaxRatio) + " and " +
                                        num(tfi::kMaxRatio) + " gives the " + bias_text(*bias) + from +
                                        " on its longest edge (" + num(longest[s]) + " long) at interval " +
                                        std::to_string(n) + ": change the interval or the cell length");
    if (bias->first_cell > 0 || bias->last_cell > 0)
      plan.notes.push_back(sheet + ": " + bias_text(*bias) + " at interval " + std::to_string(n) + " is ratio " +
                           num(g.ratio));
    if (g.kind == tfi::Spacing::Equal) continue;
    if (g.kind == tfi::Spacing::Geometric && dirs.twisted[s])
      throw Error(ErrorKind::Usage, mesh.source + ": " + sheet + " closes on itself reversed (a Moebius-like ring of "
                                                          "faces): its edges cannot all run one way, so the " +
                                        bias_text(*bias) + from + " is impossible; a dual bias "
                                        "(--sheet-dual-bias " + std::to_string(s) + "=R) is symmetric and fits");
    const double smallest = tfi::Series(n, g).smallest_cell();
    if (!(smallest >= tfi::kMinCell))
      throw Error(ErrorKind::Usage, sheet + ": the " + bias_text(*bias) + from + " at interval " +
                                        std::to_string(n) + " makes its smallest cell " + num(smallest) +
                                        " of the edge (the limit is 2^-40): use a ratio nearer 1 or fewer intervals");
    plan.sheet_grading[s] = g;
    if (g.kind != tfi::Spacing::Geometric) continue;
    // Start: the node asked for, on an edge of the sheet; else the lower
    // file id of its first edge.
    Id e0 = first_edge[s], v = -1;
    if (bias->start) {
      const auto it = vertex_of_file_id.find(*bias->start);
      Id on = -1;
      if (it != vertex_of_file_id.end())
        for (Id e = first_edge[s]; e < ne && on < 0; ++e)
          if (sheets.edge_sheet[e] == s && (topo.edge_v[2 * e] == it->second || topo.edge_v[2 * e + 1] == it->second)) on = e;
      if (on >= 0) {
        e0 = on, v = it->second;
      } else if (bias_from == sheet) {
        throw Error(ErrorKind::Usage, mesh.source + ": " + sheet + ": node " + std::to_string(*bias->start) +
                                          " is on none of its edges (`dicer sheets --edges` lists them)");
      } else {
        plan.notes.push_back(sheet + ": node " + std::to_string(*bias->start) + " (the start of " + bias_from +
                             "'s bias) is on none of its edges: its series starts at its first edge's lower node");
      }
    }
    const Id lo = topo.edge_v[2 * e0], hi = topo.edge_v[2 * e0 + 1];
    if (v < 0) {
      auto fid = [&](Id x) { return static_cast<size_t>(x) < mesh.vertex_file_id.size() ? mesh.vertex_file_id[x] : x + 1; };
      v = fid(lo) <= fid(hi) ? lo : hi;
    }
    plan.sheet_start[s] = v;
    // Along e0 the series leaves v: it runs hi -> lo when v is hi.
    toggle[s] = dirs.edge_flip[e0] != static_cast<std::uint8_t>(v == hi);
  }
  if (any_bias)
    for (Id e = 0; e < ne; ++e) {
      const Id s = sheets.edge_sheet[e];
      plan.edge_flip[e] = plan.sheet_grading[s].kind == tfi::Spacing::Geometric ? dirs.edge_flip[e] ^ toggle[s] : 0;
    }
  if (req.size && req.global)
    plan.notes.push_back("both --size and --interval given: --size sets every sheet without a sheet, block or entity "
                         "request; --interval is unused");
  return plan;
}

}  // namespace dicer
