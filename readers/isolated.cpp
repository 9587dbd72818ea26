// The isolated read (isolated.hpp): fork, read in the child under an
// address-space limit, send the mesh back through a pipe.
#include "isolated.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <new>

#include "dicer/error.hpp"
#include "hdf5_lock.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define DICER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DICER_ASAN 1
#endif
#endif

namespace dicer {
namespace {

// ---- the byte stream: little-endian host order, the same binary on both ends.
struct Packer {
  std::string out;
  void u64(std::uint64_t v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); }
  void str(const std::string& s) {
    u64(s.size());
    out += s;
  }
  template <class T>
  void vec(const std::vector<T>& v) {
    u64(v.size());
    if (!v.empty()) out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
};

struct Unpacker {
  const std::string& in;
  const std::string& path;
  std::size_t at = 0;
  [[noreturn]] void fail() const {
    throw Error(ErrorKind::BadInput, path + ": the isolated reader sent a truncated mesh");
  }
  std::uint64_t u64() {
    std::uint64_t v = 0;
    if (in.size() - at < sizeof v) fail();
    std::memcpy(&v, in.data() + at, sizeof v);
    at += sizeof v;
    return v;
  }
  std::string str() {
    const std::uint64_t n = u64();
    if (n > in.size() - at) fail();
    std::string s = in.substr(at, n);
    at += n;
    return s;
  }
  template <class T>
  std::vector<T> vec() {
    const std::uint64_t n = u64();
    if (n > (in.size() - at) / sizeof(T)) fail();
    std::vector<T> v(n);
    if (n) std::memcpy(v.data(), in.data() + at, n * sizeof(T));  // data() of an empty vector may be null
    at += n * sizeof(T);
    return v;
  }
};

constexpr char kMeshTag = 'M', kErrorTag = 'E';

bool write_all(int fd, const std::string& s) {
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t w = ::write(fd, s.data() + done, s.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    done += static_cast<std::size_t>(w);
  }
  return true;
}

std::string read_all(int fd) {
  std::string s;
  char buf[1 << 16];
  for (;;) {
    const ssize_t r = ::read(fd, buf, sizeof buf);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    s.append(buf, static_cast<std::size_t>(r));
  }
  return s;
}

#if !defined(DICER_ASAN)
// Address space the child already has (inherited mappings), in bytes.
std::uint64_t current_vm_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t pages = 0;
  statm >> pages;
  return pages * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}
#endif

std::uint64_t child_budget(std::int64_t file_size) {
  if (const char* e = std::getenv("DICER_READER_MEMORY_MB"); e && *e) {
    char* end = nullptr;
    const unsigned long long mb = std::strtoull(e, &end, 10);
    if (end && *end == '\0' && mb > 0) return static_cast<std::uint64_t>(mb) << 20;
  }
  return (std::uint64_t{2} << 30) + 64 * static_cast<std::uint64_t>(std::max<std::int64_t>(file_size, 0));
}

[[noreturn]] void child(int fd, std::int64_t file_size, const std::function<CoarseMesh()>& read) {
  hdf5_lock().unlock();  // held by the parent across fork(): this copy is ours alone
  // A crash here is the parent's to report, naming the file: a handler the
  // program installed (dicer-cad's blames the CAD model) is not ours.
  for (const int s : {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT}) ::signal(s, SIG_DFL);
  const struct rlimit no_core = {0, 0};  // a crash here is reported, not dumped
  setrlimit(RLIMIT_CORE, &no_core);
#if !defined(DICER_ASAN)  // ASan's shadow memory cannot live under an address-space limit
  const rlim_t limit = static_cast<rlim_t>(current_vm_bytes() + child_budget(file_size));
  const struct rlimit rl = {limit, limit};
  setrlimit(RLIMIT_AS, &rl);
#else
  (void)file_size;
#endif
  std::string out;
  auto error = [&](ErrorKind kind, const std::string& what) {
    Packer p;
    p.u64(static_cast<std::uint64_t>(kind));
    p.str(what);
    out = std::string(1, kErrorTag) + p.out;
  };
  try {
    const CoarseMesh m = read();
    out = std::string(1, kMeshTag) + pack_mesh(m);
  } catch (const Error& e) {
    error(e.kind(), e.what());
  } catch (const std::bad_alloc&) {
    error(ErrorKind::BadInput, "needs more memory than the reader allows (" +
                                   std::to_string(child_budget(file_size) >> 20) +
                                   " MiB; DICER_READER_MEMORY_MB raises it): sizes that large are damaged, hostile or a mesh too big for that limit");
  } catch (const std::exception& e) {
    error(ErrorKind::BadInput, std::string("the reader failed: ") + e.what());
  }
  _exit(write_all(fd, out) ? 0 : 1);
}

}  // namespace

