// Gmsh (OpenCASCADE) behind a small batched interface.
#include "cad.hpp"

#include <gmsh.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
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
// Standard output goes to stderr for the life of this object (fd level: the
// kernel's own printf/cout included). Single-threaded use: dicer-cad prints
// nothing else meanwhile.
class StdoutToStderr {
 public:
  StdoutToStderr() {
    std::fflush(stdout);
    saved_ = ::dup(STDOUT_FILENO);
    if (saved_ >= 0) ::dup2(STDERR_FILENO, STDOUT_FILENO);
  }
  ~StdoutToStderr() {
    if (saved_ < 0) return;
    std::fflush(stdout);
    std::cout.flush();
    ::dup2(saved_, STDOUT_FILENO);
    ::close(saved_);
  }
  StdoutToStderr(const StdoutToStderr&) = delete;
  StdoutToStderr& operator=(const StdoutToStderr&) = delete;

 private:
  int saved_ = -1;
};
}  // namespace

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
  gmsh_call(ErrorKind::BadInput, path + ": OpenCASCADE cannot read the CAD file", [&] {
    gmsh::model::add(model_);
    gmsh::vectorpair out;
    // OpenCASCADE's STEP reader prints its complaints ("**** ERR StepFile")
    // to standard output, where --json's document goes: onto stderr.
    const StdoutToStderr occ_talks_to_stderr;
    gmsh::model::occ::importShapes(path, out, /*highestDimOnly=*/false);
    if (needs_fragment(out)) gmsh::model::occ::removeAllDuplicates();
    gmsh::model::occ::synchronize();
  });
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
#endif
