#pragma once
// AtomicOutput: the one way dicer writes a file (stores and every export).
// An interrupted or failed write never damages an existing file of the same
// name, and leaves nothing behind.
//
// Protocol:
//  1. The constructor opens the target's folder and picks a temporary name
//     in it, ".NAME.tmp-PID" (shortened with a hash when it would pass
//     NAME_MAX), after removing stale temporaries of the same NAME left by
//     dead processes (a SIGKILL cannot be caught; the next run cleans up).
//  2. The writer creates and fills temp_path() (or, for libraries with
//     fixed path buffers such as Exodus 6.02, short_path(): the same file
//     named through /proc/self/fd, always under 64 characters).
//  3. commit(): fsync of the file, rename onto NAME, fsync of the folder,
//     so after commit() returns the new file survives a power loss.
//  4. The destructor removes the temporary unless committed (errors,
//     exceptions, cancellation), and remove_uncommitted() does the same from
//     a signal handler (async-signal-safe).
// Refuses (Error{Usage}) an output that is an existing directory, and
// (Error{Io}, naming the folder and the reason) a folder it cannot open or
// write in (permissions, a read-only file system, an immutable folder).
// Not copyable or movable; one per output file.
#include <string>

namespace dicer {

class AtomicOutput {
 public:
  explicit AtomicOutput(const std::string& final_path);
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;

  const std::string& final_path() const { return final_; }
  const std::string& temp_path() const { return temp_; }  // in the target folder, for messages and most libraries
  const std::string& short_path() const { return short_; }  // /proc/self/fd/N/NAME: the same file, short
  // Durably replaces final_path() with the temporary. Throws Error{Io}.
  void commit();
  // commit()'s part that can fail for reasons other than the rename: fsync
  // of the temporary, and a directory now at the final name. A set of
  // files calls it for every file before the first commit(), so a failure
  // leaves every old file in place; only a rename failing half way (an
  // immutable old file) can leave a mix. Idempotent.
  void flush();
  // For a writer that holds many finished temporaries until all are
  // written (a Nemesis set, committed together): lets go of the folder's
  // handle (one file descriptor each): flush() and commit() open the folder
  // again by name for their call. short_path() is invalid after park().
  void park();
  bool committed() const { return committed_; }

  // Unlinks every uncommitted temporary of this process. Async-signal-safe:
  // for signal handlers that must exit without unwinding.
  static void remove_uncommitted() noexcept;

 private:
  std::string final_, name_, temp_name_, temp_, short_;
  std::string dir_;
  int dir_fd_ = -1;
  int slot_ = -1;  // index in the process-wide registry of live temporaries
  bool committed_ = false;
  bool flushed_ = false;
};

}  // namespace dicer
