#pragma once
// numpy arrays over dicer's buffers. Two ways, and which one a function uses
// is part of its documented contract:
//  - owned():  the array takes a std::vector over by a capsule, no copy:
//              for data computed for the caller (nodes(), blocks()).
//  - view():   a read-only array over memory another Python object owns
//              (a Chunk, a Partition), which the array keeps alive as its
//              base; read-only because the owner's other arrays index it.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <span>
#include <vector>

namespace dicer::py_module {

namespace py = pybind11;

template <class T>
std::vector<py::ssize_t> c_strides(const std::vector<py::ssize_t>& shape) {
  std::vector<py::ssize_t> s(shape.size());
  py::ssize_t step = sizeof(T);
  for (size_t d = shape.size(); d-- > 0;) {
    s[d] = step;
    step *= shape[d];
  }
  return s;
}

template <class T>
py::array owned(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  auto* holder = new std::vector<T>(std::move(v));
  py::capsule base(holder, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  const auto strides = c_strides<T>(shape);
  return py::array(py::dtype::of<T>(), std::move(shape), strides, holder->data(), base);
}

template <class T>
py::array owned(std::vector<T>&& v) {
  const auto n = static_cast<py::ssize_t>(v.size());
  return owned(std::move(v), {n});
}

template <class T>
py::array view(std::span<const T> s, std::vector<py::ssize_t> shape, py::handle base) {
  const auto strides = c_strides<T>(shape);
  // A null pointer would make numpy allocate; an empty array needs none.
  static const T empty{};
  py::array a(py::dtype::of<T>(), std::move(shape), strides, s.empty() ? &empty : s.data(), base);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

template <class T>
py::array view(std::span<const T> s, py::handle base) {
  return view(s, {static_cast<py::ssize_t>(s.size())}, base);
}

// x, y, z (structure of arrays, as dicer keeps them) -> one (n, 3) array.
inline std::vector<double> interleave(std::span<const double> x, std::span<const double> y, std::span<const double> z) {
  std::vector<double> out(3 * x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    out[3 * i] = x[i];
    out[3 * i + 1] = y[i];
    out[3 * i + 2] = z[i];
  }
  return out;
}

}  // namespace dicer::py_module
