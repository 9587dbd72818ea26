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

}  // namespace dicer::cli
