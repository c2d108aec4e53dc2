#pragma once
/// The reference model's own synthesis: the sensor strains of a force pulse at one point, summed
/// over modes with a constant loss factor per mode, and the first-arrival times read from them.

#include <Eigen/Core>
#include <cstdint>
#include <span>

namespace sonicboom::solid {

struct PulseResponseConfig {
  double pulse_duration_s{2.5e-4};  // half-sine force pulse, 1 N peak
  double sample_rate_hz{1.0e6};     // evaluation rate (well above the modes: timing to 1 us)
  double window_s{0.003};           // response length after the pulse starts
  double loss_factor{0.02};         // eta of every mode (damping ratio eta / 2)
};

/// (sensors x samples) strain at each sensor for the pulse applied at the point whose modal
/// amplitudes are `force_modal` (modes): sensor_modal (sensors x modes) holds each sensor's
/// read-out of each mass-normalized shape; omega (modes) in rad/s. Each mode is integrated exactly
/// for a force held constant over a sample (zero-order hold at sample_rate_hz).
Eigen::MatrixXd PulseResponse(const Eigen::VectorXd& omega_rad_s,
                              const Eigen::MatrixXd& sensor_modal,
                              const Eigen::VectorXd& force_modal,
                              const PulseResponseConfig& config);

/// (sensors x samples) strain at each sensor for a force given sample by sample (N, each held
/// over its sample, zero-order hold) from first_sample on, at sample_rate_hz, from rest. omega
/// (modes) rad/s, zeta (modes) damping ratio of each mode (< 1), sensor_modal (sensors x modes)
/// each sensor's read-out of each mass-normalized shape, force_modal (modes) each shape's drive
/// per newton of the force. Exact for each mode; every mode rings to the end of the record.
Eigen::MatrixXd ForcedResponse(const Eigen::VectorXd& omega_rad_s, const Eigen::VectorXd& zeta,
                               const Eigen::MatrixXd& sensor_modal,
                               const Eigen::VectorXd& force_modal, std::span<const double> force_n,
                               int64_t first_sample, double sample_rate_hz, int64_t samples);

/// (rows) first time (s) each row of `signals` reaches `threshold` of its own peak magnitude,
/// linearly interpolated between samples.
Eigen::VectorXd ThresholdArrivals(const Eigen::MatrixXd& signals, double sample_rate_hz,
                                  double threshold);

}  // namespace sonicboom::solid
