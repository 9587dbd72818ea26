// dicer's HDF5 file driver for the files it writes (hdf5_file.hpp,
// create_file_id): POSIX pread/pwrite like HDF5's sec2, plus one rule for
// failures. The first failed write or truncate is returned to HDF5 (so the
// call that hit the full disk fails), and from then on writes go to an
// in-memory overlay, which reads see, so HDF5 can finish closing the file.
// Without it a close after ENOSPC fails, and HDF5 1.10 then keeps the id of
// a file it has already freed and crashes at exit. The file is a temporary
// that AtomicOutput removes; what the overlay holds is never kept.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <iterator>
#include <mutex>
#include <new>
#include <unordered_map>
#include <vector>

#include "hdf5_file.hpp"

namespace dicer::h5 {
namespace {

struct DriverInfo {
  int* first_errno;  // the caller's, or nullptr
};

constexpr haddr_t kMaxAddr = (haddr_t{1} << 62) - 1;  // off_t range, as sec2
constexpr haddr_t kOverlayPage = 4096;

struct WriteFile {
  H5FD_t pub;  // HDF5's part; must come first
  int fd = -1;
  haddr_t eoa = 0, eof = 0;
  dev_t dev = 0;
  ino_t ino = 0;
  int error = 0;  // errno of the first failure; then writes go to the overlay
  int* report = nullptr;
  std::unordered_map<haddr_t, std::vector<unsigned char>> overlay;  // page address -> bytes
};

WriteFile* self(H5FD_t* f) { return reinterpret_cast<WriteFile*>(f); }
const WriteFile* self(const H5FD_t* f) { return reinterpret_cast<const WriteFile*>(f); }

herr_t fail(int err, const char* what) {
  H5Epush2(H5E_DEFAULT, __FILE__, what, __LINE__, H5E_ERR_CLS, H5E_VFL, H5E_WRITEERROR,
           "%s, errno = %d, error message = '%s'", what, err, std::strerror(err));
  return -1;
}

void record(WriteFile* f, int err) {
  if (f->error != 0) return;
  f->error = err;
  if (f->report && *f->report == 0) *f->report = err;
}

bool in_range(const WriteFile* f, haddr_t addr, size_t size) {
  return addr != HADDR_UNDEF && addr <= kMaxAddr && size <= kMaxAddr - addr && addr + size <= f->eoa;
}

// Reads the file as written (zeros past its end), without the overlay.
bool read_disk(const WriteFile* f, haddr_t addr, size_t size, unsigned char* out) {
  while (size > 0) {
    const ssize_t n = ::pread(f->fd, out, std::min<size_t>(size, 1u << 30), static_cast<off_t>(addr));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return false;
    if (n == 0) {
      std::memset(out, 0, size);
      return true;
    }
    out += n, addr += static_cast<haddr_t>(n), size -= static_cast<size_t>(n);
  }
  return true;
}

std::vector<unsigned char>* overlay_page(WriteFile* f, haddr_t page) {
  auto it = f->overlay.find(page);
  if (it != f->overlay.end()) return &it->second;
  std::vector<unsigned char> bytes(kOverlayPage);
  if (!read_disk(f, page, kOverlayPage, bytes.data())) return nullptr;
  return &f->overlay.emplace(page, std::move(bytes)).first->second;
}

H5FD_t* open(const char* name, unsigned flags, hid_t fapl, haddr_t maxaddr) {
  if (!name || !*name || maxaddr == 0 || maxaddr == HADDR_UNDEF || maxaddr > kMaxAddr) return nullptr;
  const auto* info = static_cast<const DriverInfo*>(H5Pget_driver_info(fapl));
  int oflags = O_CLOEXEC | ((flags & H5F_ACC_RDWR) ? O_RDWR : O_RDONLY);
  if (flags & H5F_ACC_TRUNC) oflags |= O_TRUNC;
  if (flags & H5F_ACC_CREAT) oflags |= O_CREAT;
  if (flags & H5F_ACC_EXCL) oflags |= O_EXCL;
  const int fd = ::open(name, oflags, 0666);
  struct stat st {};
  if (fd < 0 || ::fstat(fd, &st) != 0) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    // Not recorded as a write failure: HDF5 first probes whether the file
    // exists (ENOENT) before it creates it; the reason is on the stack.
    H5Epush2(H5E_DEFAULT, __FILE__, "open", __LINE__, H5E_ERR_CLS, H5E_VFL, H5E_CANTOPENFILE,
             "unable to open file: name = '%s', errno = %d, error message = '%s'", name, err, std::strerror(err));
    return nullptr;
  }
  auto* f = new (std::nothrow) WriteFile();
  if (!f) {
    ::close(fd);
    return nullptr;
  }
  f->fd = fd;
  f->eof = static_cast<haddr_t>(st.st_size);
  f->dev = st.st_dev, f->ino = st.st_ino;
  f->report = info ? info->first_errno : nullptr;
  return &f->pub;
}

herr_t close(H5FD_t* file) {
  WriteFile* f = self(file);
  const int rc = ::close(f->fd);
  const int err = errno;
  // A close that loses data (NFS reports late) is a write failure too.
  if (rc != 0 && f->error == 0) record(f, err);
  delete f;
  return 0;
}

int cmp(const H5FD_t* a, const H5FD_t* b) {
  const WriteFile *f = self(a), *g = self(b);
  if (f->dev != g->dev) return f->dev < g->dev ? -1 : 1;
  if (f->ino != g->ino) return f->ino < g->ino ? -1 : 1;
  return 0;
}

herr_t query(const H5FD_t*, unsigned long* flags) {
  if (flags)
    *flags = H5FD_FEAT_AGGREGATE_METADATA | H5FD_FEAT_ACCUMULATE_METADATA | H5FD_FEAT_DATA_SIEVE |
             H5FD_FEAT_AGGREGATE_SMALLDATA | H5FD_FEAT_POSIX_COMPAT_HANDLE;
  return 0;
}

haddr_t get_eoa(const H5FD_t* f, H5FD_mem_t) { return self(f)->eoa; }
herr_t set_eoa(H5FD_t* f, H5FD_mem_t, haddr_t addr) {
  if (addr > kMaxAddr) return -1;
  self(f)->eoa = addr;
  return 0;
}
haddr_t get_eof(const H5FD_t* f, H5FD_mem_t) { return self(f)->eof; }

herr_t get_handle(H5FD_t* f, hid_t, void** handle) {
  if (!handle) return -1;
  *handle = &self(f)->fd;
  return 0;
}

herr_t read(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, void* buf) {
  WriteFile* f = self(file);
  if (!in_range(f, addr, size)) return fail(EINVAL, "read beyond the end of the allocated file");
  auto* out = static_cast<unsigned char*>(buf);
  if (!read_disk(f, addr, size, out)) return fail(errno, "read failed");
  if (f->overlay.empty() || size == 0) return 0;
  for (haddr_t page = addr / kOverlayPage * kOverlayPage; page < addr + size; page += kOverlayPage) {
    auto it = f->overlay.find(page);
    if (it == f->overlay.end()) continue;
    const haddr_t lo = std::max(page, addr), hi = std::min(page + kOverlayPage, addr + size);
    std::memcpy(out + (lo - addr), it->second.data() + (lo - page), hi - lo);
  }
  return 0;
}

herr_t write(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, const void* buf) {
  WriteFile* f = self(file);
  if (!in_range(f, addr, size)) return fail(EINVAL, "write beyond the end of the allocated file");
  const auto* in = static_cast<const unsigned char*>(buf);
  const haddr_t end = addr + size;
  if (f->error == 0) {
    haddr_t at = addr;
    while (at < end) {
      const ssize_t n = ::pwrite(f->fd, in + (at - addr), std::min<haddr_t>(end - at, 1u << 30), static_cast<off_t>(at));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int err = n < 0 ? errno : EIO;
        record(f, err);
        f->eof = std::max(f->eof, at);
        return fail(err, "write failed");
      }
      at += static_cast<haddr_t>(n);
    }
  } else {
    for (haddr_t page = addr / kOverlayPage * kOverlayPage; page < end; page += kOverlayPage) {
      std::vector<unsigned char>* p = overlay_page(f, page);
      if (!p) return fail(errno, "read failed");
      const haddr_t lo = std::max(page, addr), hi = std::min(page + kOverlayPage, end);
      std::memcpy(p->data() + (lo - page), in + (lo - addr), hi - lo);
    }
  }
  f->eof = std::max(f->eof, end);
  return 0;
}

