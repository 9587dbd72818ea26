#pragma once
// numpy arrays over dicer's buffers. Three ways, and which one a function
// uses is part of its documented contract:
//  - owned():  the array takes a std::vector over by a capsule, no copy:
//              for data computed for the caller (nodes(); blocks()' ids and
//              connectivity, the block's own vectors handed over).
//  - Recycler::array(): the caller's array too, its buffer taken from the
//              recycler and given back to it when the array dies: for an
//              iterator that copies each step out of buffers it reuses
//              (batches(); blocks()' interleaved points), so that a loop
//              which drops each step's arrays reuses two buffers instead of
//              asking the allocator anew.
//  - view():   a read-only array over memory another Python object owns
//              (a Chunk, a Partition), which the array keeps alive as its
//              base; read-only because the owner's other arrays index it.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <memory>
#include <span>
#include <utility>
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

// Buffers of T for Recycler::array(): at most kKeep idle ones are kept (the
// memory an iterator holds beyond its live arrays is two steps' worth).
// Why not the allocator alone: glibc gives an array of a step (hundreds of
// KiB) back to the kernel when it dies (munmap, or a trim of the heap's top)
// and the next step's array faults every page in again, zeroed: half the
// time of a Python loop over batches (bench/README.md "Python"). Touched
// only with the GIL held (steps and capsule destructors both hold it).
template <class T>
class Recycler : public std::enable_shared_from_this<Recycler<T>> {
 public:
  static constexpr size_t kKeep = 2;
  // A C-ordered array of `shape`, its values unset (written by the caller
  // at once), whose buffer returns here when the array dies.
  py::array_t<T> array(std::vector<py::ssize_t> shape) {
    size_t n = 1;
    for (py::ssize_t d : shape) n *= static_cast<size_t>(d);
    Buffer b;
    for (size_t i = 0; i < idle_.size(); ++i)
      if (idle_[i].size >= n) {
        b = std::move(idle_[i]);
        idle_.erase(idle_.begin() + static_cast<std::ptrdiff_t>(i));
        break;
      }
    if (!b.data) b = Buffer{std::unique_ptr<T[]>(new T[n > 0 ? n : 1]), n};  // default-initialised: not zeroed
    auto owner = std::make_unique<Held>(Held{this->shared_from_this(), std::move(b)});
    py::capsule base(owner.get(), [](void* p) {
      std::unique_ptr<Held> h(static_cast<Held*>(p));
      h->owner->give_back(std::move(h->buffer));
    });
    Held* held = owner.release();  // the capsule's now (it deletes it even if the array is not made)
    const auto strides = c_strides<T>(shape);
    return py::array_t<T>(std::move(shape), strides, held->buffer.data.get(), base);
  }

 private:
  struct Buffer {
    std::unique_ptr<T[]> data;
    size_t size = 0;
  };
  struct Held {
    std::shared_ptr<Recycler> owner;  // the recycler outlives its arrays
    Buffer buffer;
  };
  void give_back(Buffer&& b) {
    if (idle_.size() < kKeep) idle_.push_back(std::move(b));
  }
  std::vector<Buffer> idle_;
};

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
// Into out (3 x.size() values), which may be a fresh numpy array's buffer.
inline void interleave_into(std::span<const double> x, std::span<const double> y, std::span<const double> z, double* out) {
  for (size_t i = 0; i < x.size(); ++i) {
    out[3 * i] = x[i];
    out[3 * i + 1] = y[i];
    out[3 * i + 2] = z[i];
  }
}
inline std::vector<double> interleave(std::span<const double> x, std::span<const double> y, std::span<const double> z) {
  std::vector<double> out(3 * x.size());
  interleave_into(x, y, z, out.data());
  return out;
}

}  // namespace dicer::py_module
