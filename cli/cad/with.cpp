// Linked into `dicer-cad` (the commands with Gmsh): every command runs here.
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "../common.hpp"
#include "../exit_codes.hpp"
#include "dicer/atomic_output.hpp"

namespace dicer::cli {
namespace {

// What a crash says, made before it (a signal handler may only write it).
// OpenCASCADE dereferences dangling entities of malformed STEP files
// (SIGSEGV) and Gmsh throws from its OpenMP threads (std::terminate,
// SIGABRT): one line deleted from a valid STEP file was enough. The
// crash is said as an error naming the model, the temporaries go, and the
// exit code is 70 (internal error) rather than a signal's death.
constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};
std::string g_crash[std::size(kCrashSignals)];
alignas(16) char g_alt_stack[1 << 16];  // the main thread's stack overflow still runs the handler (not Gmsh's threads')

extern "C" void on_crash(int sig) {
  AtomicOutput::remove_uncommitted();
  for (size_t i = 0; i < std::size(kCrashSignals); ++i)
    if (kCrashSignals[i] == sig) {
      ssize_t ignored = ::write(STDERR_FILENO, g_crash[i].data(), g_crash[i].size());
      (void)ignored;
    }
  ::_exit(kExitInternal);
}

// The CAD model of the command line: dice/verify --geometry's value (the
// last, as the commands take it), or mesh-coarse's first argument that is
// no option's value.
std::string cad_of(const std::vector<std::string>& all) {
  const std::vector<std::string> args = options_part(all);
  std::string geometry;
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--geometry" && i + 1 < args.size()) geometry = args[++i];
    else if (args[i].rfind("--geometry=", 0) == 0) geometry = args[i].substr(11);
  }
  if (!geometry.empty()) return geometry;
  if (!all.empty() && all[0] == "mesh-coarse") {
    bool after_dashes = false;
    for (size_t i = 1; i < all.size(); ++i) {
      const std::string& a = all[i];
      if (!after_dashes && a == "--") {
        after_dashes = true;
      } else if (!after_dashes && (a == "-o" || a == "--output" || a == "--size")) {
        ++i;
      } else if (after_dashes || a.empty() || a[0] != '-') {
        return a;
      }
    }
  }
  return "";
}

void say_crashes_as_errors(const std::vector<std::string>& args) {
  const std::string command = args.empty() ? "" : args[0];
  const std::string cad = cad_of(args);
  const std::string model = cad.empty() ? "the CAD model" : "the CAD model " + printable(cad);
  const char* names[] = {"SIGSEGV (segmentation fault)", "SIGBUS", "SIGILL", "SIGFPE", "SIGABRT (abort)"};
  for (size_t i = 0; i < std::size(kCrashSignals); ++i)
    g_crash[i] = "dicer " + command + ": error: dicer-cad crashed with " + names[i] + " working on " + model +
                 ": OpenCASCADE and Gmsh crash on some malformed STEP and BREP files; check that Gmsh opens it (gmsh " +
                 (cad.empty() ? std::string("MODEL") : printable(cad)) +
                 "). If it does, this is a dicer bug: please report it with the files. No output file was written.\n";
  stack_t ss{};
  ss.ss_sp = g_alt_stack;
  ss.ss_size = sizeof g_alt_stack;
  ::sigaltstack(&ss, nullptr);
  struct sigaction sa {};
  sa.sa_handler = on_crash;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_ONSTACK | SA_RESETHAND;
  for (const int s : kCrashSignals) ::sigaction(s, &sa, nullptr);
}

}  // namespace

// dicer-cad is where a handed-over command lands: the mark that dicer set
// (cad/without.cpp) stops here, so no program dicer-cad starts inherits it.
void hand_over_if_cad(char**, const std::vector<std::string>& args) {
  ::unsetenv("DICER_CAD_HANDED_OVER");
  say_crashes_as_errors(args);
}

}  // namespace dicer::cli
