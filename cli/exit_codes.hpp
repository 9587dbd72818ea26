#pragma once
// The exit status of the dicer command: the one table that maps an error's
// kind (and, for Cancelled, the signal that arrived) to a code, and the text
// of `dicer --help` and the README made from it.
#include <string>

#include "dicer/error.hpp"

namespace dicer::cli {

inline constexpr int kExitSuccess = 0;
inline constexpr int kExitDefect = 1;     // verify found a defect, transfer --check no nesting (outcomes, not errors)
inline constexpr int kExitInternal = 70;  // a bug or out of memory: anything not a dicer::Error

// Cancelled: 128 + the signal (130 SIGINT, 143 SIGTERM, 129 SIGHUP); 130
// when no signal was recorded (a cancel callback of the library).
int exit_code(ErrorKind kind, int signal);

// "Exit codes:" and one line per code, for `dicer --help`.
std::string exit_code_help();

}  // namespace dicer::cli
