#include "dicer/intervals.hpp"

#include <algorithm>
#include <cmath>

#include "dicer/error.hpp"

namespace dicer {

Id checked_interval(const std::string& what, long double n) {
  if (!(n >= 1) || n != std::floor(n))
    throw Error(ErrorKind::Usage, what + ": interval must be a whole number >= 1 (got " +
                                      std::to_string(static_cast<double>(n)) + ")");
  if (n > kMaxInterval)
    throw Error(ErrorKind::Overflow, what + ": interval " + std::to_string(static_cast<double>(n)) +
                                         " is too large (limit 2^40)");
  return static_cast<Id>(n);
}

IntervalRequest merge(IntervalRequest base, const IntervalRequest& over) {
  if (over.global) base.global = over.global;
  if (over.size) base.size = over.size;
  for (const auto& b : over.blocks) {
    std::erase_if(base.blocks, [&](const auto& x) { return x.first == b.first; });
    base.blocks.push_back(b);
  }
  for (const auto& s : over.sheets) {
    std::erase_if(base.sheets, [&](const auto& x) { return x.first == s.first; });
    base.sheets.push_back(s);
  }
  return base;
}

IntervalPlan resolve_intervals(const CoarseMesh& mesh, const Topology& topo, const Sheets& sheets,
                               const IntervalRequest& req) {
  const Id ns = sheets.num_sheets();
  IntervalPlan plan;
  plan.sheet_interval.assign(static_cast<size_t>(ns), 0);

  // Block requests by block index.
  std::vector<Id> block_n(mesh.blocks.size(), 0);
  for (const auto& [key, n] : req.blocks) {
    checked_interval("block " + key, static_cast<long double>(n));
    int found = -1;
    for (size_t b = 0; b < mesh.blocks.size() && found < 0; ++b)
      if (std::to_string(mesh.blocks[b].id) == key) found = static_cast<int>(b);
    for (size_t b = 0; b < mesh.blocks.size() && found < 0; ++b)
      if (!mesh.blocks[b].name.empty() && mesh.blocks[b].name == key) found = static_cast<int>(b);
    if (found < 0) {
      std::string known;
      for (const auto& b : mesh.blocks)
        known += (known.empty() ? "" : ", ") + std::to_string(b.id) + (b.name.empty() ? "" : " (" + b.name + ")");
      throw Error(ErrorKind::Usage, mesh.source + ": no block with id or name \"" + key + "\" (blocks: " + known + ")");
    }
    block_n[found] = n;
  }
  std::vector<Id> sheet_n(static_cast<size_t>(ns), 0);
  for (const auto& [s, n] : req.sheets) {
    checked_interval("sheet " + std::to_string(s), static_cast<long double>(n));
    if (s < 0 || s >= ns)
      throw Error(ErrorKind::Usage, mesh.source + ": no sheet " + std::to_string(s) + " (the mesh has " +
                                        std::to_string(ns) + " sheets, ids 0.." + std::to_string(ns - 1) + ")");
    sheet_n[s] = n;
  }
  if (req.global) checked_interval("--interval", static_cast<long double>(*req.global));
  if (req.size && !(*req.size > 0 && std::isfinite(*req.size)))
    throw Error(ErrorKind::Usage, "--size must be a positive number");

  // Size rule: longest edge of each sheet.
  std::vector<double> longest;
  if (req.size) {
    longest.assign(static_cast<size_t>(ns), 0.0);
    for (Id e = 0; e < topo.num_edges(); ++e) {
      const Vec3 a = mesh.vertex(topo.edge_v[2 * e]), b = mesh.vertex(topo.edge_v[2 * e + 1]);
      const double len = std::sqrt((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) + (b.z - a.z) * (b.z - a.z));
      longest[sheets.edge_sheet[e]] = std::max(longest[sheets.edge_sheet[e]], len);
    }
  }
  auto block_label = [&](std::int32_t b) {
    return "block " + std::to_string(mesh.blocks[b].id) +
           (mesh.blocks[b].name.empty() ? "" : " (" + mesh.blocks[b].name + ")");
  };

  for (Id s = 0; s < ns; ++s) {
    // Block requests touching this sheet.
    Id bmax = 0;
    std::string touched;
    bool differ = false;
    for (Id i = sheets.block_offset[s]; i < sheets.block_offset[s + 1]; ++i) {
      const std::int32_t b = sheets.block_index[i];
      if (block_n[b] == 0) continue;
      if (bmax != 0 && block_n[b] != bmax) differ = true;
      bmax = std::max(bmax, block_n[b]);
      touched += (touched.empty() ? "" : ", ") + block_label(b) + " asks " + std::to_string(block_n[b]);
    }
    Id n = 0;
    if (sheet_n[s] > 0) {
      n = sheet_n[s];
      if (bmax > 0 && (differ || bmax != n))
        plan.notes.push_back("sheet " + std::to_string(s) + ": sheet interval " + std::to_string(n) +
                             " overrides its blocks (" + touched + ")");
    } else if (bmax > 0) {
      n = bmax;
      if (differ)
        plan.notes.push_back("sheet " + std::to_string(s) + " touches blocks with different intervals (" + touched +
                             "): using the largest, " + std::to_string(n));
    } else if (req.size) {
      const long double q = std::ceil(static_cast<long double>(longest[s]) / *req.size);
      n = checked_interval("sheet " + std::to_string(s) + " at --size", std::max<long double>(q, 1));
    } else if (req.global) {
      n = *req.global;
    } else {
      n = 1;
    }
    plan.sheet_interval[s] = n;
  }
  if (req.size && req.global)
    plan.notes.push_back("both --size and --interval given: --size sets every sheet without a sheet or block "
                         "request; --interval is unused");
  return plan;
}

}  // namespace dicer
