#include "sonicboom/solid/solid_response.h"

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {

Eigen::MatrixXd ForcedResponse(const Eigen::VectorXd& omega_rad_s, const Eigen::VectorXd& zeta,
                               const Eigen::MatrixXd& sensor_modal,
                               const Eigen::VectorXd& force_modal, std::span<const double> force_n,
                               int64_t first_sample, double sample_rate_hz, int64_t samples) {
  SONICBOOM_DEMAND(sensor_modal.cols() == omega_rad_s.size());
  SONICBOOM_DEMAND(force_modal.size() == omega_rad_s.size() && zeta.size() == omega_rad_s.size());
  SONICBOOM_DEMAND(first_sample >= 0 && samples >= 0);
  const double dt = 1.0 / sample_rate_hz;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(sensor_modal.rows(), samples);
  const int64_t force_end = first_sample + static_cast<int64_t>(force_n.size());
  // each mode q'' + 2 zeta w q' + w^2 q = f(t) as a complex one-pole: z = q' + (zeta w + i w_d) q
  // obeys z' = p z + f with p = -zeta w + i w_d; exact over a step for a held force. The sample
  // k reads the state at k dt, before its own force acts.
  for (Eigen::Index n = 0; n < omega_rad_s.size(); ++n) {
    SONICBOOM_DEMAND(zeta(n) >= 0.0 && zeta(n) < 1.0);
    const double w = omega_rad_s(n), wd = w * std::sqrt(1.0 - zeta(n) * zeta(n));
    const std::complex<double> p(-zeta(n) * w, wd);
    const std::complex<double> decay = std::exp(p * dt), gain = (decay - 1.0) / p;
    const Eigen::VectorXd read = sensor_modal.col(n) / wd;  // q = Im z / w_d (q, q' real)
    std::complex<double> z(0.0, 0.0);
    for (int64_t k = first_sample; k < samples; ++k) {
      out.col(k) += read * z.imag();
      const double f = k < force_end ? force_n[static_cast<size_t>(k - first_sample)] : 0.0;
      z = decay * z + gain * (force_modal(n) * f);
    }
  }
  return out;
}

Eigen::MatrixXd PulseResponse(const Eigen::VectorXd& omega_rad_s,
                              const Eigen::MatrixXd& sensor_modal,
                              const Eigen::VectorXd& force_modal,
                              const PulseResponseConfig& config) {
  const double dt = 1.0 / config.sample_rate_hz;
  const int64_t samples = static_cast<int64_t>(std::ceil(config.window_s / dt));
  // the force pulse (N), sampled at the middle of each step
  std::vector<double> force(static_cast<size_t>(samples), 0.0);
  for (int64_t k = 0; k < samples; ++k) {
    const double t = (k + 0.5) * dt;
    if (t < config.pulse_duration_s)
      force[static_cast<size_t>(k)] = std::sin(std::numbers::pi * t / config.pulse_duration_s);
  }
  // a sample reads the state after its own step, as the pulse's first sample is its first step
  const Eigen::MatrixXd y = ForcedResponse(
      omega_rad_s, Eigen::VectorXd::Constant(omega_rad_s.size(), 0.5 * config.loss_factor),
      sensor_modal, force_modal, force, 0, config.sample_rate_hz, samples + 1);
  return y.rightCols(samples);
}

Eigen::VectorXd ThresholdArrivals(const Eigen::MatrixXd& signals, double sample_rate_hz,
                                  double threshold) {
  Eigen::VectorXd t(signals.rows());
  for (Eigen::Index r = 0; r < signals.rows(); ++r) {
    const double level = threshold * signals.row(r).cwiseAbs().maxCoeff();
    t(r) = std::numeric_limits<double>::quiet_NaN();
    for (Eigen::Index k = 0; k < signals.cols(); ++k) {
      const double a = std::abs(signals(r, k));
      if (a >= level) {
        const double prev = k > 0 ? std::abs(signals(r, k - 1)) : 0.0;
        const double frac = a > prev ? (level - prev) / (a - prev) : 0.0;
        t(r) = (k - 1 + frac) / sample_rate_hz;
        break;
      }
    }
  }
  return t;
}

}  // namespace sonicboom::solid
