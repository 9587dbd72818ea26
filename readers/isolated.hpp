#pragma once
// Reading a file whose parser dicer does not control in a child process.
// Private to readers/.
//
// netCDF-4 Exodus files are HDF5 files, and HDF5 1.10 parses their metadata
// as it is: dicer checks what it can (attribute and variable shapes) but a
// damaged file may still crash or exhaust memory inside the library. So
// such a file is read in a forked child with an address-space limit; the
// mesh comes back through a pipe. A crash (signal) or an allocation failure
// in the child becomes Error{BadInput} naming the file, never the end of
// the calling process. Cost: one fork and one copy of the coarse mesh
// through a pipe, O(coarse mesh).
//
// DICER_READER_IN_PROCESS=1 reads in process (debuggers, profilers);
// DICER_READER_MEMORY_MB=N limits the child to N MiB of address space
// beyond what it inherits (default: 2 GiB + 64 x the file's size).
#include <cstdint>
#include <functional>
#include <string>

#include "dicer/coarse_mesh.hpp"

namespace dicer {

CoarseMesh read_isolated(const std::string& path, std::int64_t file_size,
                         const std::function<CoarseMesh()>& read);

// The byte stream the child sends (exposed for the round-trip test).
std::string pack_mesh(const CoarseMesh& m);
CoarseMesh unpack_mesh(const std::string& bytes, const std::string& path);

}  // namespace dicer
