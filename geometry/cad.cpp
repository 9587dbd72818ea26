// Gmsh (OpenCASCADE) behind a small batched interface.
#include "cad.hpp"
#include "dicer/geometry.hpp"

#include <gmsh.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace dicer::geometry {
namespace {

std::recursive_mutex& gmsh_mutex() {
  static std::recursive_mutex m;
  return m;
}
std::atomic<bool> g_started{false};

std::string lower_ext(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

}  // namespace

bool needs_fragment(const std::vector<std::pair<int, int>>& shapes) {
  // Several solids (or shells) may repeat their shared faces; fragmenting
  // makes them conformal. OpenCASCADE fails to fragment a lone shape.
  int top = -1, count = 0;
  for (const auto& [d, t] : shapes) top = std::max(top, d);
  for (const auto& [d, t] : shapes) count += d == top;
  return count > 1;
}

void gmsh_start() {
  std::lock_guard lock(gmsh_mutex());
  if (g_started) return;
  gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
  gmsh::option::setNumber("General.Terminal", 0);  // errors come back as exceptions + getLastError
  gmsh::option::setNumber("General.AbortOnError", 2);
  g_started = true;
}

bool Cad::gmsh_initialised() { return g_started; }

std::string fmt(double x) {
  std::ostringstream s;
  s.precision(3);
  s << x;
  return s.str();
}

void gmsh_call(ErrorKind kind, const std::string& context, const std::function<void()>& fn) {
  std::lock_guard lock(gmsh_mutex());
  std::string why;
  try {
    fn();
    return;
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is said as such (exit 70), not as Gmsh failing
  } catch (const std::exception& e) {
    why = e.what();
  } catch (...) {
  }
  std::string last;
  try {
    gmsh::logger::getLastError(last);
  } catch (...) {
  }
  if (!last.empty()) why = last;
  if (why.empty()) why = "Gmsh failed";
  throw Error(kind, context + ": " + why);
}

namespace {

// What OpenCASCADE prints while it reads a CAD file. Its readers write
// their complaints ("**** ERR StepFile : Undefined Parsing: Line 83: ...",
// in ANSI colours) straight to the standard streams, not through Gmsh's
// logger: they came before dicer's message, coloured, and the error itself
// said only Gmsh's "Could not read file". A damaged STEP file often reads
// "successfully" with parts missing, and only those lines said so. So both
// streams go to an anonymous in-memory file (memfd) while OpenCASCADE
// reads, and what it said becomes part of dicer's messages. The crash
// handler of dicer-cad reads the same file (cad_reader_said), as
// OpenCASCADE crashes on some of the files it complains about.
std::atomic<int> g_capture_fd{-1};   // the memfd while a read runs
char g_last_said[1024];              // the last read's text, for a later crash
std::atomic<size_t> g_last_said_size{0};
// The timed call under way (TimedCall): the process's CPU time at its
// start, 0 when none, kClaimed once a watchdog has ended it
// (cad_claim_overdue); its limit; what it is, written before its start is
// stored and read by the watchdog only after it claimed the call, which
// then never returns. CPU time, not wall time: a call that loops spends
// it, while a process stopped (Ctrl-Z) or starved on a busy machine does
// not, and is not taken for one that loops.
std::atomic<std::int64_t> g_call_started_ns{0};
std::atomic<double> g_call_limit{0};
constexpr std::int64_t kClaimed = -1;
struct CallInWords {
  ErrorKind kind = ErrorKind::BadInput;
  std::string what, how, advice;
} g_call;
static_assert(std::atomic<std::int64_t>::is_always_lock_free);

std::int64_t cpu_ns() {
  timespec t{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000 + t.tv_nsec;
}

void flush_streams() {
  std::cout.flush();
  std::cerr.flush();
  std::fflush(stdout);
  std::fflush(stderr);
}

std::string seconds_text(double s) {  // "7200 s", "2.5 s"
  char b[48];
  std::snprintf(b, sizeof b, s >= 10 ? "%.0f s" : "%.3g s", s);
  return b;
}

}  // namespace

TimeLimit time_limit(const char* variable, double computed, const std::string& formula) {
  const char* e = std::getenv(variable);
  if (!e || !*e)
    return {computed, "limit " + seconds_text(computed) + ": " + formula + "; " + variable + " sets it"};
  char* end = nullptr;
  const double v = std::strtod(e, &end);
  if (end == e || *end != '\0' || !(v > 0) || !std::isfinite(v))
    throw Error(ErrorKind::Usage, std::string(variable) + "=" + e + ": not a positive number of seconds");
  return {v, "limit " + seconds_text(v) + ", from " + variable};
}

TimedCall::TimedCall(ErrorKind kind, double limit, std::string what, std::string how, std::string advice) {
  DICER_ASSERT(g_call_started_ns.load() == 0, "one timed Gmsh call at a time");
  g_call.kind = kind;
  g_call.what = std::move(what), g_call.how = std::move(how), g_call.advice = std::move(advice);
  g_call_limit.store(limit);
  g_call_started_ns.store(std::max<std::int64_t>(1, cpu_ns()));
}

TimedCall::~TimedCall() {
  // A call the watchdog has claimed waits for the process to end, so that
  // nothing is written after the watchdog said nothing was.
  if (g_call_started_ns.exchange(0) == kClaimed)
    for (;;) ::pause();
}

namespace {

class ReaderOutput {
 public:
  ReaderOutput() : raw_(64 << 10, '\0'), said_(2048, '\0') {  // allocated before the streams move
    flush_streams();
    fd_ = ::memfd_create("dicer-opencascade-output", MFD_CLOEXEC);
    out_ = ::fcntl(STDOUT_FILENO, F_DUPFD_CLOEXEC, 0);
    err_ = ::fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 0);
    if (fd_ < 0 || out_ < 0 || err_ < 0) {
      // Nothing captured; standard output still must not take OpenCASCADE's
      // lines (--json's document goes there).
      if (out_ >= 0) ::dup2(STDERR_FILENO, STDOUT_FILENO);
      return;
    }
    g_capture_fd.store(fd_);
    ::dup2(fd_, STDOUT_FILENO);
    ::dup2(fd_, STDERR_FILENO);
  }
  // Restores the streams; returns what was said, cleaned (one line).
  std::string finish() {
    if (done_) return {};
    done_ = true;
    flush_streams();
    if (out_ >= 0) ::dup2(out_, STDOUT_FILENO), ::close(out_);
    if (err_ >= 0) ::dup2(err_, STDERR_FILENO), ::close(err_);
    g_capture_fd.store(-1);
    if (fd_ < 0) return {};
    // The first 64 KiB say what went wrong; no allocation until fd_ is closed.
    const ssize_t n = ::pread(fd_, raw_.data(), raw_.size(), 0);
    ::close(fd_);
    fd_ = -1;
    said_.resize(clean_reader_text(raw_.data(), n > 0 ? static_cast<size_t>(n) : 0, said_.data(), said_.size()));
    const size_t keep = std::min(said_.size(), sizeof g_last_said);
    std::memcpy(g_last_said, said_.data(), keep);
    g_last_said_size.store(keep);
    return said_;
  }
  ~ReaderOutput() {
    try {
      finish();
    } catch (...) {
    }
  }
  ReaderOutput(const ReaderOutput&) = delete;
  ReaderOutput& operator=(const ReaderOutput&) = delete;

