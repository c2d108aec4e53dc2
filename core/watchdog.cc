#include "internal/watchdog.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::internal {
namespace {

using Clock = std::chrono::steady_clock;

// the reads this thread is in (their messages, innermost last), for the crash handler below; a
// fixed array, so that the handler reads it without allocating, and guards may end in any order
constexpr int kMaxGuards = 32;
thread_local const char* open_reads[kMaxGuards];
thread_local int open_read_count = 0;

// A fault inside a read (libhdf5 1.10 over-reads a damaged global heap, or glibc aborts on the heap
// it corrupted): the read's message and exit status 1 instead of a core dump; a fault anywhere
// else keeps its default action.
void OnFault(int sig) {
  const char* what = open_read_count > 0 ? open_reads[open_read_count - 1] : nullptr;
  if (what == nullptr) {
    signal(sig, SIG_DFL);
    raise(sig);
    return;
  }
  auto put = [](const char* s) {
    if (write(STDERR_FILENO, s, std::strlen(s)) < 0) return;
  };
  put("error: ");
  put(what);
  put(sig == SIGSEGV   ? " crashed (segmentation fault): the file is corrupted\n"
      : sig == SIGBUS  ? " crashed (bus error): the file is corrupted\n"
      : sig == SIGABRT ? " crashed (abort, heap corrupted): the file is corrupted\n"
                       : " crashed: the file is corrupted\n");
  _exit(1);
}

// An alternate signal stack for this thread, so that the handler runs even when the fault is a
// stack overflow; set up once per thread, given back (disabled, then freed) when the thread ends.
struct AltStack {
  stack_t stack{};
  AltStack() {
    stack.ss_size = 1 << 16;
    stack.ss_sp = std::malloc(stack.ss_size);
    if (stack.ss_sp != nullptr && sigaltstack(&stack, nullptr) != 0) {
      std::free(stack.ss_sp);
      stack.ss_sp = nullptr;
    }
  }
  ~AltStack() {
    if (stack.ss_sp == nullptr) return;
    stack_t off{};
    off.ss_flags = SS_DISABLE;
    sigaltstack(&off, nullptr);
    std::free(stack.ss_sp);
  }
};

void EnsureAltStack() {
  thread_local AltStack stack;
}

// SONICBOOM_READ_TIMEOUT_S: plain decimal seconds, 0 (no deadline) or from 0.5 to one day;
// anything else (a word, a negative or non-finite number, hex) is refused, not read as "off"
double ParseTimeout(const char* env) {
  const std::string text(env);
  const bool plain = text.find_first_not_of("0123456789.eE+-") == std::string::npos;
  char* end = nullptr;
  errno = 0;
  const double v = plain ? std::strtod(env, &end) : -1.0;
  const bool number = plain && end != env && *end == '\0' && errno == 0 && std::isfinite(v);
  if (number && (v == 0.0 || (v >= 0.5 && v <= 86400.0))) return v;
  throw ConfigError(fmt::format(
      "SONICBOOM_READ_TIMEOUT_S = '{}': expected seconds from 0.5 to 86400, or 0 for no deadline",
      text));
}

// the monitor's tick, and how much later than a tick it must wake to count the gap as lost time
constexpr std::chrono::milliseconds kTick{500};
constexpr std::chrono::milliseconds kLostAfter{1000};

struct Monitor {
  std::mutex mutex;
  std::map<long long, std::pair<Clock::time_point, std::string>> open;  // id -> (deadline, what)
  long long next_id{0};
  double seconds{120.0};

  Monitor() {
    if (const char* env = std::getenv("SONICBOOM_READ_TIMEOUT_S"); env != nullptr && *env) {
      seconds = ParseTimeout(env);
    }
    if (!(seconds > 0.0)) return;
    struct sigaction action {};
    action.sa_handler = OnFault;
    action.sa_flags = SA_ONSTACK;
    sigemptyset(&action.sa_mask);
    for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL}) sigaction(sig, &action, nullptr);
    // the first tick's reference is taken here, not in the thread: a process stopped before the
    // thread first runs has lost that time too
    std::thread([this, last = Clock::now()]() mutable {
      for (;;) {
        std::this_thread::sleep_for(kTick);
        std::lock_guard<std::mutex> lock(mutex);
        const Clock::time_point now = Clock::now();
        // a tick far later than asked: the process was stopped (SIGSTOP, a suspended job) or not
        // scheduled; that time is not the read's, so every open deadline moves on by it
        const Clock::duration lost = now - last - kTick;
        last = now;
        if (lost > kLostAfter) {
          for (auto& [id, entry] : open) entry.first += lost;
        }
        for (const auto& [id, entry] : open) {
          if (now < entry.first) continue;
          std::fprintf(stderr,
                       "error: %s does not finish (no answer within %.0f s): the file is "
                       "corrupted\n",
                       entry.second.c_str(), seconds);
          std::fflush(stderr);
          std::_Exit(1);
        }
      }
    }).detach();
  }
};

Monitor& TheMonitor() {
  static Monitor* monitor = new Monitor();  // never destroyed: its thread outlives main
  return *monitor;
}

}  // namespace

FaultGuard::FaultGuard(const std::string& what) : what_(std::make_unique<std::string>(what)) {
  if (!(TheMonitor().seconds > 0.0) || open_read_count == kMaxGuards) return;
  EnsureAltStack();
  open_reads[open_read_count++] = what_->c_str();
  armed_ = true;
}

FaultGuard::~FaultGuard() {
  if (!armed_) return;
  // this guard's entry out of the list, wherever it is (the object may have moved threads: then
  // it is not found here and the other thread's list keeps a stale entry until it ends)
  for (int k = open_read_count - 1; k >= 0; --k) {
    if (open_reads[k] != what_->c_str()) continue;
    for (int j = k; j + 1 < open_read_count; ++j) open_reads[j] = open_reads[j + 1];
    --open_read_count;
    break;
  }
}

ReadDeadline::ReadDeadline(const std::string& what) : guard_(what) {
  Monitor& m = TheMonitor();
  if (!(m.seconds > 0.0)) return;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(m.seconds));
  std::lock_guard<std::mutex> lock(m.mutex);
  id_ = m.next_id++;
  m.open.emplace(id_, std::make_pair(deadline, what));
}

ReadDeadline::~ReadDeadline() {
  if (id_ < 0) return;
  Monitor& m = TheMonitor();
  std::lock_guard<std::mutex> lock(m.mutex);
  m.open.erase(id_);
}

}  // namespace sonicboom::internal
