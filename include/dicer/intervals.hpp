#pragma once
// Intervals: one number of fine intervals per dicer sheet, and how the fine
// nodes are spaced along its edges (its grading, tfi.hpp).
//
// Interval precedence, highest first (also in `dicer dice --help` and README):
//   1. --sheet-interval S=N / "sheets": {"S": N}
//   2. --block-interval B=N / "blocks": {"B": N} (B is a block id or name)
//      and --entity-interval DIM:TAG=N / "entities": {"DIM:TAG": N} (every
//      sheet with an edge on that curve, surface or volume, edge_entities
//      below): a sheet that several of these requests touch takes the
//      LARGEST;
//   3. --size H / "size": the smallest n making every cell of the sheet's
//      longest edge (straight-line length of the coarse edge) no longer
//      than H, under the sheet's grading (equal spacing: its length / n);
//   4. --interval N / "global";   5. otherwise 1.
// Grading precedence: --sheet-bias / --sheet-dual-bias S (or "sheets":
// {"S": {"bias": R}}) over block and entity biases; a sheet that block or
// entity biases disagree on takes the first of them (its blocks in block
// order, then entities in (dim, tag) order); otherwise equal spacing.
// Every time a rule overrides another request for the same sheet, a note
// names the sheet, the requests and the values; nothing is resolved
// silently. Command-line flags override the same keys of an intervals file.
//
// Grading (tfi::Series): a geometric series of ratio R (each fine edge R
// times the previous one, going away from the start node) or a dual series
// (the same from both ends to the middle). Its direction crosses the sheet
// face by face (orient_sheets, sheets.hpp) from the start node: a node id of
// the input file on one of the sheet's edges, by default the lower file id
// of the sheet's first edge (as `dicer sheets --edges` lists them). A
// twisted sheet (a Moebius-like ring) refuses a geometric bias (a dual one
// has no direction). Instead of R, the length h of the first or last cell
// may be given: R is then the ratio that makes that cell of the sheet's
// longest edge h long at the sheet's interval; when the interval comes from
// --size, n is the smallest interval for which that series has no cell
// longer than H (R follows from h and n).
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/sheets.hpp"
#include "dicer/tfi.hpp"
#include "dicer/topology.hpp"