 private:
  std::string raw_, said_;
  int fd_ = -1, out_ = -1, err_ = -1;
  bool done_ = false;
};

}  // namespace

size_t clean_reader_text(const char* in, size_t n, char* out, size_t cap) noexcept {
  // Async-signal-safe (the crash handler calls it): plain loops, no
  // allocation. Lines are joined by "; ", ANSI escapes dropped, the
  // asterisks OpenCASCADE frames its lines with and runs of blanks
  // removed, " : " written ": ".
  if (cap == 0) return 0;
  size_t o = 0, line_start = 0;
  const size_t room = cap - 1;
  auto trim_line = [&] {  // a line starts with neither, so it never empties
    while (o > line_start && (out[o - 1] == ' ' || out[o - 1] == '*')) --o;
  };
  bool at_line_start = true;
  for (size_t i = 0; i < n && o < room; ++i) {
    unsigned char c = static_cast<unsigned char>(in[i]);
    if (c == 0x1b) {  // ESC [ parameters final, or ESC and one byte
      if (i + 1 < n && in[i + 1] == '[') {
        i += 2;
        while (i < n && !(static_cast<unsigned char>(in[i]) >= 0x40 && static_cast<unsigned char>(in[i]) <= 0x7e)) ++i;
      } else {
        ++i;
      }
      continue;
    }
    if (c == '\n' || c == '\r') {
      trim_line();
      at_line_start = true;
      continue;
    }
    if (c == '\t') c = ' ';
    if (c < 0x20 || c == 0x7f) c = '?';  // no control byte reaches a terminal
    if (at_line_start) {
      if (c == ' ' || c == '*') continue;
      if (o > 0) {
        if (o + 2 >= room) break;
        out[o++] = ';', out[o++] = ' ';
      }
      line_start = o;
      at_line_start = false;
    }
    if (c == ' ' && o > line_start && out[o - 1] == ' ') continue;
    if (c == ':' && o > line_start && out[o - 1] == ' ') --o;
    out[o++] = static_cast<char>(c);
  }
  if (!at_line_start) trim_line();
  out[o] = '\0';
  return o;
}

}  // namespace dicer::geometry

