#include "common.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <iterator>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"

namespace dicer::cli {

Args::Args(std::string command, std::vector<std::string> argv, std::vector<std::string> value_flags,
           std::vector<std::string> bool_flags, int max_positional)
    : command_(std::move(command)) {
  auto known = [](const std::vector<std::string>& v, const std::string& s) {
    for (const auto& x : v)
      if (x == s) return true;
    return false;
  };
  for (size_t i = 0; i < argv.size(); ++i) {
    std::string a = argv[i];
    if (a.size() > 1 && a[0] == '-' && !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      std::string name = a, val;
      bool has_val = false;
      if (auto eq = a.find('='); eq != std::string::npos) name = a.substr(0, eq), val = a.substr(eq + 1), has_val = true;
      if (known(value_flags, name)) {
        if (!has_val) {
          if (i + 1 >= argv.size())
            throw Error(ErrorKind::Usage, name + " needs a value");
          val = argv[++i];
        }
        values_[name].push_back(val);
      } else if (known(bool_flags, name) && !has_val) {
        values_[name].push_back("");
      } else {
        throw Error(ErrorKind::Usage, "unknown option " + name + " (see dicer " + command_ +
                                          " --help)");
      }
    } else {
      positional_.push_back(a);
    }
  }
  if (static_cast<int>(positional_.size()) > max_positional)
    throw Error(ErrorKind::Usage, "unexpected argument \"" + positional_[max_positional] +
                                      "\" (see dicer " + command_ + " --help)");
}

std::optional<std::string> Args::value(const std::string& flag) const {
  auto it = values_.find(flag);
  if (it == values_.end()) return std::nullopt;
  return it->second.back();
}
std::vector<std::string> Args::values(const std::string& flag) const {
  auto it = values_.find(flag);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}
std::string Args::need_positional(size_t i, const std::string& what) const {
  if (i >= positional_.size())
    throw Error(ErrorKind::Usage, "missing " + what + " (see dicer " + command_ + " --help)");
  return positional_[i];
}
std::int64_t Args::int_value(const std::string& flag, std::int64_t fallback) const {
  auto v = value(flag);
  return v ? parse_int(flag, *v) : fallback;
}

std::int64_t parse_int(const std::string& what, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0') throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a whole number");
  if (errno == ERANGE) throw Error(ErrorKind::Overflow, what + ": \"" + text + "\" does not fit in 64 bits");
  return v;
}

double parse_double(const std::string& what, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a finite number");
  return v;
}

std::pair<std::int64_t, std::int64_t> parse_range(const std::string& what, const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) {
    const auto a = parse_int(what, text);
    return {a, a + 1};
  }
  const auto a = parse_int(what, text.substr(0, colon)), b = parse_int(what, text.substr(colon + 1));
  if (a < 0 || b < a) throw Error(ErrorKind::Usage, what + ": \"" + text + "\" is not a range FIRST:END with 0 <= FIRST <= END");
  return {a, b};
}

IntervalRequest interval_request(const Args& args) {
  IntervalRequest file;
  if (auto p = args.value("--intervals-file")) file = read_interval_file(*p);
  IntervalRequest flags;
  if (auto v = args.value("--interval")) flags.global = parse_int("--interval", *v);
  if (auto v = args.value("--size")) flags.size = parse_double("--size", *v);
  for (const auto& kv : args.values("--block-interval")) {
    const auto eq = kv.rfind('=');
    if (eq == std::string::npos || eq == 0)
      throw Error(ErrorKind::Usage, "--block-interval: \"" + kv + "\" is not BLOCK=N");
    flags.blocks.emplace_back(kv.substr(0, eq), parse_int("--block-interval " + kv, kv.substr(eq + 1)));
  }
  for (const auto& kv : args.values("--sheet-interval")) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) throw Error(ErrorKind::Usage, "--sheet-interval: \"" + kv + "\" is not SHEET=N");
    flags.sheets.emplace_back(parse_int("--sheet-interval " + kv, kv.substr(0, eq)),
                              parse_int("--sheet-interval " + kv, kv.substr(eq + 1)));
  }
  return merge(file, flags);
}

StoreOptions store_options(const Args& args) {
  StoreOptions o;
  if (auto v = args.value("--cache-mb")) {
    const auto mb = parse_int("--cache-mb", *v);
    if (mb < 1 || mb > (1ll << 30)) throw Error(ErrorKind::Usage, "--cache-mb: must be between 1 and 2^30 (MiB)");
    o.cache_bytes = static_cast<std::uint64_t>(mb) << 20;
  }
  if (auto v = args.value("--read-ahead")) {
    const auto n = parse_int("--read-ahead", *v);
    if (n < 0 || n > 1024) throw Error(ErrorKind::Usage, "--read-ahead: must be between 0 and 1024 pages");
    o.read_ahead_pages = static_cast<unsigned>(n);
  }
  return o;
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

CancelOnSignals::CancelOnSignals() {
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

void print_cache_stats(const FineMesh& mesh, const std::string& command) {
  const auto cache = store_cache(mesh);
  if (!cache) return;
  const CacheStats st = cache->stats();
  std::fprintf(stderr,
               "dicer %s: cache: %llu pages read, %s read from file, %s decompressed, %llu hits, %llu misses, %llu "
               "evictions, peak resident %s of %s budget\n",
               command.c_str(), static_cast<unsigned long long>(st.pages_read), human_bytes(st.bytes_read).c_str(),
               human_bytes(st.bytes_decompressed).c_str(), static_cast<unsigned long long>(st.hits),
               static_cast<unsigned long long>(st.misses), static_cast<unsigned long long>(st.evictions),
               human_bytes(st.peak_resident_bytes).c_str(), human_bytes(cache->budget()).c_str());
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