namespace dicer {

// The one limit on an interval, checked wherever one enters (flags, the
// intervals file, --size): a whole number in [1, kMaxInterval]. Throws
// Error{Usage} below 1 or fractional, Error{Overflow} above the limit.
inline constexpr Id kMaxInterval = Id{1} << 40;  // any larger overflows counts long before
Id checked_interval(const std::string& what, long double n);

// How one request grades its sheets: a geometric or dual series given by
// its ratio, or by the length of its first (last) cell. `start`: a node id
// of the input file where a geometric series starts.
struct BiasRequest {
  tfi::Spacing kind = tfi::Spacing::Geometric;  // Geometric or Dual
  double ratio = 1;       // R in [1/tfi::kMaxRatio, tfi::kMaxRatio], used when no cell is given
  double first_cell = 0;  // > 0: the first cell's length (dual: both end cells)
  double last_cell = 0;   // > 0: the last cell's length (geometric only)
  std::optional<Id> start;
  friend bool operator==(const BiasRequest&, const BiasRequest&) = default;
};
// "1.2", "1.2@345", "first:0.01", "last:0.5@17" (kind: Geometric), or the
// same for Dual ("@V" refused). Error{Usage} naming `what`.
BiasRequest parse_bias(const std::string& what, const std::string& text, tfi::Spacing kind);
// A finite number, the whole of `text`, else Error{Usage} naming `what`
// (bias requests here and every numeric option of the command line).
double parse_real(const std::string& what, const std::string& text);
// A whole number in 64 bits, the whole of `text`, else Error{Usage} naming
// `what` (every whole-number option of the command line).
std::int64_t parse_whole(const std::string& what, const std::string& text);
// Its checks (ratio range, positive finite cells), Error{Usage} naming `what`.
void check_bias(const std::string& what, const BiasRequest& b);
// "1.2 from node 345", "dual 1.1", "first cell 0.01": for notes and `sheets`.
std::string bias_text(const BiasRequest& b);

// A geometric entity (MSH entity or CAD tag): dimension 1..3 and tag.
using EntityTag = std::pair<int, int>;
// "2:5" -> (2, 5); Error{Usage} naming `what` unless DIM is 1, 2 or 3 and
// TAG a whole number.
EntityTag parse_entity(const std::string& what, const std::string& text);

struct IntervalRequest {
  std::optional<Id> global;
  std::optional<double> size;
  std::vector<std::pair<std::string, Id>> blocks;  // block id or name -> n
  std::vector<std::pair<Id, Id>> sheets;           // sheet id -> n
  std::vector<std::pair<EntityTag, Id>> entities;  // (dim, tag) -> n
  std::vector<std::pair<std::string, BiasRequest>> block_bias;
  std::vector<std::pair<Id, BiasRequest>> sheet_bias;
  std::vector<std::pair<EntityTag, BiasRequest>> entity_bias;
};

// The repeatable interval and grading options as the command line writes
// them, one string per occurrence: "B=N" (split at the last '=', so a block
// name may hold one), "S=N", "DIM:TAG=N", "S=R[@V]", "S=R" (dual), "B=R[@V]",
// "DIM:TAG=R[@V]", where R may be first:h or last:h. `dicer dice` and the
// Python package (which writes its keyword arguments so) both read them
// through parse_interval_options: one reading, one wording of its errors.
struct IntervalOptionText {
  std::vector<std::string> block_interval, sheet_interval, entity_interval;
  std::vector<std::string> sheet_bias, sheet_dual_bias, block_bias, entity_bias;
};
// Error{Usage} naming the option and the text ("--sheet-bias 3=x: ..."); a
// sheet with both a geometric and a dual bias is refused. Intervals are
// only parsed here: resolve_intervals checks their range.
IntervalRequest parse_interval_options(const IntervalOptionText& text);

// Parses the JSON intervals file {"global":4,"size":0.05,"blocks":{"2":6},
// "sheets":{"17":12},"entities":{"2:5":8}}; a block, sheet or entity value
// is a number (the interval) or an object with any of "interval", "bias",
// "dual_bias", "first", "last", "start" (one of bias, dual_bias, first,
// last). Every key optional, unknown keys refused.
IntervalRequest read_interval_file(const std::string& path);
// `over` wins over `base` key by key.
IntervalRequest merge(IntervalRequest base, const IntervalRequest& over);

struct IntervalPlan {
  std::vector<Id> sheet_interval;          // n >= 1 per sheet
  // Per sheet: its grading (flip unused: the direction is per edge) and,
  // geometric, the vertex (index into the mesh) its series starts at, -1.
  std::vector<tfi::Grading> sheet_grading;
  std::vector<Id> sheet_start;
  // Per edge of the topology: the series runs hi -> lo along it.
  std::vector<std::uint8_t> edge_flip;
  std::vector<std::string> notes;          // how conflicts were resolved
  // Edge e's grading in its canonical direction (lo -> hi).
  tfi::Grading edge_grading(const Sheets& s, Id e) const {
    tfi::Grading g = sheet_grading[s.edge_sheet[e]];
    g.flip = g.kind == tfi::Spacing::Geometric && edge_flip[e];
    return g;
  }
};

// The geometric entity each coarse edge lies on (pack_owner in tables.hpp,
// -1 unknown), from the vertices' classification and the model topology
// (CoarseMesh::vertex_geo_*, geo_entities): the lowest-dimensional entity
// whose closure holds both ends (a curve met by one edge alone when two
// curves join the same two points). Without model topology: the ends'
// entity when they share one, else the higher-dimensional of the two.
// An edge lies "on" an entity for entity requests when its entity is that
// entity or one in its closure (a surface's bounding curves, a volume's
// surfaces). O(E log) time.
std::vector<std::int64_t> edge_entities(const CoarseMesh& mesh, const Topology& topo);

// Throws Error{Usage} for n < 1, a non-positive size, unknown block, sheet
// or entity, a bad bias (twisted sheet, start node off the sheet, a cell
// size no ratio reaches, a smallest cell below tfi::kMinCell).
IntervalPlan resolve_intervals(const CoarseMesh& mesh, const Topology& topo, const Sheets& sheets,
                               const IntervalRequest& request);

}  // namespace dicer
