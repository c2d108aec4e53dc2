#include "internal/fidelity_metrics.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <vector>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/solid_response.h"

namespace sonicboom::experiments {

double RelativeError(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref) {
  SONICBOOM_DEMAND(y.rows() == ref.rows() && y.cols() == ref.cols());
  return (y - ref).norm() / ref.norm();
}

TimingError TimingErrorUs(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref,
                          double sample_rate_hz, const WavefrontWindow& wavefront) {
  // first arrivals (s): 20 % of each channel's own peak, as the reference command reads them
  const Eigen::VectorXd a = solid::ThresholdArrivals(y, sample_rate_hz, 0.2);
  const Eigen::VectorXd b = solid::ThresholdArrivals(ref, sample_rate_hz, 0.2);
  const double us = 1e6;  // per second
  TimingError e;
  e.arrival_us = (a - b).cwiseAbs().mean() * us;
  for (Eigen::Index i = 0; i < y.rows(); ++i)
    e.arrival_errors_us.push_back(std::abs(a[i] - b[i]) * us);
  int pairs = 0;
  for (Eigen::Index i = 0; i < y.rows(); ++i) {
    for (Eigen::Index j = i + 1; j < y.rows(); ++j) {
      const double d = std::abs((a[j] - a[i]) - (b[j] - b[i])) * us;
      e.delay_errors_us.push_back(d);
      e.delay_us += d;
      e.delay_max_us = std::max(e.delay_max_us, d);
      ++pairs;
    }
  }
  if (pairs > 0) e.delay_us /= pairs;
  // the same from aligned early wavefronts
  const Eigen::VectorXd shift = AlignedShifts(y, ref, sample_rate_hz, wavefront);
  for (Eigen::Index i = 0; i < y.rows(); ++i) {
    e.shift_errors_us.push_back(std::abs(shift[i]) * us);
    for (Eigen::Index j = i + 1; j < y.rows(); ++j)
      e.aligned_delay_errors_us.push_back(std::abs(shift[j] - shift[i]) * us);
  }
  return e;
}

namespace {

// (2 * half + 1) lags: sum over t of a(t) b(t - k), k = -half..half, over samples [0, n)
Eigen::VectorXd CrossCorrelation(const Eigen::RowVectorXd& a, const Eigen::RowVectorXd& b,
                                 int64_t n, int64_t half) {
  Eigen::VectorXd c = Eigen::VectorXd::Zero(2 * half + 1);
  for (int64_t k = -half; k <= half; ++k) {
    const int64_t lo = std::max<int64_t>(0, k), hi = std::min<int64_t>(n, n + k);
    for (int64_t t = lo; t < hi; ++t) c[k + half] += a[t] * b[t - k];
  }
  return c;
}

// c (2 * half + 1 integer lags from -half) at fractional lag x (samples): windowed-sinc
// interpolation over the `taps` nearest lags on either side (Hann window)
double InterpolateLag(const Eigen::VectorXd& c, int64_t half, double x, int64_t taps) {
  double sum = 0.0;
  const auto k0 = static_cast<int64_t>(std::floor(x));
  for (int64_t k = k0 - taps + 1; k <= k0 + taps; ++k) {
    if (k < -half || k > half) continue;
    const double d = x - static_cast<double>(k);
    const double sinc = d == 0.0 ? 1.0 : std::sin(kPi * d) / (kPi * d);
    const double window = 0.5 + 0.5 * std::cos(kPi * d / static_cast<double>(taps + 1));
    sum += c[k + half] * sinc * window;
  }
  return sum;
}

}  // namespace

Eigen::VectorXd AlignedShifts(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref,
                              double sample_rate_hz, const WavefrontWindow& wavefront) {
  SONICBOOM_DEMAND(y.rows() == ref.rows() && wavefront.samples > 0 && wavefront.max_lag_s > 0);
  const int64_t n = std::min<int64_t>({wavefront.samples, y.cols(), ref.cols()});
  const double bound = wavefront.max_lag_s * sample_rate_hz;  // samples
  const auto lags = static_cast<int64_t>(std::floor(bound));  // integer lags within it
  constexpr int64_t kTaps = 16;                               // interpolation: lags on either side
  constexpr int64_t kSteps = 64;                              // refinement: steps per sample
  const int64_t half = lags + 1 + kTaps;  // the integer lags the interpolation reads
  Eigen::VectorXd shift(y.rows());
  for (Eigen::Index ch = 0; ch < y.rows(); ++ch) {
    const Eigen::VectorXd c = CrossCorrelation(y.row(ch), ref.row(ch), n, half);
    // the best integer lag within the bound, then the best fraction within a sample of it
    int64_t best = -lags;
    for (int64_t k = -lags; k <= lags; ++k)
      if (c[k + half] > c[best + half]) best = k;
    double best_x = static_cast<double>(best), best_c = c[best + half];
    for (int64_t step = -kSteps; step <= kSteps; ++step) {
      const double x =
          std::clamp(static_cast<double>(best) + static_cast<double>(step) / kSteps, -bound, bound);
      const double v = InterpolateLag(c, half, x, kTaps);
      if (v > best_c) best_c = v, best_x = x;
    }
    shift[ch] = best_x / sample_rate_hz;
  }
  return shift;
}

Eigen::VectorXd OctaveEnergies(const Eigen::MatrixXd& y, double sample_rate_hz) {
  const std::vector<double> centres{250, 500, 1000, 2000, 4000, 8000, 16000};
  Eigen::VectorXd e = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(centres.size()));
  const Eigen::Index n = y.cols();
  for (Eigen::Index bin = 1; bin < n / 2; ++bin) {
    const double f = bin * sample_rate_hz / n;
    int band = -1;
    for (size_t b = 0; b < centres.size(); ++b) {
      if (f >= centres[b] / std::sqrt(2.0) && f < centres[b] * std::sqrt(2.0))
        band = static_cast<int>(b);
    }
    if (band < 0) continue;
    // one bin of every channel: rotate a unit phasor through the record
    const std::complex<double> step = std::polar(1.0, -2 * kPi * bin / n);
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      std::complex<double> acc = 0, w = 1;
      for (Eigen::Index k = 0; k < n; ++k) {
        acc += y(i, k) * w;
        w *= step;
      }
      e[band] += std::norm(acc);
    }
  }
  return e;
}

