#pragma once
// Shared plumbing of the dicer command that needs no option parser: number
// arguments, file-argument checks, signals, human-readable sizes, progress
// bars. The parser and the option sets shared by several commands are in
// command.hpp, JSON output in json_out.hpp, exit codes in exit_codes.hpp.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/mpi.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

// The MPI session of this process, set by main (inactive without mpirun).
dicer::mpi::Session& session();
void set_session(dicer::mpi::Session* s);
// Under mpirun, a command without a distributed mode runs on rank 0 alone;
// every rank returns rank 0's exit code (errors agreed by checkpoint).
int on_rank0(const std::function<int()>& fn);
// Runs fn on this rank; under mpirun, then agrees on errors with the other
// ranks (every rank calls it, and all throw if any failed).
void agree(const std::function<void()>& fn);

// In `dicer` (built without Gmsh): when args (command first) need a CAD
// model, replaces this process by `dicer-cad` with the same argv (beside
// this executable, or $DICER_CAD); throws Error{Io} when it cannot. In
// `dicer-cad`: does nothing (cli/cad/with.cpp).
void hand_over_if_cad(char** argv, const std::vector<std::string>& args);

// Under mpirun, after an agree() in which every rank read a store from
// `path`: mpi::require_same_store. Does nothing without MPI.
void check_same_store(const std::string& path, const std::string& uuid);

// The words before the first "--" (after it every word is an argument):
// what a scan of the command line for an option looks at.
std::vector<std::string> options_part(const std::vector<std::string>& args);

std::int64_t parse_int(const std::string& what, const std::string& text);
// A --threads value: 1 to 1024 (Error{Usage} otherwise).
std::int64_t parse_threads(const std::string& text);
double parse_double(const std::string& what, const std::string& text);
// "a:b" -> [a, b); "a" -> [a, a+1).
std::pair<std::int64_t, std::int64_t> parse_range(const std::string& what, const std::string& text);

// A file the command reads: refused before any library opens it when it is
// missing (Error{Io}), a directory or anything but a regular file (a FIFO
// would block the open; Error{Usage}). `role` names the argument ("STORE",
// "--intervals-file").
void check_input_file(const std::string& path, const std::string& role);
// The file the command writes (`role`: "-o"): refused (Error{Usage}) when it
// is "-" (no standard output), exists and is a directory or not a regular
// file, or is the same file
// (device and inode, so links and "./" spellings count) as one of `inputs`.
void check_output_file(const std::string& path, const std::string& role,
                       const std::vector<std::pair<std::string, std::string>>& inputs);

// SIGXFSZ (a file grown past RLIMIT_FSIZE) ignored for the rest of the
// process: the write then fails with EFBIG, an ordinary I/O error, instead
// of the signal killing dicer with its temporary left behind. Called by
// CancelOnSignals (every command that writes); idempotent.
void ignore_file_size_signal();

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

// --stats: the page cache counters on stderr, one line, human readable.
void print_cache_stats(const FineMesh& mesh, const std::string& command);

std::string human_bytes(std::uint64_t bytes);
// "dicer COMMAND: warning: CAD: OpenCASCADE reported problems reading it:
// SAID; ..." on stderr when said (a report's cad_reader_said) is not empty.
void warn_cad_reader(const std::string& command, const std::string& cad, const std::string& said);
// Text from a file or an argument for a terminal (a name in a table, an
// error message): control characters (a line break in a block name, ESC)
// as \n, \t, \xHH or \u00HH (C1), bytes that are not well-formed UTF-8
// as \xHH, so one record stays on one line and no escape sequence from a
// hostile file reaches the terminal. Well-formed UTF-8 is kept.
std::string printable(const std::string& name);
std::string human_count(std::int64_t n);
std::string human_duration(std::uint64_t ns);  // "850 ns", "37.5 us", "6.9 ms", "1.23 s"

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

// The subcommands: argv without the command's name; the exit status.
int cmd_sheets(const std::vector<std::string>& argv);
int cmd_dice(const std::vector<std::string>& argv);
int cmd_info(const std::vector<std::string>& argv);
int cmd_query(const std::vector<std::string>& argv);
int cmd_verify(const std::vector<std::string>& argv);
int cmd_footprint(const std::vector<std::string>& argv);
int cmd_export(const std::vector<std::string>& argv);
int cmd_sweep(const std::vector<std::string>& argv);
int cmd_mesh_coarse(const std::vector<std::string>& argv);
int cmd_transfer(const std::vector<std::string>& argv);

}  // namespace dicer::cli
