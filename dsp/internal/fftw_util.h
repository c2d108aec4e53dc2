#pragma once
/// Private FFTW helpers shared by features.cc and spectral_gate.cc: the process-wide planner
/// lock, aligned arrays, owned plans, and a pool of per-call scratch objects for const (shared)
/// DSP blocks. Only dsp .cc files include this header; fftw3.h never reaches a public header.

#include <fftw3.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace sonicboom::internal::fftw {

/// The FFTW planner (plan creation and destruction) is not thread-safe; every plan made or
/// destroyed by the dsp module goes through this one lock. Plan execution is thread-safe.
std::mutex& PlannerMutex();

/// An FFTW-aligned array of T, zero-filled, so that every scratch buffer has the same alignment
/// as the arrays the plans were made with and new-array execution is allowed. Single-precision
/// element types (float, fftwf_complex) come from fftwf_malloc, the others from fftw_malloc.
template <typename T>
class Array {
  static constexpr bool kSingle = std::is_same_v<T, float> || std::is_same_v<T, fftwf_complex>;

 public:
  Array() = default;
  explicit Array(int64_t size) : size_(size) {
    const size_t bytes = sizeof(T) * static_cast<size_t>(std::max<int64_t>(size, 1));
    data_ = static_cast<T*>(kSingle ? fftwf_malloc(bytes) : fftw_malloc(bytes));
    if (data_ == nullptr) throw std::bad_alloc();
    std::memset(static_cast<void*>(data_), 0, bytes);
  }
  ~Array() {
    if constexpr (kSingle) {
      fftwf_free(data_);
    } else {
      fftw_free(data_);
    }
  }
  Array(Array&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}
  Array& operator=(Array&& other) noexcept {
    std::swap(data_, other.data_);
    std::swap(size_, other.size_);
    return *this;
  }
  Array(const Array&) = delete;
  Array& operator=(const Array&) = delete;
  T* data() const { return data_; }
  int64_t size() const { return size_; }
  T& operator[](int64_t i) const { return data_[i]; }

 private:
  T* data_{nullptr};
  int64_t size_{0};
};

/// fftw_destroy_plan / fftwf_destroy_plan (call under the planner lock), and the error for a
/// plan FFTW could not make.
void DestroyPlan(fftw_plan plan);
void DestroyPlan(fftwf_plan plan);
[[noreturn]] void ThrowNoPlan();

/// Owns an FFTW plan of either precision (fftw_plan: double, fftwf_plan: float); destroys it
/// under the planner lock.
template <typename PlanT>
class BasicPlan {
 public:
  BasicPlan() = default;
  ~BasicPlan() { Destroy(); }
  /// Takes ownership of a plan made under the planner lock (call without holding it). Throws
  /// NumericalError when FFTW could not make the plan (nullptr).
  void Adopt(PlanT plan) {
    Destroy();
    if (plan == nullptr) ThrowNoPlan();
    plan_ = plan;
  }
  BasicPlan(const BasicPlan&) = delete;
  BasicPlan& operator=(const BasicPlan&) = delete;
  PlanT get() const { return plan_; }

 private:
  void Destroy() {
    if (plan_ == nullptr) return;
    std::lock_guard<std::mutex> lock(PlannerMutex());
    DestroyPlan(plan_);
    plan_ = nullptr;
  }
  PlanT plan_{nullptr};
};

using Plan = BasicPlan<fftw_plan>;    // double precision
using PlanF = BasicPlan<fftwf_plan>;  // single precision

/// FFTW_ESTIMATE plans of the real transforms of n points: forward r2c (n -> n / 2 + 1 bins) and
/// inverse c2r, made under the planner lock on scratch Arrays (so they run on any Array of the
/// same sizes), in double (Plan) or single (PlanF) precision. Either output may be null. Throws
/// NumericalError when FFTW cannot plan.
void PlanRealTransforms(int64_t n, Plan* forward, Plan* inverse);
void PlanRealTransforms(int64_t n, PlanF* forward, PlanF* inverse);

/// Periodic Hann window of n points (torch.hann_window(periodic=True), scipy 'hann', sym=False).
std::vector<double> PeriodicHann(int64_t n);

/// A pool of scratch objects shared by the threads that call one const object. A call leases
/// one object (created only when every existing one is in use), so in steady state nothing is
/// allocated and no two concurrent calls share scratch.
template <typename T>
class ScratchPool {
 public:
  explicit ScratchPool(std::function<std::unique_ptr<T>()> make) : make_(std::move(make)) {}

  class Lease {
   public:
    Lease(const ScratchPool* pool, std::unique_ptr<T> item) : pool_(pool), item_(std::move(item)) {}
    ~Lease() { pool_->Release(std::move(item_)); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    T& operator*() const { return *item_; }
    T* operator->() const { return item_.get(); }

   private:
    const ScratchPool* pool_;
    std::unique_ptr<T> item_;
  };

  Lease Acquire() const {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!free_.empty()) {
        std::unique_ptr<T> item = std::move(free_.back());
        free_.pop_back();
        return Lease(this, std::move(item));
      }
    }
    return Lease(this, make_());
  }

 private:
  void Release(std::unique_ptr<T> item) const {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.push_back(std::move(item));
  }

  std::function<std::unique_ptr<T>()> make_;
  mutable std::mutex mutex_;
  mutable std::vector<std::unique_ptr<T>> free_;
};

/// Reflect-pads index i into [0, n) without repeating the edge sample (torch and numpy
/// "reflect"), folding again when the padding is longer than the signal.
inline int64_t ReflectIndex(int64_t i, int64_t n) {
  if (n == 1) return 0;
  const int64_t period = 2 * (n - 1);
  int64_t k = i % period;
  if (k < 0) k += period;
  return k < n ? k : period - k;
}

/// frame[k] = window[k] * x[first + k] for k in [0, n_fft): samples [first, first + n_fft) of x
/// (n samples), reflect-padded outside [0, n) (ReflectIndex), times the window.
inline void WindowedFrame(const float* x, int64_t n, int64_t first, const double* window,
                          int64_t n_fft, double* frame) {
  if (first >= 0 && first + n_fft <= n) {
    // inside the signal: a straight windowed copy
    const float* in = x + first;
    for (int64_t k = 0; k < n_fft; ++k) frame[k] = window[k] * in[k];
    return;
  }
  for (int64_t k = 0; k < n_fft; ++k) {
    const int64_t i = first + k;
    const double sample = (i >= 0 && i < n) ? x[i] : x[ReflectIndex(i, n)];
    frame[k] = window[k] * sample;
  }
}

}  // namespace sonicboom::internal::fftw
