// The intervals file (JSON), parsed with nlohmann-json: a small, well-kept
// parser is safer than our own for user-written JSON.
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>  // Debian's nlohmann-json3-dev

#include "dicer/error.hpp"
#include "dicer/intervals.hpp"
#include "input_file.hpp"

namespace dicer {

IntervalRequest read_interval_file(const std::string& path) {
  const std::string text = InputFile(path).read_all();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(ErrorKind::Usage, path + ": not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw Error(ErrorKind::Usage, path + ": top level must be a JSON object");
  IntervalRequest r;
  auto number = [&](const nlohmann::json& v, const std::string& where) -> long double {
    if (!v.is_number()) throw Error(ErrorKind::Usage, path + ": " + where + ": must be a number");
    return v.get<long double>();
  };
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    if (k == "global") {
      r.global = checked_interval(path + ": global", number(*it, k));
    } else if (k == "size") {
      const double s = static_cast<double>(number(*it, k));
      if (!(s > 0) || !std::isfinite(s)) throw Error(ErrorKind::Usage, path + ": size must be a positive number");
      r.size = s;
    } else if (k == "blocks" || k == "sheets") {
      if (!it->is_object()) throw Error(ErrorKind::Usage, path + ": " + k + " must be an object");
      for (auto b = it->begin(); b != it->end(); ++b) {
        const Id n = checked_interval(path + ": " + k + " \"" + b.key() + "\"", number(*b, k + "." + b.key()));
        if (k == "blocks") {
          r.blocks.emplace_back(b.key(), n);
        } else {
          char* end = nullptr;
          const long long s = std::strtoll(b.key().c_str(), &end, 10);
          if (b.key().empty() || *end != '\0' || s < 0)
            throw Error(ErrorKind::Usage, path + ": sheets: \"" + b.key() + "\" is not a sheet id");
          r.sheets.emplace_back(s, n);
        }
      }
    } else {
      throw Error(ErrorKind::Usage, path + ": unknown key \"" + k + "\" (known: global, size, blocks, sheets)");
    }
  }
  return r;
}

}  // namespace dicer
