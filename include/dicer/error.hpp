#pragma once
// The one exception type the library throws at its public boundary.
//
// Three tiers (STYLE.md #8): bad files, bad arguments and I/O failures throw
// dicer::Error; expected outcomes (a verify that finds a defect) are return
// values; programmer errors (a broken internal invariant) are DICER_ASSERT,
// checked in every build, tests and release alike. The library never calls
// exit or abort: a failed assertion throws InternalError, which is not a
// dicer::Error, so the CLI reports an internal error (exit 70) and a test
// fails loudly.
#include <stdexcept>
#include <string>

namespace dicer {

enum class ErrorKind {
  Usage = 2,        // bad command-line argument or API parameter
  BadInput = 3,     // malformed, truncated, hostile or inconsistent input file
  Unsupported = 4,  // valid file, but content dicer cannot dice (tets, HEX20...)
  Io = 5,           // the OS or HDF5 failed to read or write
  Overflow = 6,     // requested fine counts do not fit 64-bit ids
  Geometry = 7,     // mesh and CAD do not match, or projection would invert an element
  Corrupt = 8,      // store page checksum or structure mismatch
  Cancelled = 9,    // the caller asked to stop (a cancel callback, Ctrl-C); nothing was written
};

// Message convention: "<file>: <entity>: <what is wrong>". The CLI prints
// what() on one line and maps kind() to its exit status through one table
// (cli/exit_codes.cpp), not through the enum's values.
class Error : public std::runtime_error {
 public:
  Error(ErrorKind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const noexcept { return kind_; }

 private:
  ErrorKind kind_;
};

// A failed DICER_ASSERT: a bug in dicer, not in its input.
class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

[[noreturn]] inline void assertion_failed(const char* cond, const char* what, const char* file, int line) {
  throw InternalError(std::string("internal error: ") + what + " (" + cond + " failed at " + file + ":" +
                      std::to_string(line) + ")");
}

}  // namespace dicer

#define DICER_ASSERT(cond, what) ((cond) ? void(0) : ::dicer::assertion_failed(#cond, what, __FILE__, __LINE__))
