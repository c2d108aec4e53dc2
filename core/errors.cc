#include "sonicboom/core/errors.h"

#include <csignal>
#include <cstdio>
#include <cstdlib>

namespace sonicboom::internal {

void AbortOnFailedDemand(const char* condition, const char* file, int line) {
  std::fprintf(stderr, "sonicboom: internal invariant failed: %s at %s:%d\n", condition, file,
               line);
  // our bug, not a damaged file: the default abort even inside a guarded read (watchdog.h)
  std::signal(SIGABRT, SIG_DFL);
  std::abort();
}

}  // namespace sonicboom::internal
