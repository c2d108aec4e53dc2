#pragma once
// A last resort against a third-party library that is not hardened against hostile files:
// libhdf5 1.10 loops forever on some corrupted files, and over-reads on others until it faults
// (a damaged global heap behind a variable-length string; found by fuzz/dataset_fuzz.cc,
// docs/robustness.md). A ReadDeadline covers one read that must finish in seconds: one monitor
// thread (started on first use) checks the open deadlines twice a second, and a fault
// (SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL) while a read is open is caught; either way the read's
// message is printed and the process ends with exit status 1, so a hostile file gives an error
// instead of a hang or a core dump. A fault outside any read keeps its default action.
// SONICBOOM_READ_TIMEOUT_S sets the time (default 120 s; 0 disables the monitor and the fault
// handler, as the fuzzers want). The time counts while the process runs: when the monitor wakes
// more than a second late (the process was stopped by SIGSTOP or a shell's ^Z, or starved), the
// open deadlines move on by the time lost, so pausing a long job does not read as a hung file.

#include <memory>
#include <string>
#include <utility>

namespace sonicboom::internal {

/// A fault on this thread while a FaultGuard lives is reported as a crash of its read. An object
/// that holds a file open (DatasetFile) keeps one for its whole life: libhdf5 may corrupt the
/// heap while reading and fault only when the file is closed.
class FaultGuard {
 public:
  /// `what` names the read, e.g. "D.h5: reading the file".
  explicit FaultGuard(const std::string& what);
  ~FaultGuard();
  // the message stays where it is (on the heap); the moved-from guard is disarmed
  FaultGuard(FaultGuard&& other) noexcept
      : what_(std::move(other.what_)), armed_(std::exchange(other.armed_, false)) {}
  FaultGuard& operator=(FaultGuard&&) = delete;
  FaultGuard(const FaultGuard&) = delete;
  FaultGuard& operator=(const FaultGuard&) = delete;

 private:
  std::unique_ptr<std::string> what_;
  bool armed_{false};
};

/// A read that must finish in seconds (and a FaultGuard over it).
class ReadDeadline {
 public:
  /// `what` names the read, e.g. "D.h5: reading sample row 3".
  explicit ReadDeadline(const std::string& what);
  ~ReadDeadline();
  ReadDeadline(const ReadDeadline&) = delete;
  ReadDeadline& operator=(const ReadDeadline&) = delete;

 private:
  FaultGuard guard_;
  long long id_{-1};  // -1: the monitor is disabled
};

}  // namespace sonicboom::internal
