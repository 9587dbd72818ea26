// The intervals file (JSON), parsed with nlohmann-json: a small, well-kept
// parser is safer than our own for user-written JSON.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <set>
#include <string>
#include <vector>
#include <nlohmann/json.hpp>  // Debian's nlohmann-json3-dev

#include "dicer/error.hpp"
#include "dicer/intervals.hpp"
#include "input_file.hpp"

namespace dicer {

IntervalRequest read_interval_file(const std::string& path) {
  const std::string text = InputFile(path).read_all();
  nlohmann::json j;
  // A key given twice in one object: nlohmann keeps the last, silently; the
  // parser's callback sees each key as it comes, so the file is refused.
  std::vector<std::set<std::string>> keys;
  auto once = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    if (event == E::object_start) keys.emplace_back();
    else if (event == E::object_end && !keys.empty()) keys.pop_back();
    else if (event == E::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second)
      throw Error(ErrorKind::Usage, path + ": key \"" + parsed.get<std::string>() + "\" appears twice in one object");
    return true;
  };
  try {
    j = nlohmann::json::parse(text, once);
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
    } else if (k == "blocks" || k == "sheets" || k == "entities") {
      if (!it->is_object()) throw Error(ErrorKind::Usage, path + ": " + k + " must be an object");
      for (auto b = it->begin(); b != it->end(); ++b) {
        const std::string where = path + ": " + k + " \"" + b.key() + "\"";
        // A number (the interval) or {"interval", "bias" | "dual_bias" |
        // "first" | "last", "start"}.
        std::optional<Id> n;
        std::optional<BiasRequest> bias;
        if (b->is_object()) {
          BiasRequest q;
          int given = 0;
          for (auto f = b->begin(); f != b->end(); ++f) {
            const std::string& fk = f.key();
            const std::string fw = k + "." + b.key() + "." + fk;
            if (fk == "interval") {
              n = checked_interval(where, number(*f, fw));
            } else if (fk == "bias" || fk == "dual_bias") {
              q.ratio = static_cast<double>(number(*f, fw)), ++given;
              if (fk == "dual_bias") q.kind = tfi::Spacing::Dual;
            } else if (fk == "first" || fk == "last") {
              const double h = static_cast<double>(number(*f, fw));
              if (!(h > 0)) throw Error(ErrorKind::Usage, where + ": " + fk + " must be a positive cell length");
              (fk == "first" ? q.first_cell : q.last_cell) = h, ++given;
            } else if (fk == "start") {
              const long double v = number(*f, fw);
              if (v != std::floor(v) || std::fabs(v) > 9.2e18L)
                throw Error(ErrorKind::Usage, where + ": start must be a node id of the input file");
              q.start = static_cast<Id>(v);
            } else {
              throw Error(ErrorKind::Usage, where + ": unknown key \"" + fk +
                                                "\" (known: interval, bias, dual_bias, first, last, start)");
            }
          }
          if (given > 1)
            throw Error(ErrorKind::Usage, where + ": give one of bias, dual_bias, first, last");
          if (given == 0 && q.start) throw Error(ErrorKind::Usage, where + ": start needs a bias");
          if (given > 0) check_bias(where, q), bias = q;
          if (!n && !bias) throw Error(ErrorKind::Usage, where + ": give an interval or a bias");
        } else {
          n = checked_interval(where, number(*b, k + "." + b.key()));
        }
        if (k == "blocks") {
          if (n) r.blocks.emplace_back(b.key(), *n);
          if (bias) r.block_bias.emplace_back(b.key(), *bias);
        } else if (k == "entities") {
          const EntityTag e = parse_entity(where, b.key());
          if (n) r.entities.emplace_back(e, *n);
          if (bias) r.entity_bias.emplace_back(e, *bias);
        } else {
          // Digits only, no leading zero: strtoll would take " 2", "+2" and
          // "02" as 2 (beside a "2", the key check above misses it) and
          // saturate past 2^63.
          const std::string& key = b.key();
          errno = 0;
          const long long s = std::strtoll(key.c_str(), nullptr, 10);
          if (key.empty() || key.find_first_not_of("0123456789") != std::string::npos || errno == ERANGE ||
              (key.size() > 1 && key[0] == '0'))
            throw Error(ErrorKind::Usage, path + ": sheets: \"" + key + "\" is not a sheet id");
          if (n) r.sheets.emplace_back(s, *n);
          if (bias) r.sheet_bias.emplace_back(s, *bias);
        }
      }
    } else {
      throw Error(ErrorKind::Usage, path + ": unknown key \"" + k + "\" (known: global, size, blocks, sheets, entities)");
    }
  }
  return r;
}

}  // namespace dicer