std::string pack_mesh(const CoarseMesh& m) {
  Packer p;
  p.str(m.source);
  p.u64(m.mode == Mode::Volume ? 0 : 1);
  p.vec(m.x), p.vec(m.y), p.vec(m.z), p.vec(m.vertex_file_id), p.vec(m.conn), p.vec(m.element_file_id);
  p.vec(m.element_block);
  p.u64(m.blocks.size());
  for (const auto& b : m.blocks) p.u64(static_cast<std::uint64_t>(b.id)), p.str(b.name);
  p.u64(m.side_sets.size());
  for (const auto& s : m.side_sets) p.u64(static_cast<std::uint64_t>(s.id)), p.str(s.name), p.vec(s.element), p.vec(s.side);
  p.u64(m.node_sets.size());
  for (const auto& s : m.node_sets) p.u64(static_cast<std::uint64_t>(s.id)), p.str(s.name), p.vec(s.vertex);
  p.vec(m.vertex_geo_dim), p.vec(m.vertex_geo_tag);
  p.u64(m.geo_entities.size());
  for (const auto& g : m.geo_entities)
    p.u64(static_cast<std::uint64_t>(g.dim)), p.u64(static_cast<std::uint32_t>(g.tag)), p.vec(g.bounding);
  p.u64(m.warnings.size());
  for (const auto& w : m.warnings) p.str(w);
  return p.out;
}

CoarseMesh unpack_mesh(const std::string& bytes, const std::string& path) {
  Unpacker u{bytes, path};
  CoarseMesh m;
  m.source = u.str();
  m.mode = u.u64() == 0 ? Mode::Volume : Mode::Surface;
  m.x = u.vec<double>(), m.y = u.vec<double>(), m.z = u.vec<double>();
  m.vertex_file_id = u.vec<Id>(), m.conn = u.vec<Id>(), m.element_file_id = u.vec<Id>();
  m.element_block = u.vec<std::int32_t>();
  // Counts of small records are bounded by the bytes left (one u64 each at least).
  auto count = [&] {
    const std::uint64_t n = u.u64();
    if (n > bytes.size() - u.at) u.fail();
    return n;
  };
  for (std::uint64_t i = count(); i > 0; --i) {
    Block b;
    b.id = static_cast<std::int64_t>(u.u64());
    b.name = u.str();
    m.blocks.push_back(std::move(b));
  }
  for (std::uint64_t i = count(); i > 0; --i) {
    SideSet s;
    s.id = static_cast<std::int64_t>(u.u64());
    s.name = u.str();
    s.element = u.vec<Id>();
    s.side = u.vec<std::int8_t>();
    m.side_sets.push_back(std::move(s));
  }
  for (std::uint64_t i = count(); i > 0; --i) {
    NodeSet s;
    s.id = static_cast<std::int64_t>(u.u64());
    s.name = u.str();
    s.vertex = u.vec<Id>();
    m.node_sets.push_back(std::move(s));
  }
  m.vertex_geo_dim = u.vec<std::int8_t>();
  m.vertex_geo_tag = u.vec<std::int32_t>();
  for (std::uint64_t i = count(); i > 0; --i) {
    GeoEntity g;
    g.dim = static_cast<int>(u.u64());
    g.tag = static_cast<std::int32_t>(static_cast<std::uint32_t>(u.u64()));
    g.bounding = u.vec<int>();
    m.geo_entities.push_back(std::move(g));
  }
  for (std::uint64_t i = count(); i > 0; --i) m.warnings.push_back(u.str());
  if (u.at != bytes.size()) u.fail();
  return m;
}

CoarseMesh read_isolated(const std::string& path, std::int64_t file_size, const std::function<CoarseMesh()>& read) {
  if (const char* e = std::getenv("DICER_READER_IN_PROCESS"); e && std::string(e) == "1") return read();
  int fds[2];
  if (::pipe(fds) != 0)
    throw Error(ErrorKind::Io, path + ": cannot start the isolated reader (pipe: " + std::strerror(errno) + ")");
  pid_t pid;
  {
    // No other thread may be inside HDF5 while the process is copied.
    std::lock_guard lock(hdf5_lock());
    pid = ::fork();
    if (pid == 0) {
      ::close(fds[0]);
      child(fds[1], file_size, read);
    }
  }
  const int fork_errno = errno;
  ::close(fds[1]);
  if (pid < 0) {
    ::close(fds[0]);
    throw Error(ErrorKind::Io, path + ": cannot start the isolated reader (fork: " + std::strerror(fork_errno) + ")");
  }
  const std::string bytes = read_all(fds[0]);
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status))
    throw Error(ErrorKind::BadInput, path + ": not a readable Exodus II file (the netCDF-4/HDF5 library crashed on it: " +
                                         std::string(strsignal(WTERMSIG(status))) + ", in an isolated reader)");
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || bytes.empty())
    throw Error(ErrorKind::BadInput, path + ": not a readable Exodus II file (the isolated reader ended without an answer)");
  if (bytes[0] == kErrorTag) {
    const std::string rest = bytes.substr(1);
    Unpacker u{rest, path};
    const auto kind = static_cast<ErrorKind>(u.u64());
    const std::string what = u.str();
    // The child's message already names the file when it comes from the reader.
    throw Error(kind, what.rfind(path, 0) == 0 ? what : path + ": " + what);
  }
  if (bytes[0] != kMeshTag) throw Error(ErrorKind::BadInput, path + ": the isolated reader sent no mesh");
  return unpack_mesh(bytes.substr(1), path);
}

}  // namespace dicer
