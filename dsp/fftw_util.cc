#include "internal/fftw_util.h"

#include <cmath>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::internal::fftw {

std::mutex& PlannerMutex() {
  static std::mutex mutex;
  return mutex;
}

void DestroyPlan(fftw_plan plan) {
  fftw_destroy_plan(plan);
}
void DestroyPlan(fftwf_plan plan) {
  fftwf_destroy_plan(plan);
}
void ThrowNoPlan() {
  throw NumericalError("FFTW could not create a plan");
}

namespace {

// The FFTW planner functions of one precision: Real is the sample type.
struct Double {
  using Real = double;
  using Complex = fftw_complex;
  static constexpr auto r2c = fftw_plan_dft_r2c_1d;
  static constexpr auto c2r = fftw_plan_dft_c2r_1d;
};
struct Single {
  using Real = float;
  using Complex = fftwf_complex;
  static constexpr auto r2c = fftwf_plan_dft_r2c_1d;
  static constexpr auto c2r = fftwf_plan_dft_c2r_1d;
};

template <typename Api, typename PlanT>
void PlanReal(int64_t n, PlanT* forward, PlanT* inverse) {
  Array<typename Api::Real> real(n);
  Array<typename Api::Complex> complex(n / 2 + 1);
  decltype(forward->get()) r2c = nullptr, c2r = nullptr;
  {
    std::lock_guard<std::mutex> lock(PlannerMutex());
    if (forward != nullptr) {
      r2c = Api::r2c(static_cast<int>(n), real.data(), complex.data(), FFTW_ESTIMATE);
    }
    if (inverse != nullptr) {
      c2r = Api::c2r(static_cast<int>(n), complex.data(), real.data(), FFTW_ESTIMATE);
    }
    // a plan FFTW could not make: destroy the other one, which nothing owns yet
    if ((forward != nullptr && r2c == nullptr) || (inverse != nullptr && c2r == nullptr)) {
      if (r2c != nullptr) DestroyPlan(r2c);
      if (c2r != nullptr) DestroyPlan(c2r);
      ThrowNoPlan();
    }
  }
  // Adopt takes the lock itself (to destroy a previous plan)
  if (forward != nullptr) forward->Adopt(r2c);
  if (inverse != nullptr) inverse->Adopt(c2r);
}

}  // namespace

void PlanRealTransforms(int64_t n, Plan* forward, Plan* inverse) {
  PlanReal<Double>(n, forward, inverse);
}
void PlanRealTransforms(int64_t n, PlanF* forward, PlanF* inverse) {
  PlanReal<Single>(n, forward, inverse);
}

std::vector<double> PeriodicHann(int64_t n) {
  std::vector<double> w(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) {
    w[static_cast<size_t>(k)] =
        0.5 -
        0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n));
  }
  return w;
}

}  // namespace sonicboom::internal::fftw
