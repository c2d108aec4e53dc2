#pragma once
/// Progress of a long step: thread-safe counter, redraw at most 10 Hz; a bar on a terminal,
/// a plain log line every 10 % (or 30 s) elsewhere. Silent when quiet.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace sonicboom {

/// A duration as a log line shows it: "42s", "3m07s", "2h05m"; "?" when negative or not finite.
std::string FormatDuration(double seconds);

class Progress {
 public:
  Progress(std::string label, int64_t total, bool enabled = true);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  /// Adds `n` finished items; safe from worker threads.
  void Add(int64_t n = 1);
  /// Sets an extra text shown after the counter (e.g. "loss 0.12").
  void SetStatus(const std::string& status);
  /// Final line.
  void Finish();

  /// Globally turns progress output off (-q, --json).
  static void SetQuiet(bool quiet);

 private:
  void Draw(bool final_line);

  std::string label_;
  int64_t total_;
  bool enabled_;
  bool tty_;
  bool finished_{false};
  std::atomic<int64_t> done_{0};
  std::mutex mutex_;
  std::string status_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  int last_decile_{-1};
  int64_t last_drawn_{-1};  // `done` at the last drawn line
};

}  // namespace sonicboom
