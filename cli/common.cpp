#include "common.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <limits>
#include <tuple>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/intervals.hpp"

namespace dicer::cli {

namespace {
dicer::mpi::Session* g_session = nullptr;
}  // namespace

dicer::mpi::Session& session() {
  if (!g_session) throw std::logic_error("no MPI session (main sets one)");
  return *g_session;
}
void set_session(dicer::mpi::Session* s) { g_session = s; }

void agree(const std::function<void()>& fn) {
  dicer::mpi::Session& s = session();
  if (!s.active()) return fn();
  dicer::mpi::collectively(s.comm(), fn);
}

int on_rank0(const std::function<int()>& fn) {
  dicer::mpi::Session& s = session();
  if (!s.active()) return fn();
  int code = 0;
  dicer::mpi::collectively(s.comm(), [&] {
    if (s.rank() == 0) code = fn();
  });
  MPI_Bcast(&code, 1, MPI_INT, 0, s.comm());
  return code;
}

void check_same_store(const std::string& path, const std::string& uuid) {
  dicer::mpi::Session& s = session();
  if (s.active()) dicer::mpi::require_same_store(s.comm(), path, uuid);
}

std::vector<std::string> options_part(const std::vector<std::string>& args) {
  return {args.begin(), std::find(args.begin(), args.end(), std::string("--"))};
}

std::int64_t parse_int(const std::string& what, const std::string& text) { return parse_whole(what, text); }

double parse_double(const std::string& what, const std::string& text) { return parse_real(what, text); }

std::pair<std::int64_t, std::int64_t> parse_range(const std::string& what, const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) {
    const auto a = parse_int(what, text);
    if (a == std::numeric_limits<std::int64_t>::max())  // a + 1 would overflow; no mesh has that id
      throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is out of range");
    return {a, a + 1};
  }
  const auto a = parse_int(what, text.substr(0, colon)), b = parse_int(what, text.substr(colon + 1));
  if (a < 0 || b < a) throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a range FIRST:END with 0 <= FIRST <= END");
  return {a, b};
}

namespace {

const char* file_kind(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO (named pipe)";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  return "a special file";
}

}  // namespace

void check_input_file(const std::string& path, const std::string& role) {
  if (path.empty()) throw Error(ErrorKind::Usage, role + ": the file name is empty");
  // stat, never open: opening a FIFO without a writer blocks for ever.
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    throw Error(ErrorKind::Io, path + ": cannot open: " + std::strerror(err));
  }
  if (!S_ISREG(st.st_mode))
    throw Error(ErrorKind::Usage, path + ": " + role + " is " + file_kind(st.st_mode) + ", not a regular file");
}

