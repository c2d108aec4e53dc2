#pragma once
/// The closed-form rung (acoustics.model = modal-closed-form): the modes of an ideal simply
/// supported thin tube by Flügge's equations (cylinder_modes.h), with no seam, holes, bolts or
/// mounts, as a bank that renders disc strain from contact forces. Built once, rendered many
/// times; Render is const.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

class ClosedFormBank {
 public:
  /// The modes up to band_hz (radial modes only: a normal force excites no other), each damped
  /// by material.loss_factor / 2, played until decayed by |decay_floor_db|.
  ClosedFormBank(const TubeConfig& tube, const MaterialConfig& material, const MicArrayConfig& mics,
                 double sample_rate_hz, double band_hz, double decay_floor_db);

  /// (mics x samples) disc strain of `forces` (positive inward) from rest, the modes at or below
  /// band_hz; *modes_used (optional) counts the mode families played.
  Eigen::MatrixXd Render(std::span<const ForceInput> forces, double band_hz, int64_t samples,
                         int64_t* modes_used = nullptr) const;

  /// (modes) frequencies of the modes at or below band_hz, ascending, Hz; a pair (n >= 1) is
  /// listed twice, as the two modes it is.
  Eigen::VectorXd FrequenciesHz(double band_hz) const;
  /// Mode families held ((m, n) with its degenerate pair counted once).
  int64_t families() const { return static_cast<int64_t>(modes_.size()); }

 private:
  // one mode family: recursion pole, drive and sensor factors
  struct Mode {
    double frequency_hz;
    double pole_re, pole_im;  // exp((-sigma + i omega_d) T)
    double decay_per_sample;  // sigma T
    double response_scale;    // T / (omega_d M)
    double wavenumber_m;      // k = m pi / L
    int n;
    double drive_w;             // W: radial part of the shape
    double strain_factor;       // surface strain per unit modal amplitude, aperture included
    Eigen::VectorXd mic_axial;  // (mics) sin(k x_i)
  };
  double half_length_m_;
  double floor_ln_;                // |decay_floor_db| in nepers
  Eigen::VectorXd mic_theta_rad_;  // (mics)
  std::vector<Mode> modes_;        // ascending frequency
};

}  // namespace sonicboom::acoustics
