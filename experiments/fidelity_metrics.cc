#include "internal/fidelity_metrics.h"

#include <algorithm>
#include <limits>
#include <cmath>
#include <complex>
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
                          double sample_rate_hz) {
  // first arrivals (s): 20 % of each channel's own peak, as the reference command reads them
  const Eigen::VectorXd a = solid::ThresholdArrivals(y, sample_rate_hz, 0.2);
  const Eigen::VectorXd b = solid::ThresholdArrivals(ref, sample_rate_hz, 0.2);
  const double us = 1e6;  // per second
  TimingError e;
  e.arrival_us = (a - b).cwiseAbs().mean() * us;
  for (Eigen::Index i = 0; i < y.rows(); ++i) e.arrival_errors_us.push_back(std::abs(a[i] - b[i]) * us);
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
  return e;
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
