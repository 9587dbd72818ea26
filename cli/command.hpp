#pragma once
// The option parser of every subcommand (CLI11) and the option sets several
// commands share, each declared once. A command declares its options here
// and nowhere else: `dicer COMMAND --help` lists exactly what the parser
// accepts (names, value, default, description), between the command's
// hand-written usage line, explanation and examples.
#include <CLI/CLI.hpp>
#include <string>
#include <utility>
#include <vector>

#include "dicer/intervals.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

struct CommandDoc {
  const char* name;      // "info"
  const char* synopsis;  // after "Usage: dicer ", e.g. "info STORE [--json] [store options]"
  const char* about;     // what the command does, in paragraphs
  const char* examples;  // command lines, one per line
};

class Command {
 public:
  explicit Command(const CommandDoc& doc);

  // The command's one positional argument, a file it reads (MESH, STORE,
  // CAD): required, and checked by parse() (check_input_file).
  void input(const char* name, std::string& into, const char* description);
  // --name VALUE, the last one given wins. A non-empty `into` is the default
  // and the help shows it; `shown_default` documents a default the code
  // works out itself ("all cores").
  CLI::Option* value(const std::string& names, std::string& into, const char* value_name, const char* description,
                     const std::string& group = "Options", const std::string& shown_default = "");
  // --name VALUE, repeatable; every value kept, in order.
  CLI::Option* values(const std::string& names, std::vector<std::string>& into, const char* value_name,
                      const char* description, const std::string& group = "Options");
  CLI::Option* flag(const std::string& names, bool& into, const char* description, const std::string& group = "Options");
  // --quiet for a command that prints no progress: accepted, so that a
  // script can pass it to every command.
  void quiet_accepted();
  // A value option naming another file the command reads: checked by parse().
  CLI::Option* input_value(const std::string& names, std::string& into, const char* value_name, const char* description,
                           const std::string& group = "Options");
  // -o, --output FILE: required unless `required` is false; parse() refuses
  // a directory, a non-regular file and the same file as any input.
  CLI::Option* output(std::string& into, const char* value_name, const char* description, bool required = true);
  // parse() refuses the command line without `o` ("missing --format FMT (what)").
  void require(CLI::Option* o, const std::string& what);

  // argv without the command name. Returns false when --help was asked for
  // (the help is then printed on stdout). Throws Error{Usage} naming the
  // flag for anything the parser refuses, then checks the files.
  bool parse(const std::vector<std::string>& argv);
  std::string help() const;
  const std::string& name() const { return name_; }
  bool given(const CLI::Option* o) const { return o->count() > 0; }

 private:
  std::string display_name(const CLI::Option* o) const;
  [[noreturn]] void usage_error(const std::string& message) const;

  CommandDoc doc_;
  std::string name_;
  CLI::App app_;
  std::vector<std::pair<CLI::Option*, std::string>> required_;
  std::vector<CLI::Option*> inputs_;
  CLI::Option* output_ = nullptr;
  bool quiet_ = false;  // quiet_accepted(): nothing to quiet
};

// The option sets below register options bound to their own members: the
// object must outlive parse() and not be const (parse() writes into it).
//
// --cache-mb, --read-ahead, --no-keep-tables, --stats: one declaration for every command that
// opens a store (info, query, verify, footprint, export, sweep).
class StoreFlags {
 public:
  explicit StoreFlags(Command& cmd);
  StoreOptions options() const;
  // After the work: the page cache counters on stderr when --stats was given.
  void report(const FineMesh& mesh) const;
  bool stats() const { return stats_; }

 private:
  std::string command_, cache_mb_, read_ahead_;
  bool no_keep_tables_ = false, stats_ = false;
};

// --interval, --size, --block-interval, --sheet-interval, --entity-interval,
// the bias flags, --intervals-file: one declaration for `sheets` and `dice`.
class IntervalFlags {
 public:
  explicit IntervalFlags(Command& cmd);
  // The intervals file (if any) merged with the flags, which win.
  IntervalRequest request() const;

 private:
  std::string interval_, size_, file_;
  IntervalOptionText text_;
  const CLI::Option *interval_opt_ = nullptr, *size_opt_ = nullptr, *file_opt_ = nullptr;
};

}  // namespace dicer::cli
