#pragma once
// Every JSON document the dicer command prints goes through here, one
// policy for all (stated in `dicer --help` and the README):
//  - a string that is not valid UTF-8 (a file name, a block name read from
//    a file) has each invalid byte sequence replaced by U+FFFD, so the
//    output is always valid UTF-8 JSON;
//  - a number that is not finite (NaN, +-Inf) is written as null: JSON has
//    no such numbers, and a reader must not get a document it cannot parse;
//  - a double is written in the shortest form that reads back to the same
//    64 bits (at most 17 significant digits), so coordinates are exact.
// Header-only so that the tests check the very function the command uses.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "dicer/tfi.hpp"
#include "dicer/types.hpp"

namespace dicer::cli {

// Keys stay in the order the command adds them (the documented order).
using Json = nlohmann::ordered_json;

// One line, no trailing newline.
inline std::string json_text(const Json& j) {
  return j.dump(-1, ' ', /*ensure_ascii=*/false, Json::error_handler_t::replace);
}

inline void print_json(const Json& j) {
  const std::string s = json_text(j) + "\n";
  std::fwrite(s.data(), 1, s.size(), stdout);
}

// A sheet's grading (`sheets`, `info`): null when equally spaced, else
// {"kind": "geometric"|"dual", "ratio": R, "start": file node id (geometric)}.
inline Json grading_json(const tfi::Grading& g, Id start) {
  if (g.kind == tfi::Spacing::Equal) return nullptr;
  Json j = {{"kind", g.kind == tfi::Spacing::Dual ? "dual" : "geometric"}, {"ratio", g.ratio}};
  if (g.kind == tfi::Spacing::Geometric) j["start"] = start;
  return j;
}
// The same as text: "-", "1.2@345", "dual 1.3".
inline std::string grading_text(const tfi::Grading& g, Id start) {
  if (g.kind == tfi::Spacing::Equal) return "-";
  char buf[64];
  if (g.kind == tfi::Spacing::Dual) std::snprintf(buf, sizeof buf, "dual %.6g", g.ratio);
  else std::snprintf(buf, sizeof buf, "%.6g@%lld", g.ratio, static_cast<long long>(start));
  return buf;
}

}  // namespace dicer::cli
