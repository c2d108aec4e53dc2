#include "sonicboom/core/progress.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace sonicboom {
namespace {

std::atomic<bool> g_quiet{false};

}  // namespace

std::string FormatDuration(double seconds) {
  if (seconds < 0 || !std::isfinite(seconds)) return "?";
  const int64_t s = std::llround(seconds);
  if (s >= 3600) return fmt::format("{}h{:02d}m", s / 3600, (s % 3600) / 60);
  return s >= 60 ? fmt::format("{}m{:02d}s", s / 60, s % 60) : fmt::format("{}s", s);
}

void Progress::SetQuiet(bool quiet) {
  g_quiet = quiet;
}

Progress::Progress(std::string label, int64_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled && !g_quiet),
      tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

Progress::~Progress() {
  Finish();
}

void Progress::Add(int64_t n) {
  done_ += n;
  if (!enabled_) return;
  // redraw at most 10 Hz on a terminal; elsewhere at each 10 % step or every 30 s
  std::lock_guard<std::mutex> lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_draw_).count();
  const int decile = total_ > 0 ? static_cast<int>(10 * done_ / total_) : 0;
  if ((tty_ && since >= 0.1) || (!tty_ && (decile != last_decile_ || since >= 30.0))) {
    last_decile_ = decile;
    last_draw_ = now;
    Draw(false);
  }
}

void Progress::SetStatus(const std::string& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  status_ = status;
}

void Progress::Finish() {
  if (!enabled_ || finished_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  finished_ = true;
  // a log line already showing the final count is not repeated
  if (!tty_ && last_drawn_ == done_) return;
  Draw(true);
}

void Progress::Draw(bool final_line) {
  // rate and ETA from the mean rate so far
  const int64_t done = done_;
  last_drawn_ = done;
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double rate = elapsed > 0 ? done / elapsed : 0.0;
  const double eta = rate > 0 ? (total_ - done) / rate : -1.0;
  const double frac = total_ > 0 ? static_cast<double>(done) / total_ : 1.0;
  std::string text =
      fmt::format("{} {}/{} ({:.0f}%) {:.1f}/s elapsed {} eta {}{}{}", label_, done, total_,
                  100 * frac, rate, FormatDuration(elapsed),
                  final_line ? "0s" : FormatDuration(eta), status_.empty() ? "" : "  ", status_);
  if (tty_) {
    // bar redrawn in place
    const int width = 24;
    const int filled = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r\033[K[%s%s] %s%s", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), text.c_str(), final_line ? "\n" : "");
    std::fflush(stderr);
  } else {
    spdlog::info("{}", text);
  }
}

}  // namespace sonicboom
