// The read watchdog counts the time a read runs, not the time its process was stopped.
#include "internal/watchdog.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <thread>

namespace sonicboom::internal {
namespace {

// A read left open past its deadline while the process runs ends the process naming the read.
TEST(WatchdogDeathTest, AReadOpenPastItsDeadlineEndsTheProcess) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        ::setenv("SONICBOOM_READ_TIMEOUT_S", "1", 1);
        ReadDeadline read("hung.h5: reading sample row 3");
        std::this_thread::sleep_for(std::chrono::seconds(3));
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(1),
      "hung.h5: reading sample row 3 does not finish \\(no answer within 1 s\\)");
}

// Stopped (SIGSTOP, as a shell's ^Z or a scheduler pausing a job) for twice its deadline, then
// continued: the read is still inside its own time and the process goes on (it used to exit 1,
// reporting the file as corrupted).
TEST(WatchdogDeathTest, AStoppedProcessIsNotAHungRead) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        ::setenv("SONICBOOM_READ_TIMEOUT_S", "2", 1);
        const pid_t reader = ::getpid();
        if (::fork() == 0) {  // the waker: continues the reader 4 s after it stopped itself
          std::this_thread::sleep_for(std::chrono::seconds(4));
          ::kill(reader, SIGCONT);
          std::_Exit(0);
        }
        {
          ReadDeadline read("paused.h5: reading sample row 3");
          ::raise(SIGSTOP);
          // the monitor ticks twice while the read is still open after the pause
          std::this_thread::sleep_for(std::chrono::seconds(1));
        }
        std::_Exit(0);
      },
      ::testing::ExitedWithCode(0), "");
}

}  // namespace
}  // namespace sonicboom::internal