double BandEnergyErrorDb(const Eigen::VectorXd& e, const Eigen::VectorXd& ref) {
  const double floor = 1e-6 * ref.maxCoeff();
  double sum = 0;
  int bands = 0;
  for (Eigen::Index b = 0; b < ref.size(); ++b) {
    if (ref[b] <= floor) continue;
    sum += std::abs(10 * std::log10(std::max(e[b], 1e-300) / ref[b]));
    ++bands;
  }
  return bands > 0 ? sum / bands : 0.0;
}

Eigen::MatrixXd LowPass(const Eigen::MatrixXd& y, double cutoff_hz, double sample_rate_hz,
                        int64_t taps) {
  SONICBOOM_DEMAND(taps % 2 == 1 && cutoff_hz > 0 && cutoff_hz < 0.5 * sample_rate_hz);
  // the kernel (taps), centred: sinc at the cutoff under a Blackman window, unit DC gain
  const int64_t half = taps / 2;
  const double fc = cutoff_hz / sample_rate_hz;  // cycles per sample
  Eigen::VectorXd h(taps);
  for (int64_t k = -half; k <= half; ++k) {
    const double sinc = k == 0 ? 2 * fc : std::sin(2 * kPi * fc * k) / (kPi * k);
    const double x = static_cast<double>(k + half) / static_cast<double>(taps - 1);
    const double window = 0.42 - 0.5 * std::cos(2 * kPi * x) + 0.08 * std::cos(4 * kPi * x);
    h[k + half] = sinc * window;
  }
  h /= h.sum();
  // direct convolution, the kernel centred on each output sample
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(y.rows(), y.cols());
  for (Eigen::Index k = 0; k < y.cols(); ++k) {
    const Eigen::Index lo = std::max<Eigen::Index>(0, k - half);
    const Eigen::Index hi = std::min<Eigen::Index>(y.cols() - 1, k + half);
    for (Eigen::Index j = lo; j <= hi; ++j) out.col(k) += h[j - k + half] * y.col(j);
  }
  return out;
}

FrequencyError RankedFrequencyError(const Eigen::VectorXd& f_hz, const Eigen::VectorXd& ref_hz,
                                    double max_hz) {
  FrequencyError e;
  e.modes = (f_hz.array() <= max_hz).count();
  e.reference_modes = (ref_hz.array() <= max_hz).count();
  // both ascending: rank k of one against rank k of the other
  std::vector<double> rel;
  for (int64_t k = 0; k < std::min(e.modes, e.reference_modes); ++k) {
    rel.push_back(100.0 * std::abs(f_hz[k] / ref_hz[k] - 1.0));
  }
  if (rel.empty()) return e;
  e.max_pct = *std::max_element(rel.begin(), rel.end());
  std::nth_element(rel.begin(), rel.begin() + rel.size() / 2, rel.end());
  e.median_pct = rel[rel.size() / 2];
  return e;
}

}  // namespace sonicboom::experiments