namespace dicer {

bool cad_claim_overdue(std::string& message, ErrorKind& kind) {
  std::int64_t t0 = geometry::g_call_started_ns.load();
  if (t0 <= 0) return false;
  const double seconds = static_cast<double>(geometry::cpu_ns() - t0) * 1e-9;
  if (seconds <= geometry::g_call_limit.load() || !geometry::g_call_started_ns.compare_exchange_strong(t0, geometry::kClaimed))
    return false;
  const auto& c = geometry::g_call;
  kind = c.kind;  // before anything that allocates
  char said[1024];
  const size_t n = cad_reader_said(said, sizeof said);
  char took[64];
  std::snprintf(took, sizeof took, " in %.1f s of CPU time", seconds);
  message = c.what + took + " (" + c.how + ")" + (n > 0 ? "; reading it, OpenCASCADE reported: " + std::string(said, n) : "") +
            ". " + c.advice;
  return true;
}

size_t cad_reader_said(char* buf, size_t cap) noexcept {
  if (cap == 0) return 0;
  const int fd = geometry::g_capture_fd.load();
  if (fd >= 0) {
    char raw[4096];
    const ssize_t n = ::pread(fd, raw, sizeof raw, 0);
    return geometry::clean_reader_text(raw, n > 0 ? static_cast<size_t>(n) : 0, buf, cap);
  }
  const size_t n = std::min(geometry::g_last_said_size.load(), cap - 1);
  std::memcpy(buf, geometry::g_last_said, n);
  buf[n] = '\0';
  return n;
}

}  // namespace dicer

namespace dicer::geometry {

Cad::Cad(const std::string& path) : path_(path), lock_(gmsh_mutex()) {
  const std::string ext = lower_ext(path);
  if (ext != ".step" && ext != ".stp" && ext != ".brep" && ext != ".brp")
    throw Error(ErrorKind::Unsupported, path + ": CAD format \"" + ext + "\" is not supported (STEP .step/.stp or BREP .brep/.brp)");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe) throw Error(ErrorKind::Io, path + ": cannot open the CAD file");
    char c = 0;
    if (!probe.get(c)) throw Error(ErrorKind::BadInput, path + ": the CAD file is empty");
  }
  gmsh_start();
  static int counter = 0;
  model_ = "dicer_cad_" + std::to_string(++counter);
  g_last_said_size.store(0);
  // OpenCASCADE's BREP reader loops for hours on some truncated files
  // (TopTools_ShapeSet::Read runs up to a shape count it never read, the
  // stream having failed: a 500-byte head of a valid cylinder did, in about
  // half the runs), and nothing stops it from inside. 30 s + 60 s per MiB:
  // a 3.2 MiB STEP file of 800 solids read in 9 s on a busy 2-core VM
  // (0.35 MiB/s), its BREP at 15 MiB/s.
  std::error_code size_error;
  const auto bytes = std::filesystem::file_size(path, size_error);
  const double mib = size_error ? 0.0 : static_cast<double>(bytes) / (1 << 20);
  const TimeLimit limit = time_limit("DICER_CAD_READ_SECONDS", 30.0 + 60.0 * mib, "30 s + 60 s per MiB of the file");
  {
    ReaderOutput talk;
    try {
      gmsh_call(ErrorKind::BadInput, path + ": OpenCASCADE cannot read the CAD file", [&] {
        gmsh::model::add(model_);
        gmsh::vectorpair out;
        {
          const TimedCall timed(ErrorKind::BadInput, limit.seconds, path + ": OpenCASCADE did not finish reading the CAD file", limit.how,
                                "Its readers loop on some truncated or malformed files; check that Gmsh opens it (gmsh " +
                                    path + ")");
          gmsh::model::occ::importShapes(path, out, /*highestDimOnly=*/false);
        }
        if (needs_fragment(out)) gmsh::model::occ::removeAllDuplicates();
        gmsh::model::occ::synchronize();
      });
    } catch (const Error& e) {
      // OpenCASCADE's own words say where ("Line 83: Incorrect syntax");
      // Gmsh's "Could not read file 'X'" only that it failed, and goes.
      said_ = talk.finish();
      if (said_.empty()) throw;
      const std::string context = path + ": OpenCASCADE cannot read the CAD file: ";
      std::string gmsh = e.what();
      if (gmsh.rfind(context, 0) == 0) gmsh.erase(0, context.size());
      if (gmsh.rfind("Could not read file", 0) == 0) gmsh.clear();
      throw Error(e.kind(), context + said_ + (gmsh.empty() ? "" : " (Gmsh: " + gmsh + ")"));
    }
    said_ = talk.finish();
  }
  with_reader_said([&] { load_entities(); });
}

