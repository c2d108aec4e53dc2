#include "sonicboom/solid/solid_response.h"

#include <cmath>
#include <complex>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {

Eigen::MatrixXd PulseResponse(const Eigen::VectorXd& omega_rad_s,
                              const Eigen::MatrixXd& sensor_modal,
                              const Eigen::VectorXd& force_modal,
                              const PulseResponseConfig& config) {
  SONICBOOM_DEMAND(sensor_modal.cols() == omega_rad_s.size());
  SONICBOOM_DEMAND(force_modal.size() == omega_rad_s.size());
  const double dt = 1.0 / config.sample_rate_hz;
  const Eigen::Index samples = static_cast<Eigen::Index>(std::ceil(config.window_s / dt));
  // the force pulse (N), sampled at the middle of each step
  Eigen::VectorXd force = Eigen::VectorXd::Zero(samples);
  for (Eigen::Index k = 0; k < samples; ++k) {
    const double t = (k + 0.5) * dt;
    if (t < config.pulse_duration_s)
      force(k) = std::sin(std::numbers::pi * t / config.pulse_duration_s);
  }
  // each mode q'' + 2 zeta w q' + w^2 q = f(t) as a complex one-pole: z = q' + (zeta w + i w_d) q
  // obeys z' = p z + f with p = -zeta w + i w_d; exact over a step for a held force
  Eigen::MatrixXd modal_q(omega_rad_s.size(), samples);
  const double zeta = 0.5 * config.loss_factor;
  for (Eigen::Index n = 0; n < omega_rad_s.size(); ++n) {
    const double w = omega_rad_s(n), wd = w * std::sqrt(1.0 - zeta * zeta);
    const std::complex<double> p(-zeta * w, wd);
    const std::complex<double> decay = std::exp(p * dt), gain = (decay - 1.0) / p;
    std::complex<double> z(0.0, 0.0);
    for (Eigen::Index k = 0; k < samples; ++k) {
      z = decay * z + gain * (force_modal(n) * force(k));
      modal_q(n, k) = z.imag() / wd;  // q and q' are real
    }
  }
  return sensor_modal * modal_q;
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
