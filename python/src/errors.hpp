#pragma once
// dicer::Error -> dicer.Error subclasses, and Ctrl-C during long calls.
#include <pybind11/pybind11.h>

#include "dicer/error.hpp"

namespace dicer::py_module {

namespace py = pybind11;

// Names and messages are bytes from files and paths, not always UTF-8
// (pybind11's str would raise UnicodeDecodeError, and an exception's
// message would come out empty): text() decodes with U+FFFD for bad bytes,
// as the command line's JSON does; path_text() as os.fsdecode does
// (surrogateescape), so the str opens the same file again.
py::str text(const std::string& s);
py::str path_text(const std::string& s);

// Creates dicer.Error and one subclass per ErrorKind in module m and
// registers the translator (message = what(), the CLI's one line).
void register_errors(py::module_& m);

// Python's signal handlers run only in the main thread with the GIL held,
// so a call that released the GIL would not see Ctrl-C until it ended.
// The library's cancel and progress callbacks call poll() (from the calling
// thread): it takes the GIL, runs the handlers, and remembers what they
// raised (KeyboardInterrupt). The binding then stops the library
// (Error{Cancelled}) and rethrows the remembered exception, so the user
// sees KeyboardInterrupt, as for any other Python call.
class SignalPoll {
 public:
  SignalPoll() = default;
  SignalPoll(const SignalPoll&) = delete;
  SignalPoll& operator=(const SignalPoll&) = delete;
  ~SignalPoll();
  // Called without the GIL. True once a handler raised.
  bool poll();
  bool raised() const { return type_ != nullptr; }
  // With the GIL: throws py::error_already_set with what the handler raised.
  [[noreturn]] void rethrow();

 private:
  PyObject *type_ = nullptr, *value_ = nullptr, *trace_ = nullptr;
};

// py::gil_scoped_release for every call into dicer, except at interpreter
// exit: a daemon thread that retakes the GIL while Python finalises is
// ended by Python with pthread_exit, whose forced unwinding through
// py::gil_scoped_release's (noexcept) destructor aborted the process
// ("terminate called without an active exception"). This destructor lets
// that unwinding through (noexcept(false)), and a thread that sees the
// exit coming waits for it instead, as Python's own daemon threads do.
class ReleaseGil {
 public:
  ReleaseGil() : state_(PyEval_SaveThread()) {}
  ~ReleaseGil() noexcept(false);
  ReleaseGil(const ReleaseGil&) = delete;
  ReleaseGil& operator=(const ReleaseGil&) = delete;

 private:
  PyThreadState* state_;
};

// Runs fn() without the GIL; a KeyboardInterrupt seen by `poll` wins over
// the Error{Cancelled} it provoked.
template <class Fn>
auto without_gil(SignalPoll& poll, Fn&& fn) {
  try {
    ReleaseGil release;
    return fn();
  } catch (const Error& e) {
    if (e.kind() == ErrorKind::Cancelled && poll.raised()) poll.rethrow();
    throw;
  }
}

}  // namespace dicer::py_module
