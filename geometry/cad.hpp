#pragma once
// The CAD model behind geometry-conforming dicing, read by Gmsh's
// OpenCASCADE kernel through the Gmsh C++ API. Private to geometry/: the
// rest of dicer never sees Gmsh, and a diced store is read without it.
//
// Gmsh keeps one global state per process, so one Cad lives at a time (a
// second one waits on a process-wide mutex) and every call is serialised.
// Loading runs OpenCASCADE's import and then removeAllDuplicates(), so a
// STEP assembly whose solids repeat their shared faces becomes conformal
// (entity tags change; owners are matched geometrically, never by tag alone).
#include <array>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <functional>

#include "dicer/error.hpp"
#include "dicer/types.hpp"

namespace dicer::geometry {

struct CadEntity {
  int dim = 0, tag = 0;
  std::string type;                  // Gmsh's name: "Line", "Plane", "Circle", "Cylinder", "BSpline surface", ...
  std::array<double, 6> box{};       // xmin, ymin, zmin, xmax, ymax, zmax
  bool flat = false;                 // a line or a plane: interpolation is already on it
  std::array<double, 2> pmin{}, pmax{};  // parameter bounds (dim 1: [0] only)
  std::array<bool, 2> periodic{};    // closed in that parameter (a circle, a cylinder's u)
  std::vector<int> up;               // tags of the dim+1 entities bounded by this one
};

class Cad {
 public:
  // Throws Error{Io} when the file cannot be read, Error{Geometry} when it
  // holds no curve or surface, Error{Unsupported} for a format that is not
  // STEP (.step, .stp) or BREP (.brep, .brp).
  explicit Cad(const std::string& path);
  ~Cad();
  Cad(const Cad&) = delete;
  Cad& operator=(const Cad&) = delete;

  const std::string& path() const { return path_; }
  const std::vector<CadEntity>& entities(int dim) const { return ents_[dim]; }
  const CadEntity* find(int dim, int tag) const;
  double diagonal() const { return diag_; }

  // Batched kernel calls: xyz and params are concatenated (3 per point; 1 or
  // 2 per parameter). Each throws Error{Geometry} naming the entity on a
  // kernel failure.
  void closest(int dim, int tag, const std::vector<double>& xyz, std::vector<double>& on,
               std::vector<double>& params) const;
  void param(int dim, int tag, const std::vector<double>& xyz, std::vector<double>& params) const;
  void value(int dim, int tag, const std::vector<double>& params, std::vector<double>& xyz) const;
  // |d x / d param| per point (dim 1: 1 per point, dim 2: 2 per point).
  void speed(int dim, int tag, const std::vector<double>& params, std::vector<double>& out) const;

  // Whether the global Gmsh state has ever been initialised in this process
  // (tests check that reading a store never does it).
  static bool gmsh_initialised();

  // What OpenCASCADE printed reading the file, cleaned to one line
  // (clean_reader_text): empty for a sound file. Its complaints mean the
  // model may be missing parts ("Unresolved Reference: Fails Count: 1").
  const std::string& reader_said() const { return said_; }
  // Runs fn; an error about the model (Geometry, BadInput, Unsupported)
  // gains reader_said(), as a damaged STEP file reads with parts missing
  // and the error that follows ("no solid", "holds no curve or surface")
  // rarely says why. Others (Io, Usage, Cancelled) are not about the file.
  template <class F>
  decltype(auto) with_reader_said(F&& fn) const {
    try {
      return fn();
    } catch (const Error& e) {
      const bool about_model =
          e.kind() == ErrorKind::Geometry || e.kind() == ErrorKind::BadInput || e.kind() == ErrorKind::Unsupported;
      if (!about_model || said_.empty() || std::string(e.what()).find(said_) != std::string::npos) throw;
      throw Error(e.kind(), std::string(e.what()) + " (reading " + path_ + ", OpenCASCADE reported: " + said_ + ")");
    }
  }

 private:
  void load_entities();
  std::string path_, model_, said_;
  std::array<std::vector<CadEntity>, 4> ents_;
  double diag_ = 0;
  std::unique_lock<std::recursive_mutex> lock_;
};

// Calls Gmsh and turns its errors (exceptions, logged errors) into
// Error{kind, context + ": " + Gmsh's last message}.
void gmsh_call(ErrorKind kind, const std::string& context, const std::function<void()>& fn);

// Whether imported shapes need OpenCASCADE's fragment (removeAllDuplicates):
// more than one shape of the highest dimension.
bool needs_fragment(const std::vector<std::pair<int, int>>& shapes);

// Process-wide Gmsh start (idempotent, quiet: General.Terminal 0).
void gmsh_start();

// OpenCASCADE's output as one line of a message: ANSI escapes dropped,
// its lines joined by "; ", the asterisks framing them and runs of blanks
// removed, " : " as ": ", other control bytes as '?'. Writes at most cap - 1 bytes and a NUL; returns
// the length. Async-signal-safe.
size_t clean_reader_text(const char* in, size_t n, char* out, size_t cap) noexcept;

// A Gmsh or OpenCASCADE call that may run for ever on a damaged model,
// for dicer-cad's watchdog (cad_claim_overdue, geometry.hpp): set up before
// the call, with its limit in seconds and its words ("X: OpenCASCADE did
// not finish reading the CAD file", how the limit was set, what to do).
// One at a time, in the thread that calls Gmsh. Timed in the process's CPU
// time. If the watchdog claims it, the destructor never returns (the
// watchdog ends the process).
class TimedCall {
 public:
  TimedCall(ErrorKind kind, double limit, std::string what, std::string how, std::string advice);
  ~TimedCall();
  TimedCall(const TimedCall&) = delete;
  TimedCall& operator=(const TimedCall&) = delete;
};
// A TimedCall's limit: the environment variable's value (seconds) when
// set, else computed by formula; how says which, for the message ("limit
// 30 s: 30 s + 60 s per MiB of the file; DICER_CAD_READ_SECONDS sets it",
// "limit 2 s, from DICER_CAD_MESH_SECONDS"). Error{Usage} for a value that
// is not a positive number.
struct TimeLimit {
  double seconds;
  std::string how;
};
TimeLimit time_limit(const char* variable, double computed, const std::string& formula);

// A number in messages: 3 significant digits.
std::string fmt(double x);

}  // namespace dicer::geometry
