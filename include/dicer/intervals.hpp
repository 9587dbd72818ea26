#pragma once
// Intervals: one number of fine intervals per dicer sheet.
//
// Precedence, highest first (also in `dicer dice --help` and README):
//   1. --sheet-interval S=N / "sheets": {"S": N}
//   2. --block-interval B=N / "blocks": {"B": N} (B is a block id or name):
//      a sheet that touches several blocks with requests takes the LARGEST;
//   3. --size H / "size": the smallest n making every edge of the sheet no
//      longer than H (straight-line length of the coarse edge);
//   4. --interval N / "global";   5. otherwise 1.
// Every time a rule overrides another request for the same sheet, a note
// names the sheet, the blocks and the values; nothing is resolved silently.
// Command-line flags override the same keys of an intervals file.
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/sheets.hpp"
#include "dicer/topology.hpp"

namespace dicer {

// The one limit on an interval, checked wherever one enters (flags, the
// intervals file, --size): a whole number in [1, kMaxInterval]. Throws
// Error{Usage} below 1 or fractional, Error{Overflow} above the limit.
inline constexpr Id kMaxInterval = Id{1} << 40;  // any larger overflows counts long before
Id checked_interval(const std::string& what, long double n);

struct IntervalRequest {
  std::optional<Id> global;
  std::optional<double> size;
  std::vector<std::pair<std::string, Id>> blocks;  // block id or name -> n
  std::vector<std::pair<Id, Id>> sheets;           // sheet id -> n
};

// Parses the JSON intervals file {"global":4,"size":0.05,"blocks":{"2":6},
// "sheets":{"17":12}}; every key optional, unknown keys refused.
IntervalRequest read_interval_file(const std::string& path);
// `over` wins over `base` key by key.
IntervalRequest merge(IntervalRequest base, const IntervalRequest& over);

struct IntervalPlan {
  std::vector<Id> sheet_interval;   // n >= 1 per sheet
  std::vector<std::string> notes;   // how conflicts were resolved
};

// Throws Error{Usage} for n < 1, a non-positive size, unknown block or sheet.
IntervalPlan resolve_intervals(const CoarseMesh& mesh, const Topology& topo, const Sheets& sheets,
                               const IntervalRequest& request);

}  // namespace dicer
