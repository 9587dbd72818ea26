#include "command.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <sstream>

#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"

namespace dicer::cli {
namespace {

constexpr size_t kNameColumn = 26;  // where option descriptions start
constexpr size_t kLineWidth = 80;

bool looks_like_option(const std::string& a) {
  // "-5" and "-.5" are values (negative numbers), "-" alone is a file name.
  return a.size() > 1 && a[0] == '-' && !std::isdigit(static_cast<unsigned char>(a[1])) && a[1] != '.';
}

std::string indent_lines(const std::string& text, const std::string& pad) {
  std::string out;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    if (end > start) out += pad + text.substr(start, end - start);
    out += '\n';
    start = end + 1;
  }
  return out;
}

// Word-wraps each line of `text` ('\n' is a forced break) that is wider
// than `width`, keeping its indentation; narrower lines stay as written
// (aligned JSON shapes).
std::string wrap(const std::string& text, size_t width) {
  std::string out;
  std::istringstream lines(text);
  bool first = true;
  for (std::string line; std::getline(lines, line); first = false) {
    if (!first) out += '\n';
    if (line.size() <= width) {
      out += line;
      continue;
    }
    const size_t lead = std::min(line.find_first_not_of(' '), line.size());
    std::istringstream words(line.substr(lead));
    std::string cur(lead, ' ');
    for (std::string w; words >> w;) {
      if (cur.size() > lead && cur.size() + 1 + w.size() > width) out += cur + '\n', cur.assign(lead, ' ');
      cur += (cur.size() > lead ? " " : "") + w;
    }
    out += cur;
  }
  return out;
}

}  // namespace

Command::Command(const CommandDoc& doc) : doc_(doc), name_(doc.name), app_("", std::string("dicer ") + doc.name) {
  // Unknown options and stray arguments come back in remaining(), so that
  // parse() words the refusal ("unknown option --x (see dicer info --help)").
  app_.allow_extras();
  app_.set_help_flag("-h,--help", "this help");
  app_.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
}

void Command::input(const char* name, std::string& into, const char* description) {
  inputs_.push_back(app_.add_option(name, into, description)->type_name("")->group("Arguments"));
}

CLI::Option* Command::value(const std::string& names, std::string& into, const char* value_name,
                            const char* description, const std::string& group, const std::string& shown_default) {
  CLI::Option* o = app_.add_option(names, into, description)->type_name(value_name)->group(group);
  if (!shown_default.empty()) o->default_str(shown_default);
  else if (!into.empty()) o->default_str(into);
  return o;
}