void Cad::load_entities() {
  const std::string& path = path_;
  gmsh_call(ErrorKind::Geometry, path + ": reading the CAD entities", [&] {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (int d = 0; d <= 3; ++d) {
      gmsh::vectorpair tags;
      gmsh::model::getEntities(tags, d);
      for (const auto& [dim, tag] : tags) {
        CadEntity e;
        e.dim = dim, e.tag = tag;
        gmsh::model::getType(dim, tag, e.type);
        auto& b = e.box;
        gmsh::model::getBoundingBox(dim, tag, b[0], b[1], b[2], b[3], b[4], b[5]);
        for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], b[k]), hi[k] = std::max(hi[k], b[3 + k]);
        e.flat = e.type == "Line" || e.type == "Plane";
        if (dim == 1 || dim == 2) {
          std::vector<double> mn, mx;
          gmsh::model::getParametrizationBounds(dim, tag, mn, mx);
          for (int k = 0; k < dim && k < static_cast<int>(mn.size()); ++k) e.pmin[k] = mn[k], e.pmax[k] = mx[k];
        }
        if (dim < 3) {
          std::vector<int> up, down;
          gmsh::model::getAdjacencies(dim, tag, up, down);
          e.up = up;
        }
        ents_[d].push_back(std::move(e));
      }
    }
    if (ents_[1].empty() && ents_[2].empty()) throw Error(ErrorKind::BadInput, path + ": the CAD file holds no curve or surface (not a model, or an empty one)");
    diag_ = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));
  });
  // Degenerate curves (a sphere's poles as a STEP file writes them) have no
  // geometry to project on: dropped, so nothing is ever owned by them.
  {
    auto& curves = ents_[1];
    curves.erase(std::remove_if(curves.begin(), curves.end(),
                                [&](const CadEntity& e) {
                                  std::vector<double> c{0.5 * (e.box[0] + e.box[3]), 0.5 * (e.box[1] + e.box[4]),
                                                        0.5 * (e.box[2] + e.box[5])},
                                      on, par;
                                  try {
                                    closest(1, e.tag, c, on, par);
                                    return false;
                                  } catch (const Error&) {
                                    return true;
                                  }
                                }),
                 curves.end());
  }
  // Periodicity: a parameter is periodic when the entity closes on itself
  // along it (same point at both bounds), e.g. a full circle or the u of a
  // cylinder; interpolation across the seam then unwraps by the period.
  for (int d = 1; d <= 2; ++d)
    for (CadEntity& e : ents_[d])
      for (int k = 0; k < d; ++k) {
        std::vector<double> p, x;
        const double other = d == 2 ? 0.5 * (e.pmin[1 - k] + e.pmax[1 - k]) : 0;
        for (double s : {0.0, 1.0}) {
          const double t = s == 0 ? e.pmin[k] : e.pmax[k];
          if (d == 1) p.push_back(t);
          else if (k == 0) p.push_back(t), p.push_back(other);
          else p.push_back(other), p.push_back(t);
        }
        value(d, e.tag, p, x);
        const double gap = std::hypot(x[0] - x[3], x[1] - x[4], x[2] - x[5]);
        e.periodic[k] = gap <= 1e-9 * std::max(diag_, 1e-300) && e.pmax[k] > e.pmin[k];
      }
}

