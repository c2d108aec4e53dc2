#include "internal/fftw_util.h"

#include <cmath>
#include <numbers>

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

void PlanRealTransforms(int64_t n, Plan* forward, Plan* inverse) {
  Array<double> real(n);
  Array<fftw_complex> complex(n / 2 + 1);
  fftw_plan r2c = nullptr, c2r = nullptr;
  {
    std::lock_guard<std::mutex> lock(PlannerMutex());
    if (forward != nullptr) {
      r2c = fftw_plan_dft_r2c_1d(static_cast<int>(n), real.data(), complex.data(), FFTW_ESTIMATE);
    }
    if (inverse != nullptr) {
      c2r = fftw_plan_dft_c2r_1d(static_cast<int>(n), complex.data(), real.data(), FFTW_ESTIMATE);
    }
  }
  // Adopt takes the lock itself (to destroy a previous plan) and throws on a null plan
  if (forward != nullptr) forward->Adopt(r2c);
  if (inverse != nullptr) inverse->Adopt(c2r);
}

std::vector<double> PeriodicHann(int64_t n) {
  std::vector<double> w(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) {
    w[static_cast<size_t>(k)] =
        0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n));
  }
  return w;
}

void Plan::Destroy() {
  if (plan_ == nullptr) return;
  std::lock_guard<std::mutex> lock(PlannerMutex());
  fftw_destroy_plan(plan_);
  plan_ = nullptr;
}

}  // namespace sonicboom::internal::fftw
