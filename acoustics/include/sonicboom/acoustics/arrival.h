#pragma once
/// A training-free arrival-time locator (docs/baselines.md): the physical floor that a learned
/// model must beat on structures it was not trained on.
///
/// Each channel is high-passed (its low band carries hum, motor tones and the slow modes that
/// differ most between structures) and its first arrival picked: the first sample, in a window
/// around the record's onset, whose magnitude exceeds both `noise_sigmas` times the channel's
/// pre-onset rms and `peak_fraction` of its own peak in the window (a per-channel level, so a
/// channel's gain or bonding does not move it). A contact at (z, theta) then predicts arrivals
/// t_k = t0 + d_k(z, theta) / c, with d_k the shortest surface path to microphone k (seams
/// crossed only at bolts, as the TDOA locator's). Over a grid of the contact region, t0 and the
/// slowness 1/c are fitted by least squares (1/c kept within a physical range), and the point
/// with the smallest residual wins. Nothing is fitted to labels: the locator needs the tube's
/// geometry and microphone positions only, not its material.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "sonicboom/acoustics/tdoa.h"
#include "sonicboom/core/archive.h"

namespace sonicboom::acoustics {

/// Picking and search settings; keys under "arrival".
struct ArrivalConfig {
  double highpass_hz{2000.0};  // second-order Butterworth high-pass before picking
  double pre_onset_s{0.004};   // picking window around the record's onset
  double post_onset_s{0.006};
  double noise_window_s{0.05};  // pre-onset noise estimate ends where the window starts
  double noise_sigmas{5.0};     // arrival: above this many noise rms ...
  double peak_fraction{0.2};    // ... and above this fraction of the channel's peak (chosen on a
                                // validation set: scripts/arrival_sweep.sh)
  double min_speed_m_s{150.0};  // fitted wave speed kept in [min, max]
  double max_speed_m_s{3000.0};
  double grid_z_step_m{0.001};
  double grid_theta_step_deg{1.0};

  void Serialize(Archive* a);
  /// Throws ConfigError naming the field as "arrival.<field>".
  void Validate(double sample_rate_hz) const;
};

/// One strike's picks and the located point.
struct ArrivalEstimate {
  std::vector<double> arrival_s;  // (mics) first arrival from the window start, s
  double z_m{0.0};
  double theta_rad{0.0};
  double speed_m_s{0.0};   // fitted wave speed at the estimate
  double residual_s{0.0};  // rms of the arrival-time residuals at the estimate
};

/// Immutable (path tables per grid point precomputed); Locate is const and thread-safe.
class ArrivalLocator {
 public:
  ArrivalLocator(const TdoaGeometry& geometry, const ArrivalConfig& config, double sample_rate_hz);
  ~ArrivalLocator();
  ArrivalLocator(const ArrivalLocator&) = delete;
  ArrivalLocator& operator=(const ArrivalLocator&) = delete;

  /// First arrival of every channel of a (mics x T) record around onset_sample (the record's
  /// all-channel onset, DetectOnset), s from the picking window's start.
  std::vector<double> PickArrivals(const Eigen::MatrixXf& record, int64_t onset_sample) const;
  /// The grid point whose predicted arrivals fit the picks best.
  ArrivalEstimate Locate(const std::vector<double>& arrival_s) const;
  /// PickArrivals, then Locate.
  ArrivalEstimate Locate(const Eigen::MatrixXf& record, int64_t onset_sample) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::acoustics
