#include "sonicboom/core/errors.h"

#include <cstdio>
#include <cstdlib>

namespace sonicboom::internal {

void AbortOnFailedDemand(const char* condition, const char* file, int line) {
  std::fprintf(stderr, "sonicboom: internal invariant failed: %s at %s:%d\n", condition, file,
               line);
  std::abort();
}

}  // namespace sonicboom::internal