herr_t flush(H5FD_t*, hid_t, hbool_t) { return 0; }  // durability is AtomicOutput::commit's fsync

herr_t truncate(H5FD_t* file, hid_t, hbool_t closing) {
  WriteFile* f = self(file);
  if (f->eoa == f->eof) return 0;
  if (f->error == 0 && ::ftruncate(f->fd, static_cast<off_t>(f->eoa)) != 0) {
    const int err = errno;
    record(f, err);
    // At close a failure would leave HDF5 with a freed file (see above):
    // recorded, reported by File::close, not returned.
    if (!closing) return fail(err, "truncate failed");
  }
  f->eof = f->eoa;
  return 0;
}

H5FD_class_t make_class() {
  H5FD_class_t c{};
  c.name = "dicer_write";
  c.maxaddr = kMaxAddr;
  c.fc_degree = H5F_CLOSE_WEAK;
  c.fapl_size = sizeof(DriverInfo);
  c.open = open;
  c.close = close;
  c.cmp = cmp;
  c.query = query;
  c.get_eoa = get_eoa;
  c.set_eoa = set_eoa;
  c.get_eof = get_eof;
  c.get_handle = get_handle;
  c.read = read;
  c.write = write;
  c.flush = flush;
  c.truncate = truncate;
  const H5FD_mem_t map[H5FD_MEM_NTYPES] = H5FD_FLMAP_DICHOTOMY;  // sec2's
  std::copy(std::begin(map), std::end(map), std::begin(c.fl_map));
  return c;
}

}  // namespace

Handle untimed_file_creation() {
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  if (fcpl && H5Pset_obj_track_times(fcpl.get(), false) < 0) fcpl.reset();
  return fcpl;
}

hid_t create_file_id(const std::string& path, int* first_errno, hid_t fcpl) {
  quiet();
  static const H5FD_class_t cls = make_class();
  static std::mutex mu;
  static hid_t driver = -1;
  {
    std::lock_guard lock(mu);
    // Re-registered when HDF5 was closed and reopened (the id then dangles).
    if (driver < 0 || H5Iis_valid(driver) <= 0 || H5Iget_type(driver) != H5I_VFL) driver = H5FDregister(&cls);
  }
  if (driver < 0) return -1;
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  const DriverInfo info{first_errno};
  if (!fapl || H5Pset_driver(fapl.get(), driver, &info) < 0 ||
      H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V110, H5F_LIBVER_V110) < 0)
    return -1;
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl, fapl.get());
  if (id >= 0) return id;
  // Closing the property list would clear the error stack the caller reads.
  const hid_t stack = H5Eget_current_stack();
  fapl.reset();
  if (stack >= 0) H5Eset_current_stack(stack);
  return id;
}

}  // namespace dicer::h5