CLI::Option* Command::values(const std::string& names, std::vector<std::string>& into, const char* value_name,
                             const char* description, const std::string& group) {
  // One value per occurrence: "--block-interval 2=4 MESH" must leave MESH alone.
  return app_.add_option(names, into, description)
      ->type_name(value_name)
      ->group(group)
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

CLI::Option* Command::flag(const std::string& names, bool& into, const char* description, const std::string& group) {
  return app_.add_flag(names, into, description)->group(group);
}

void Command::quiet_accepted() {
  app_.add_flag("--quiet", quiet_, "accepted for scripts that pass it to every command; this one draws no progress bar")
      ->group("Options");
}

CLI::Option* Command::input_value(const std::string& names, std::string& into, const char* value_name,
                                  const char* description, const std::string& group) {
  CLI::Option* o = value(names, into, value_name, description, group);
  inputs_.push_back(o);
  return o;
}

CLI::Option* Command::output(std::string& into, const char* value_name, const char* description, bool required) {
  output_ = value("-o,--output", into, value_name, description);
  if (required) require(output_, "the output file");
  return output_;
}

void Command::require(CLI::Option* o, const std::string& what) { required_.emplace_back(o, what); }

std::string Command::display_name(const CLI::Option* o) const {
  if (o->get_positional()) return o->get_name(true);
  const std::string flag = o->get_snames().empty() ? "--" + o->get_lnames().front() : "-" + o->get_snames().front();
  return o->get_type_name().empty() ? flag : flag + " " + o->get_type_name();
}

void Command::usage_error(const std::string& message) const {
  throw Error(ErrorKind::Usage, message + " (see dicer " + name_ + " --help)");
}

bool Command::parse(const std::vector<std::string>& argv) {
  // "--" ends the options: what follows is an argument even where it
  // starts with '-' (a file named -x.e). CLI11 takes the rest as
  // positionals and leaves the mark itself in remaining().
  const auto mark = std::find(argv.begin(), argv.end(), std::string("--"));
  std::vector<std::string> args;
  for (auto it = argv.begin(); it != mark; ++it) {
    const std::string& a = *it;
    // "--json=0" would be false and "--json=1" true (CLI11): a flag takes
    // no value, said so.
    if (const auto eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos) {
      const CLI::Option* o = app_.get_option_no_throw(a.substr(0, eq));
      if (o && o->get_items_expected_max() == 0) usage_error(a.substr(0, eq) + " takes no value (got \"" + a.substr(eq + 1) + "\")");
    }
    // "-o=FILE" means "-o FILE" (CLI11 would keep the "=" in the value).
    if (a.size() > 2 && a[0] == '-' && a[1] != '-' && a[2] == '=' && app_.get_option_no_throw(a.substr(0, 2))) {
      args.push_back(a.substr(0, 2)), args.push_back(a.substr(3));
    } else {
      args.push_back(a);
    }
  }
  // A value option that ends the options: say so by its name (CLI11's
  // own words would be "1 required N missing").
  if (!args.empty()) {
    const CLI::Option* last = looks_like_option(args.back()) ? app_.get_option_no_throw(args.back()) : nullptr;
    if (last && last->get_items_expected_max() > 0) usage_error(args.back() + " needs a value");
  }
  args.insert(args.end(), mark, argv.end());
  std::reverse(args.begin(), args.end());  // CLI11 takes them last first
  try {
    app_.parse(args);
  } catch (const CLI::CallForHelp&) {
    std::fputs(help().c_str(), stdout);
    return false;
  } catch (const CLI::ParseError& e) {
    usage_error(e.what());
  }
  std::vector<std::string> extra = app_.remaining();
  const auto extra_mark = std::find(extra.begin(), extra.end(), std::string("--"));
  for (auto it = extra.begin(); it != extra_mark; ++it)
    if (looks_like_option(*it)) usage_error("unknown option " + it->substr(0, it->find('=')));
  if (extra_mark != extra.end()) extra.erase(extra_mark);
  if (!extra.empty()) usage_error("unexpected argument \"" + extra.front() + "\"");
  for (const CLI::Option* in : inputs_)
    if (in->get_positional() && !given(in)) usage_error("missing " + display_name(in));
  for (const auto& [o, what] : required_)
    if (!given(o)) throw Error(ErrorKind::Usage, "missing " + display_name(o) + " (" + what + ")");
  std::vector<std::pair<std::string, std::string>> files;
  for (const CLI::Option* in : inputs_) {
    if (!given(in)) continue;
    const std::string path = in->as<std::string>(), role = in->get_positional() ? in->get_name(true) : display_name(in);
    check_input_file(path, role);
    files.emplace_back(path, role);
  }
  if (output_ && given(output_)) check_output_file(output_->as<std::string>(), "-o", files);
  return true;
}

std::string Command::help() const {
  std::string s = std::string("Usage: dicer ") + doc_.synopsis + "\n\n" + doc_.about;
  // The argument first, then the groups in the order of their first
  // option; the help flag closes "Options".
  const auto options = app_.get_options();
  std::vector<std::string> groups = {"Arguments", "Options"};
  for (const CLI::Option* o : options)
    if (std::find(groups.begin(), groups.end(), o->get_group()) == groups.end()) groups.push_back(o->get_group());
  auto entry = [&](const CLI::Option* o) {
    std::string names;
    if (o->get_positional()) names = o->get_name(true);
    for (const auto& n : o->get_snames()) names += (names.empty() ? "-" : ", -") + n;
    for (const auto& n : o->get_lnames()) names += (names.empty() ? "--" : ", --") + n;
    if (!o->get_type_name().empty()) names += " " + o->get_type_name();
    std::string head = "  " + names;
    head += head.size() + 2 <= kNameColumn ? std::string(kNameColumn - head.size(), ' ') : "\n" + std::string(kNameColumn, ' ');
    std::vector<std::string> notes;
    if (std::any_of(required_.begin(), required_.end(), [&](const auto& r) { return r.first == o; })) notes.push_back("required");
    if (o->get_multi_option_policy() == CLI::MultiOptionPolicy::TakeAll) notes.push_back("repeatable");
    if (!o->get_default_str().empty()) notes.push_back("default: " + o->get_default_str());
    std::string desc = o->get_description();
    if (!notes.empty()) {
      desc += " (";
      for (size_t i = 0; i < notes.size(); ++i) desc += (i ? "; " : "") + notes[i];
      desc += ")";
    }
    return head + indent_lines(wrap(desc, kLineWidth - kNameColumn), std::string(kNameColumn, ' ')).substr(kNameColumn);
  };
  for (const auto& g : groups) {
    std::string block;
    for (const CLI::Option* o : options)
      if (o->get_group() == g && o != app_.get_help_ptr()) block += entry(o);
    if (g == "Options") block += entry(app_.get_help_ptr());
    if (!block.empty()) s += "\n" + g + ":\n" + block;
  }
  s += "\nExamples:\n" + indent_lines(doc_.examples, "  ");
  return s;
}

// ---- the option sets shared by several commands

StoreFlags::StoreFlags(Command& cmd)
    : command_(cmd.name()),
      cache_mb_(std::to_string(StoreOptions{}.cache_bytes >> 20)),
      read_ahead_(std::to_string(StoreOptions{}.read_ahead_pages)) {
  const std::string group = "Store options (every command that opens a store)";
  cmd.value("--cache-mb", cache_mb_, "N",
            "page cache budget in MiB: decoded pages resident at once; "
            "memory stays under it plus a small constant",
            group);
  cmd.value("--read-ahead", read_ahead_, "N",
            "pages read ahead when rows are read in order, 0 to 1024", group);
  cmd.flag("--no-keep-tables", no_keep_tables_,
           "do not keep the small coarse tables resident once read (by default "
           "those that fit a quarter of a budget of 32 MiB or more stay, so "
           "random queries read their rows without a pin); every page can then "
           "be evicted",
           group);
  cmd.flag("--stats", stats_,
           "print the page cache counters to stderr when done: pages "
           "and bytes read, bytes decompressed, hits, misses, "
           "evictions, peak resident bytes; the time spent loading pages, "
           "the part the threads that missed paid themselves (the rest "
           "was read ahead), and the time spent waiting for pages in flight; "
           "under mpirun each rank prints its own, labelled \"(rank R of P)\"",
           group);
}

StoreOptions StoreFlags::options() const {
  StoreOptions o;
  const auto mb = parse_int("--cache-mb", cache_mb_);
  if (mb < 1 || mb > (1ll << 30)) throw Error(ErrorKind::Usage, "--cache-mb: must be between 1 and 2^30 (MiB)");
  o.cache_bytes = static_cast<std::uint64_t>(mb) << 20;
  const auto n = parse_int("--read-ahead", read_ahead_);
  if (n < 0 || n > 1024) throw Error(ErrorKind::Usage, "--read-ahead: must be between 0 and 1024 pages");
  o.read_ahead_pages = static_cast<unsigned>(n);
  o.keep_coarse_tables = !no_keep_tables_;
  return o;
}

void StoreFlags::report(const FineMesh& mesh) const {
  if (stats_) print_cache_stats(mesh, command_);
}

IntervalFlags::IntervalFlags(Command& cmd) {
  const std::string group = "Interval options (precedence: sheet > block and entity (the largest) > size > global > 1)";
  interval_opt_ = cmd.value("--interval", interval_, "N", "every sheet gets N", group, "1");
  size_opt_ = cmd.value("--size", size_, "H",
            "each sheet gets the smallest N that makes all the cells of "
            "its edges no longer than H (a graded sheet: under its "
            "grading)",
            group);
  cmd.values("--block-interval", text_.block_interval, "B=N",
             "sheets touching block B (id or name) get N; a sheet "
             "touching several such blocks gets the LARGEST, and the "
             "conflict is reported",
             group);
  cmd.values("--sheet-interval", text_.sheet_interval, "S=N", "sheet S gets N, whatever its blocks ask", group);
  cmd.values("--entity-interval", text_.entity_interval, "DIM:TAG=N",
             "sheets with an edge on curve (DIM 1), surface (2) or "
             "volume (3) TAG get N, ranked like block requests (the "
             "LARGEST wins, reported); TAG: the mesh's MSH entity, or "
             "the CAD's when dice is given one",
             group);
  const std::string grading = "Grading options (fine nodes closer together at one or both ends of a sheet's edges)";
  cmd.values("--sheet-bias", text_.sheet_bias, "S=R[@V]",
             "sheet S's fine edges grow by R from node V (a node id of "
             "the input file on the sheet; default: the lower node id "
             "of its first edge, as `dicer sheets` lists them) across "
             "the sheet; "
             "R > 1: fine at V. first:h or last:h instead of R: the "
             "first (last) cell of the sheet's longest edge is h long, "
             "R follows from the interval (with --size: the smallest "
             "interval whose cells all fit in the size)",
             grading);
  cmd.values("--sheet-dual-bias", text_.sheet_dual_bias, "S=R",
             "symmetric: the cells grow by R from both ends to the "
             "middle (R > 1: fine at both ends; first:h: end cells h)",
             grading);
  cmd.values("--block-bias", text_.block_bias, "B=R[@V]",
             "every sheet touching block B gets that bias (below "
             "--sheet-bias; the first block's wins, reported)",
             grading);
  cmd.values("--entity-bias", text_.entity_bias, "DIM:TAG=R[@V]",
             "every sheet with an edge on that entity gets that bias, "
             "ranked like --block-bias",
             grading);
  file_opt_ = cmd.input_value("--intervals-file", file_, "FILE",
                  "JSON with any of these keys:\n"
                  "{\"global\": 4, \"size\": 0.05, \"blocks\": {\"2\": 6,\n"
                  "\"wall\": {\"interval\": 8, \"bias\": 1.1}}, \"sheets\":\n"
                  "{\"17\": {\"interval\": 12, \"bias\": 1.2, \"start\": 345},\n"
                  "\"3\": {\"dual_bias\": 1.3}}, \"entities\": {\"2:5\": 8}}\n"
                  "(a value: an interval, or an object with interval and\n"
                  "one of bias, dual_bias, first, last, with start)\n"
                  "flags on the command line override the file",
                  group);
}

IntervalRequest IntervalFlags::request() const {
  IntervalRequest file;
  if (file_opt_->count()) file = read_interval_file(file_);
  IntervalRequest flags = parse_interval_options(text_);
  if (interval_opt_->count()) flags.global = parse_int("--interval", interval_);
  if (size_opt_->count()) flags.size = parse_double("--size", size_);
  return merge(file, flags);
}

}  // namespace dicer::cli
