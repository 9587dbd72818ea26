#pragma once
// The Exodus library's last error message, on one line: shared by the
// Exodus reader (readers/read_exodus.cpp) and writer (export/exodus.cpp).
// Private: include only from those two files.
#include <exodusII.h>
#include <netcdf.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace dicer::exodus {

// The library keeps its last message in a static buffer; clear it before
// each call so that a failure reports its own message, never a stale one.
// errno too: a failed write's reason (os_reason) is the OS's.
inline void clear_error() {
  ex_err("dicer", "", EX_MSG);
  errno = 0;
}

// After a failed call: the OS's reason for a failed write, which netCDF
// reports only as "HDF error" (a full disk, a quota, the file size limit),
// as " (No space left on device)"; "" for anything else.
inline std::string os_reason(int err) {
  if (err != ENOSPC && err != EDQUOT && err != EFBIG && err != EIO) return "";
  return std::string(" (") + std::strerror(err) + ")";
}

inline std::string reason(int rc) {
  const char* msg = nullptr;
  const char* func = nullptr;
  int code = 0;
  ex_get_err(&msg, &func, &code);
  std::string text = (msg != nullptr) ? msg : "";
  // Library messages contain tabs and newlines; keep the error on one line.
  for (char& c : text)
    if (c == '\n' || c == '\t') c = ' ';
  while (!text.empty() && text.back() == ' ') text.pop_back();
  if (text.rfind("Error: ", 0) == 0) text.erase(0, 7);
  if (code != 0 && code != EX_MSG && code > -1000 && code < 1000) {
    if (!text.empty()) text += ": ";
    text += nc_strerror(code);
  }
  if (text.empty()) text = "exodus error code " + std::to_string(rc);
  return text;
}

}  // namespace dicer::exodus
