#include "hdf5_lock.hpp"

namespace dicer {
std::recursive_mutex& hdf5_lock() {
  static std::recursive_mutex m;
  return m;
}
}  // namespace dicer
