// Linked into `dicer-cad` (the commands with Gmsh): every command runs here.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#include "../common.hpp"
#include "../exit_codes.hpp"
#include "dicer/atomic_output.hpp"
#include "dicer/geometry.hpp"

namespace dicer::cli {
namespace {

// What a crash says, made before it (a signal handler may only write it).
// OpenCASCADE dereferences dangling entities of malformed STEP files
// (SIGSEGV) and Gmsh throws from its OpenMP threads (std::terminate,
// SIGABRT): one line deleted from a valid STEP file was enough. The
// crash is said as an error naming the model, the temporaries go, and the
// exit code is 70 (internal error) rather than a signal's death.
constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};
std::string g_crash[std::size(kCrashSignals)][2];  // before and after what OpenCASCADE said
alignas(16) char g_alt_stack[1 << 16];  // the main thread's stack overflow still runs the handler (not Gmsh's threads')
// A copy of standard error made at the start: while OpenCASCADE reads, fd 2
// is the in-memory file that holds its complaints (geometry.hpp).
int g_stderr = STDERR_FILENO;

void say(int fd, const char* text, size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, text, n);
    if (w <= 0) return;
    text += w, n -= static_cast<size_t>(w);
  }
}

extern "C" void on_crash(int sig) {
  AtomicOutput::remove_uncommitted();
  // OpenCASCADE crashes on files it has just complained about; its words
  // (held back while it reads, geometry.hpp) say what is wrong with them.
  char said[1024];
  const size_t n = cad_reader_said(said, sizeof said);
  const int fd = g_stderr;
  for (size_t i = 0; i < std::size(kCrashSignals); ++i)
    if (kCrashSignals[i] == sig) {
      say(fd, g_crash[i][0].data(), g_crash[i][0].size());
      if (n > 0) {
        static const char open[] = " (OpenCASCADE reported: ", close[] = ")";
        say(fd, open, sizeof open - 1);
        say(fd, said, n);
        say(fd, close, sizeof close - 1);
      }
      say(fd, g_crash[i][1].data(), g_crash[i][1].size());
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
  if (const int copy = ::fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 3); copy >= 0) g_stderr = copy;
  const std::string command = args.empty() ? "" : args[0];
  const std::string cad = cad_of(args);
  const std::string model = cad.empty() ? "the CAD model" : "the CAD model " + printable(cad);
  const char* names[] = {"SIGSEGV (segmentation fault)", "SIGBUS", "SIGILL", "SIGFPE", "SIGABRT (abort)"};
  for (size_t i = 0; i < std::size(kCrashSignals); ++i) {
    g_crash[i][0] = "dicer " + command + ": error: dicer-cad crashed with " + names[i] + " working on " + model;
    g_crash[i][1] = ": OpenCASCADE and Gmsh crash on some malformed STEP and BREP files; check that Gmsh opens it (gmsh " +
                    (cad.empty() ? std::string("MODEL") : printable(cad)) +
                    "). If it does, this is a dicer bug: please report it with the files. No output file was written.\n";
  }
  stack_t ss{};
  ss.ss_sp = g_alt_stack;
  ss.ss_size = sizeof g_alt_stack;
  ::sigaltstack(&ss, nullptr);
  struct sigaction sa {};
  sa.sa_handler = on_crash;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_ONSTACK | SA_RESETHAND;
  for (const int s : kCrashSignals) ::sigaction(s, &sa, nullptr);
  // libstdc++'s own terminate handler prints "terminate called after
  // throwing an instance of ..." before it aborts (Gmsh throws a
  // std::string from its OpenMP threads on some damaged models): a second
  // line before dicer's. The SIGABRT handler says the crash.
  std::set_terminate([] { std::abort(); });
}

// Gmsh and OpenCASCADE calls that do not end (OpenCASCADE's BREP reader on
// some truncated files, Gmsh's meshing of some damaged models) cannot be
// stopped from inside: the library times them (geometry.hpp,
// cad_claim_overdue) and this thread ends the process when one runs past
// its limit, with one error naming the file (exit 3 for a read, 7 for
// meshing), the temporaries gone.
void watch_cad_calls(const std::string& command) {
  std::thread([command] {
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      std::string message;
      ErrorKind kind = ErrorKind::Geometry;  // set by a claim before it allocates
      try {
        if (!cad_claim_overdue(message, kind)) continue;
      } catch (...) {  // out of memory for the words: the exit code still says it
        message = "a Gmsh or OpenCASCADE call ran past its time limit";
      }
      AtomicOutput::remove_uncommitted();
      const std::string m = "dicer " + command + ": error: " + printable(message) + ". No output file was written.\n";
      say(g_stderr, m.data(), m.size());
      ::_exit(exit_code(kind, 0));
    }
  }).detach();
}

}  // namespace

// dicer-cad is where a handed-over command lands: the mark that dicer set
// (cad/without.cpp) stops here, so no program dicer-cad starts inherits it.
void hand_over_if_cad(char**, const std::vector<std::string>& args) {
  ::unsetenv("DICER_CAD_HANDED_OVER");
  say_crashes_as_errors(args);
  if (!cad_of(args).empty()) watch_cad_calls(args[0]);
}

}  // namespace dicer::cli
