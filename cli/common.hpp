#pragma once
// Shared plumbing of the dicer command: argument parsing, human-readable
// sizes, progress bars (JSON output: json_out.hpp). Subcommands stay thin.
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "dicer/intervals.hpp"
#include "dicer/store.hpp"
#include "dicer/types.hpp"

namespace dicer::cli {

// In `dicer` (built without Gmsh): when args (command first) need a CAD
// model, replaces this process by `dicer-cad` with the same argv (beside
// this executable, or $DICER_CAD); throws Error{Io} when it cannot. In
// `dicer-cad`: does nothing (cli/cad/with.cpp).
void hand_over_if_cad(char** argv, const std::vector<std::string>& args);

// Flags: "--name value", "--name=value", boolean "--name". Unknown flags,
// missing values and stray positionals are usage errors naming the flag.
class Args {
 public:
  Args(std::string command, std::vector<std::string> argv, std::vector<std::string> value_flags,
       std::vector<std::string> bool_flags, int max_positional);
  bool has(const std::string& flag) const { return values_.count(flag) > 0; }
  std::optional<std::string> value(const std::string& flag) const;
  std::vector<std::string> values(const std::string& flag) const;
  const std::vector<std::string>& positional() const { return positional_; }
  std::string need_positional(size_t i, const std::string& what) const;
  std::int64_t int_value(const std::string& flag, std::int64_t fallback) const;

 private:
  std::string command_;
  std::map<std::string, std::vector<std::string>> values_;
  std::vector<std::string> positional_;
};

std::int64_t parse_int(const std::string& what, const std::string& text);
double parse_double(const std::string& what, const std::string& text);
// "a:b" -> [a, b); "a" -> [a, a+1).
std::pair<std::int64_t, std::int64_t> parse_range(const std::string& what, const std::string& text);

// Interval flags shared by `sheets` and `dice`.
IntervalRequest interval_request(const Args& args);
inline const std::vector<std::string> kIntervalFlags = {"--interval", "--block-interval", "--sheet-interval", "--size",
                                                        "--intervals-file"};

// --cache-mb N (default 64) and --read-ahead N for commands that open a store.
inline const std::vector<std::string> kStoreFlags = {"--cache-mb", "--read-ahead"};
StoreOptions store_options(const Args& args);
// --stats: the page cache counters on stderr, one line, human readable.
void print_cache_stats(const FineMesh& mesh, const std::string& command);

// SIGINT, SIGTERM and SIGHUP while a command writes a file: the handler only
// records the signal; the command polls cancel_requested() through the
// library's progress and cancel callbacks and throws Error{Cancelled}, so
// temporary files are removed on the way out, and main exits 128 + signal.
// A second signal kills at once (the handler resets itself).
class CancelOnSignals {
 public:
  CancelOnSignals();
  ~CancelOnSignals();
  CancelOnSignals(const CancelOnSignals&) = delete;
  CancelOnSignals& operator=(const CancelOnSignals&) = delete;
};
bool cancel_requested();
int received_signal();  // 0 when none arrived
// Throws Error{Cancelled, "interrupted by SIGINT; <outcome>"} when a signal arrived.
void throw_if_cancelled(const std::string& outcome);

std::string human_bytes(std::uint64_t bytes);
std::string human_count(std::int64_t n);

// A progress bar on stderr, drawn only when stderr is a terminal and not
// --quiet; at most ~10 redraws per second.
class Progress {
 public:
  Progress(std::string label, std::int64_t total, bool quiet);
  ~Progress();
  void update(std::int64_t done);
  void update(std::int64_t done, std::int64_t total) {
    total_ = total;
    update(done);
  }

 private:
  std::string label_;
  std::int64_t total_;
  bool enabled_;
  double start_, last_ = -1;
};

using Command = std::function<int(const std::vector<std::string>&)>;
int cmd_sheets(const std::vector<std::string>& argv);
int cmd_dice(const std::vector<std::string>& argv);
int cmd_info(const std::vector<std::string>& argv);
int cmd_query(const std::vector<std::string>& argv);
int cmd_verify(const std::vector<std::string>& argv);
int cmd_footprint(const std::vector<std::string>& argv);
int cmd_export(const std::vector<std::string>& argv);
int cmd_sweep(const std::vector<std::string>& argv);
int cmd_mesh_coarse(const std::vector<std::string>& argv);

}  // namespace dicer::cli
