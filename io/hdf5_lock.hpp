#pragma once
// Debian's HDF5 is the serial, non-thread-safe build. Every HDF5 call in
// the process (the store's page loads, which the cache's read-ahead thread
// makes in the background, and the VTKHDF writer) holds this one lock.
// Recursive, so a writer holding it may call code that takes it again.
// Private to the io layer (io/): the store, the exporters and the Exodus
// reader share it through dicer_io.
#include <mutex>

namespace dicer {
std::recursive_mutex& hdf5_lock();
}  // namespace dicer