void check_output_file(const std::string& path, const std::string& role,
                       const std::vector<std::pair<std::string, std::string>>& inputs) {
  // Not standard output: an HDF5 or netCDF file needs seeking, and every
  // output appears whole under its name (written to a temporary, renamed).
  if (path == "-")
    throw Error(ErrorKind::Usage, role + " -: dicer does not write to standard output; give a file name (./- for a file named \"-\")");
  if (path.empty()) throw Error(ErrorKind::Usage, role + ": the file name is empty");
  struct stat out {};
  if (::stat(path.c_str(), &out) != 0) return;  // a new file (or a dangling link): nothing to protect
  if (S_ISDIR(out.st_mode))
    throw Error(ErrorKind::Usage, path + ": " + role + " is a directory; give the name of the file to write");
  if (!S_ISREG(out.st_mode))
    throw Error(ErrorKind::Usage, path + ": " + role + " is " + file_kind(out.st_mode) +
                                      "; dicer writes a temporary file and renames it over the output");
  for (const auto& [in, in_role] : inputs) {
    struct stat st {};
    if (::stat(in.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
      throw Error(ErrorKind::Usage, path + ": " + role + " is the same file as " + in_role + " (" + in +
                                        "); writing it would destroy the input");
  }
}

namespace {

// Atomic, not volatile sig_atomic_t: the library polls it from its worker
// threads too; lock-free makes the store async-signal-safe.
std::atomic<int> g_signal{0};
static_assert(std::atomic<int>::is_always_lock_free);
extern "C" void record_signal(int sig) { g_signal.store(sig); }
constexpr int kCancelSignals[] = {SIGINT, SIGTERM, SIGHUP};
struct sigaction g_previous[std::size(kCancelSignals)];
bool g_installed[std::size(kCancelSignals)] = {};

const char* signal_name(int sig) {
  switch (sig) {
    case SIGINT: return "SIGINT (Ctrl-C)";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    default: return "a signal";
  }
}

}  // namespace

void ignore_file_size_signal() {
  // The default action of SIGXFSZ kills without unwinding, so the temporary
  // would stay; ignored, the write fails with EFBIG and is reported.
  struct sigaction sa {};
  sa.sa_handler = SIG_IGN;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGXFSZ, &sa, nullptr);
}

CancelOnSignals::CancelOnSignals() {
  ignore_file_size_signal();
  g_signal.store(0);
  struct sigaction sa {};
  sa.sa_handler = record_signal;
  sigemptyset(&sa.sa_mask);
  // SA_RESETHAND: a second Ctrl-C gets the default action and ends the
  // process at once, should the work not reach a polling point.
  sa.sa_flags = SA_RESTART | SA_RESETHAND;
  for (size_t i = 0; i < std::size(kCancelSignals); ++i) {
    struct sigaction old {};
    ::sigaction(kCancelSignals[i], nullptr, &old);
    // Under nohup (SIGHUP ignored) a hang-up must not stop the work either.
    if (old.sa_handler == SIG_IGN) continue;
    g_installed[i] = ::sigaction(kCancelSignals[i], &sa, &g_previous[i]) == 0;
  }
}

CancelOnSignals::~CancelOnSignals() {
  for (size_t i = 0; i < std::size(kCancelSignals); ++i)
    if (g_installed[i]) ::sigaction(kCancelSignals[i], &g_previous[i], nullptr), g_installed[i] = false;
}

bool cancel_requested() { return g_signal.load() != 0; }
int received_signal() { return g_signal.load(); }

void throw_if_cancelled(const std::string& outcome) {
  if (const int sig = g_signal.load(); sig != 0)
    throw Error(ErrorKind::Cancelled, std::string("interrupted by ") + signal_name(sig) + "; " + outcome);
}

void print_cache_stats(const FineMesh& mesh, const std::string& name) {
  const auto cache = store_cache(mesh);
  if (!cache) return;
  // Under mpirun every rank prints its own cache's lines: say whose.
  std::string command = name;
  if (g_session && g_session->active() && g_session->size() > 1)
    command += " (rank " + std::to_string(g_session->rank()) + " of " + std::to_string(g_session->size()) + ")";
  const CacheStats st = cache->stats();
  const double amplification =
      st.distinct_pages_read ? static_cast<double>(st.pages_read) / static_cast<double>(st.distinct_pages_read) : 0.0;
  std::fprintf(stderr,
               "dicer %s: cache: %llu pages read (%llu distinct, %.2fx), %s read from file, %s decompressed, %llu hits, "
               "%llu misses, %llu evictions, peak resident %s of %s budget (%s kept resident)\n",
               command.c_str(), static_cast<unsigned long long>(st.pages_read),
               static_cast<unsigned long long>(st.distinct_pages_read), amplification, human_bytes(st.bytes_read).c_str(),
               human_bytes(st.bytes_decompressed).c_str(), static_cast<unsigned long long>(st.hits),
               static_cast<unsigned long long>(st.misses), static_cast<unsigned long long>(st.evictions),
               human_bytes(st.peak_resident_bytes).c_str(), human_bytes(cache->budget()).c_str(),
               human_bytes(st.kept_bytes).c_str());
  if (st.load_ns > 0 || st.load_wait_ns > 0) {
    const auto calls = std::max<std::uint64_t>(1, st.pages_read);
    std::fprintf(stderr,
                 "dicer %s: page loads: %s in the loader (%s a page), %s of it by pins that missed, %s "
                 "waiting for pages in flight (threads summed)\n",
                 command.c_str(), human_duration(st.load_ns).c_str(), human_duration(st.load_ns / calls).c_str(),
                 human_duration(st.demand_load_ns).c_str(), human_duration(st.load_wait_ns).c_str());
  }
  // The tables a query reads by element: how much of each it touched (a
  // box query reads the pages of the groups its box meets).
  const MeshTables& t = mesh.tables();
  std::string per;
  for (const auto& [name, pages, array] :
       {std::tuple{"elements", t.elements.pages(), t.elements.array()},
        std::tuple{"element_corners", t.corners.pages(), t.corners.array()},
        std::tuple{"element_bounds", t.bounds.pages(), t.bounds.array()}}) {
    if (pages <= 0) continue;
    const auto read = cache->distinct_pages_read(array);
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s%s %llu of %lld pages (%.2f%%)", per.empty() ? "" : ", ", name,
                  static_cast<unsigned long long>(read), static_cast<long long>(pages),
                  100.0 * static_cast<double>(read) / static_cast<double>(pages));
    per += buf;
  }
  if (!per.empty()) std::fprintf(stderr, "dicer %s: distinct pages read: %s\n", command.c_str(), per.c_str());
}

