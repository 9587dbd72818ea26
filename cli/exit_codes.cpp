#include "exit_codes.hpp"

#include <csignal>
#include <cstdio>
#include <optional>
#include <string>

namespace dicer::cli {
namespace {

struct Row {
  int code;
  std::optional<ErrorKind> kind;  // none: not an error (success, a defect) or not a dicer::Error
  int signal;                     // Cancelled rows: the signal that arrived
  const char* meaning;
};

constexpr Row kTable[] = {
    {kExitSuccess, std::nullopt, 0, "success"},
    {kExitDefect, std::nullopt, 0, "verify found a defect; transfer --check: not nested"},
    {2, ErrorKind::Usage, 0, "bad command-line usage: an unknown option, a bad value, a\n"
     "directory or FIFO given as a file, an output that is an input"},
    {3, ErrorKind::BadInput, 0, "bad input file (a STORE that is not a dicer store too)"},
    {4, ErrorKind::Unsupported, 0, "unsupported content (element types, store version)"},
    {5, ErrorKind::Io, 0, "I/O error (a missing file among them)"},
    {6, ErrorKind::Overflow, 0, "counts would overflow 64-bit ids"},
    {7, ErrorKind::Geometry, 0, "mesh and CAD do not fit, an element would invert, or Gmsh\n"
     "cannot mesh the CAD model as asked (mesh-coarse)"},
    {8, ErrorKind::Corrupt, 0, "corrupt store (a checksum fails, tables disagree)"},
    {kExitInternal, std::nullopt, 0, "internal error, or out of memory"},
    {128 + SIGHUP, ErrorKind::Cancelled, SIGHUP, "hung up (SIGHUP)"},
    {128 + SIGINT, ErrorKind::Cancelled, SIGINT, "interrupted (Ctrl-C, SIGINT)"},
    {128 + SIGTERM, ErrorKind::Cancelled, SIGTERM, "terminated (SIGTERM)"},
};

}  // namespace

int exit_code(ErrorKind kind, int signal) {
  if (kind == ErrorKind::Cancelled && signal == 0) signal = SIGINT;
  for (const Row& r : kTable)
    if (r.kind == kind && (kind != ErrorKind::Cancelled || r.signal == signal)) return r.code;
  return kExitInternal;  // a kind the table lacks, or a signal dicer does not catch
}

std::string exit_code_help() {
  std::string s = "Exit codes:\n";
  char line[256];
  for (const Row& r : kTable) {
    std::string meaning = r.meaning;
    for (size_t p = meaning.find('\n'); p != std::string::npos; p = meaning.find('\n', p + 1))
      meaning.insert(p + 1, std::string(7, ' '));
    std::snprintf(line, sizeof line, "  %-4d %s\n", r.code, meaning.c_str());
    s += line;
  }
  s += "dice and export stopped by a signal (129, 130, 143) leave no output file\nbehind, not even a temporary one.\n";
  return s;
}

}  // namespace dicer::cli
