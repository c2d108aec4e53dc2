#include "internal/fftw_util.h"

#include "sonicboom/core/errors.h"

namespace sonicboom::internal::fftw {

std::mutex& PlannerMutex() {
  static std::mutex mutex;
  return mutex;
}

void Plan::Adopt(fftw_plan plan) {
  Destroy();
  if (plan == nullptr) throw NumericalError("FFTW could not create a plan");
  plan_ = plan;
}

void Plan::Destroy() {
  if (plan_ == nullptr) return;
  std::lock_guard<std::mutex> lock(PlannerMutex());
  fftw_destroy_plan(plan_);
  plan_ = nullptr;
}

}  // namespace sonicboom::internal::fftw