Cad::~Cad() {
  try {
    gmsh::model::setCurrent(model_);
    gmsh::model::remove();
  } catch (...) {
  }
}

const CadEntity* Cad::find(int dim, int tag) const {
  if (dim < 0 || dim > 3) return nullptr;
  for (const CadEntity& e : ents_[dim])
    if (e.tag == tag) return &e;
  return nullptr;
}

namespace {
std::string name(int dim, int tag) {
  static const char* kind[4] = {"point", "curve", "surface", "volume"};
  return std::string("CAD ") + kind[dim] + " " + std::to_string(tag);
}
}  // namespace

void Cad::closest(int dim, int tag, const std::vector<double>& xyz, std::vector<double>& on,
                  std::vector<double>& params) const {
  if (dim == 0) {
    std::vector<double> p;
    value(0, tag, {}, p);
    on.clear();
    for (size_t i = 0; i < xyz.size() / 3; ++i) on.insert(on.end(), p.begin(), p.begin() + 3);
    params.clear();
    return;
  }
  gmsh_call(ErrorKind::Geometry, path_ + ": closest point on " + name(dim, tag),
            [&] { gmsh::model::getClosestPoint(dim, tag, xyz, on, params); });
  if (on.size() != xyz.size()) throw Error(ErrorKind::Geometry, path_ + ": " + name(dim, tag) + ": projection failed");
}

void Cad::param(int dim, int tag, const std::vector<double>& xyz, std::vector<double>& params) const {
  gmsh_call(ErrorKind::Geometry, path_ + ": parameters on " + name(dim, tag),
            [&] { gmsh::model::getParametrization(dim, tag, xyz, params); });
  if (params.size() != xyz.size() / 3 * static_cast<size_t>(dim))
    throw Error(ErrorKind::Geometry, path_ + ": " + name(dim, tag) + ": parametrization failed");
}

void Cad::value(int dim, int tag, const std::vector<double>& params, std::vector<double>& xyz) const {
  gmsh_call(ErrorKind::Geometry, path_ + ": evaluating " + name(dim, tag),
            [&] { gmsh::model::getValue(dim, tag, params, xyz); });
  const size_t want = dim == 0 ? 3 : params.size() / static_cast<size_t>(dim) * 3;
  if (xyz.size() != want) throw Error(ErrorKind::Geometry, path_ + ": " + name(dim, tag) + ": evaluation failed");
}

void Cad::speed(int dim, int tag, const std::vector<double>& params, std::vector<double>& out) const {
  std::vector<double> d;
  gmsh_call(ErrorKind::Geometry, path_ + ": derivatives on " + name(dim, tag),
            [&] { gmsh::model::getDerivative(dim, tag, params, d); });
  out.clear();
  for (size_t i = 0; i + 2 < d.size(); i += 3) out.push_back(std::hypot(d[i], d[i + 1], d[i + 2]));
}

}  // namespace dicer::geometry

#if defined(__SANITIZE_ADDRESS__)
// Gmsh 4.8 leaks a few hundred bytes per surface it meshes (meshGFace) and
// keeps its global state until exit, and OpenCASCADE's STEP reader and
// writer (libTK*) keep theirs; LeakSanitizer would fail every process that
// used them. Only leaks allocated inside those libraries are suppressed.
extern "C" const char* __lsan_default_suppressions() { return "leak:libgmsh.so\nleak:libTK\n"; }
// Nor print the table of suppressions used at exit: seven lines on stderr
// after dicer's one (OpenCASCADE's STEP reader leaks on a file with a
// syntax error).
extern "C" const char* __lsan_default_options() { return "print_suppressions=0"; }
#endif