std::int64_t parse_threads(const std::string& text) {
  const std::int64_t t = parse_int("--threads", text);
  if (t < 1 || t > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  return t;
}

std::string printable(const std::string& name) {
  std::string out;
  auto hex = [&](const char* form, unsigned v) {
    char buf[8];
    std::snprintf(buf, sizeof buf, form, v);
    out += buf;
  };
  const auto* s = reinterpret_cast<const unsigned char*>(name.data());
  const size_t n = name.size();
  for (size_t i = 0; i < n;) {
    const unsigned c = s[i];
    if (c < 0x80) {
      if (c == '\n') out += "\\n";
      else if (c == '\t') out += "\\t";
      else if (c < 0x20 || c == 0x7f) hex("\\x%02x", c);
      else out += static_cast<char>(c);
      ++i;
      continue;
    }
    // A well-formed UTF-8 sequence (RFC 3629: no overlong forms, no
    // surrogates, nothing past U+10FFFF) is kept, a C1 control excepted;
    // any other byte is shown as \xHH, so no byte reaches the terminal
    // that it could take for an escape sequence.
    const int len = c >= 0xc2 && c <= 0xdf ? 2 : c >= 0xe0 && c <= 0xef ? 3 : c >= 0xf0 && c <= 0xf4 ? 4 : 0;
    bool ok = len > 0 && i + static_cast<size_t>(len) <= n;
    for (int k = 1; ok && k < len; ++k) ok = (s[i + k] & 0xc0) == 0x80;
    if (ok && len >= 3) {
      const unsigned b = s[i + 1];
      ok = !(c == 0xe0 && b < 0xa0) && !(c == 0xed && b > 0x9f) && !(c == 0xf0 && b < 0x90) && !(c == 0xf4 && b > 0x8f);
    }
    if (!ok) {
      hex("\\x%02x", c);
      ++i;
    } else if (c == 0xc2 && s[i + 1] < 0xa0) {
      hex("\\u%04x", s[i + 1]);
      i += 2;
    } else {
      out.append(name, i, static_cast<size_t>(len));
      i += static_cast<size_t>(len);
    }
  }
  return out;
}

void warn_cad_reader(const std::string& command, const std::string& cad, const std::string& said) {
  if (said.empty()) return;
  std::fprintf(stderr,
               "dicer %s: warning: %s: OpenCASCADE reported problems reading it: %s; the model may be missing parts "
               "(check it in Gmsh)\n",
               command.c_str(), printable(cad).c_str(), printable(said).c_str());
}

std::string human_bytes(std::uint64_t b) {
  const char* unit[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
  double v = static_cast<double>(b);
  int u = 0;
  while (v >= 1024 && u < 5) v /= 1024, ++u;
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, unit[u]);
  return buf;
}

std::string human_count(std::int64_t n) {
  const char* unit[] = {"", "k", "M", "G", "T"};
  double v = static_cast<double>(n);
  int u = 0;
  while (std::fabs(v) >= 1000 && u < 4) v /= 1000, ++u;
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f%s" : "%.2f%s", v, unit[u]);
  return buf;
}

std::string human_duration(std::uint64_t ns) {
  const double v = static_cast<double>(ns);
  char buf[32];
  if (v < 1e3) std::snprintf(buf, sizeof buf, "%.0f ns", v);
  else if (v < 1e6) std::snprintf(buf, sizeof buf, "%.1f us", v / 1e3);
  else if (v < 1e9) std::snprintf(buf, sizeof buf, "%.1f ms", v / 1e6);
  else std::snprintf(buf, sizeof buf, "%.2f s", v / 1e9);
  return buf;
}

static double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

Progress::Progress(std::string label, std::int64_t total, bool quiet)
    : label_(std::move(label)), total_(total), enabled_(!quiet && ::isatty(2)), start_(now_s()) {}

Progress::~Progress() {
  if (enabled_ && last_ >= 0) std::fprintf(stderr, "\r\033[K");
}

void Progress::update(std::int64_t done) {
  if (!enabled_) return;
  const double t = now_s();
  if (last_ >= 0 && t - last_ < 0.1 && done < total_) return;
  last_ = t;
  const double frac = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int width = 30, fill = static_cast<int>(frac * width);
  const double el = t - start_, rate = el > 0 ? static_cast<double>(done) / el : 0;
  const double left = rate > 0 ? static_cast<double>(total_ - done) / rate : 0;
  std::fprintf(stderr, "\r%s [%.*s%*s] %5.1f%%  %s/s  %.0fs left\033[K", label_.c_str(), fill,
               "##############################", width - fill, "", 100 * frac, human_count(static_cast<std::int64_t>(rate)).c_str(), left);
  std::fflush(stderr);
}

}  // namespace dicer::cli
