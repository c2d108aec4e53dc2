#pragma once
// A last resort against a third-party library that never returns: libhdf5 1.10 loops forever on
// some corrupted files (a variable-length string attribute whose global heap is damaged; found by
// fuzz/dataset_fuzz.cc, docs/robustness.md). A ReadDeadline covers one read that must finish in
// seconds; one monitor thread (started on first use) checks the open deadlines twice a second,
// and when one has passed it prints the read's message and ends the process with exit status 1:
// a hostile file gives an error instead of a hang. SONICBOOM_READ_TIMEOUT_S sets the time
// (default 120 s; 0 disables the monitor).

#include <string>

namespace sonicboom::internal {

class ReadDeadline {
 public:
  explicit ReadDeadline(const std::string& what);
  ~ReadDeadline();
  ReadDeadline(const ReadDeadline&) = delete;
  ReadDeadline& operator=(const ReadDeadline&) = delete;

 private:
  long long id_{-1};  // -1: the monitor is disabled
};

}  // namespace sonicboom::internal
