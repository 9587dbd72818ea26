#include "errors.hpp"

#include <chrono>
#include <string>
#include <thread>

#include "dicer/mpi.hpp"

namespace dicer::py_module {
namespace {

struct Kind {
  ErrorKind kind;
  const char* class_name;
  const char* kind_name;
  int exit_code;          // what `dicer` exits with for this kind (cli/exit_codes.cpp)
  PyObject* extra_base;   // a builtin the class also derives from, or null
  const char* doc;
};

PyObject* g_error = nullptr;
PyObject* g_internal = nullptr;
PyObject* g_classes[16] = {};

PyObject* class_for(ErrorKind k) {
  const auto i = static_cast<size_t>(k);
  return i < std::size(g_classes) && g_classes[i] ? g_classes[i] : g_error;
}

void set_class_attr(PyObject* cls, const char* name, py::object value) {
  if (PyObject_SetAttrString(cls, name, value.ptr()) != 0) throw py::error_already_set();
}

}  // namespace

py::str text(const std::string& s) {
  PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "replace");
  if (!o) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

py::str path_text(const std::string& s) {
  PyObject* o = PyUnicode_DecodeFSDefaultAndSize(s.data(), static_cast<Py_ssize_t>(s.size()));
  if (!o) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

void register_errors(py::module_& m) {
  // Builtins mixed in where the kind is one: `except ValueError` catches a
  // bad argument and `except OverflowError` an id overflow. The overflow
  // class is IdOverflowError so that `from dicer import *` does not shadow
  // the builtin OverflowError.
  const Kind kinds[] = {
      {ErrorKind::Usage, "UsageError", "usage", 2, PyExc_ValueError, "A bad argument (the CLI's exit 2)."},
      {ErrorKind::BadInput, "BadInputError", "bad_input", 3, nullptr,
       "A malformed, truncated or inconsistent input file (exit 3)."},
      {ErrorKind::Unsupported, "UnsupportedError", "unsupported", 4, nullptr,
       "A valid file with content dicer cannot dice, or an unknown store version (exit 4)."},
      {ErrorKind::Io, "IoError", "io", 5, nullptr, "The OS or HDF5 failed to read or write; a missing file (exit 5)."},
      {ErrorKind::Overflow, "IdOverflowError", "overflow", 6, PyExc_OverflowError,
       "Fine counts would overflow 64-bit ids (exit 6)."},
      {ErrorKind::Geometry, "GeometryError", "geometry", 7, nullptr,
       "Mesh and CAD do not fit, a projection would invert an element, or Gmsh cannot mesh the CAD as asked (exit 7)."},
      {ErrorKind::Corrupt, "CorruptError", "corrupt", 8, nullptr, "A damaged or inconsistent store (exit 8)."},
      {ErrorKind::Cancelled, "CancelledError", "cancelled", 130, nullptr,
       "The work was cancelled; nothing was written (exit 130 for Ctrl-C)."},
  };
  g_error = PyErr_NewExceptionWithDoc("dicer.Error",
                                      "Every error dicer reports: the library's dicer::Error. `kind` names it, "
                                      "`exit_code` is what the dicer command exits with, str() is the CLI's "
                                      "one-line message.",
                                      PyExc_Exception, nullptr);
  if (!g_error) throw py::error_already_set();
  m.add_object("Error", py::handle(g_error));
  for (const Kind& k : kinds) {
    py::tuple bases = k.extra_base ? py::make_tuple(py::handle(g_error), py::handle(k.extra_base))
                                   : py::make_tuple(py::handle(g_error));
    const std::string qualified = std::string("dicer.") + k.class_name;
    PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), k.doc, bases.ptr(), nullptr);
    if (!cls) throw py::error_already_set();
    set_class_attr(cls, "kind", py::str(k.kind_name));
    set_class_attr(cls, "exit_code", py::int_(k.exit_code));
    g_classes[static_cast<size_t>(k.kind)] = cls;
    m.add_object(k.class_name, py::handle(cls));
  }
  // Not a dicer.Error: a bug in dicer (a failed DICER_ASSERT), not in the input.
  g_internal = PyErr_NewExceptionWithDoc("dicer.InternalError",
                                         "A broken internal invariant: a bug in dicer (the CLI's exit 70).",
                                         PyExc_RuntimeError, nullptr);
  if (!g_internal) throw py::error_already_set();
  set_class_attr(g_internal, "exit_code", py::int_(70));
  m.add_object("InternalError", py::handle(g_internal));

  py::register_exception_translator([](std::exception_ptr p) {
    // PyErr_SetString decodes strictly: a message with a non-UTF-8 path
    // came out empty.
    auto raise = [](PyObject* type, const char* what) { PyErr_SetObject(type, text(what).ptr()); };
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      raise(class_for(e.kind()), e.what());
    } catch (const InternalError& e) {
      raise(g_internal, e.what());
    } catch (const mpi::PeerFailed& e) {
      // Another rank failed in a collective call: the same class as its
      // error, so every rank raises alike ("rank 1 failed").
      raise(class_for(e.kind()), e.what());
    }
  });
}

ReleaseGil::~ReleaseGil() noexcept(false) {
#if PY_VERSION_HEX >= 0x030D0000
  while (Py_IsFinalizing()) std::this_thread::sleep_for(std::chrono::seconds(1));
#else
  while (_Py_IsFinalizing()) std::this_thread::sleep_for(std::chrono::seconds(1));  // its name before 3.13
#endif
  PyEval_RestoreThread(state_);
}

SignalPoll::~SignalPoll() {
  if (type_ || value_ || trace_) {
    py::gil_scoped_acquire gil;
    Py_XDECREF(type_);
    Py_XDECREF(value_);
    Py_XDECREF(trace_);
  }
}

bool SignalPoll::poll() {
  if (raised()) return true;
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() == 0) return false;
  PyErr_Fetch(&type_, &value_, &trace_);
  return true;
}

void SignalPoll::rethrow() {
  PyErr_Restore(type_, value_, trace_);
  type_ = value_ = trace_ = nullptr;
  throw py::error_already_set();
}

}  // namespace dicer::py_module
