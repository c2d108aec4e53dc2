#pragma once
/// The production modal rung: a bank of the discretized shell's numerical modes (shell_modes.h),
/// prepared once for a microphone array and the audio rate, that renders many strikes fast.
/// Every mode is a complex one-pole recursion z[k] = p z[k-1] + u[k] (impulse invariance: u is the
/// impulse the mode receives in sample k, state in double); the six outputs are a matrix product
/// of the mode states, block by block; a mode stops once it decayed by decay_floor_db, and since
/// Rayleigh decay grows with frequency the live modes are always a prefix of the bank. Modes above
/// the strike's band are restored by their static part (residual flexibility) at the sensors.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// One radial force on the tube: audio-rate samples (area-averaged over each sample, N) from
/// first_sample on, at (z, theta) of the tube frame; positive pushes the wall inward.
struct ForceInput {
  double z_m{0.0};
  double theta_rad{0.0};
  int64_t first_sample{0};
  std::vector<double> force_n;
};

/// Mode shapes at a subset of the DOFs: what a bank reads (ShellModalBank::RowsRead), so that a
/// structure variant never needs its shapes at every DOF.
struct ModeRows {
  Eigen::VectorXd omega_rad_s;  // (modes) ascending
  int64_t rigid_body_modes{0};
  std::vector<int64_t> dofs;  // ascending DOF of every row
  Eigen::MatrixXd shapes;     // (rows x modes) mass-normalized
  /// The rows of full modes (with shapes) at `dofs`.
  static ModeRows Of(const ShellModes& modes, std::vector<int64_t> dofs);
};

class ShellModalBank {
 public:
  /// modes: mass-normalized shapes of `model` (with_shapes). residual: restore the static part of
  /// the modes left out (needs a structure without rigid-body modes; ignored otherwise).
  /// placement_margin_m > 0 keeps the shapes around every disc, so that a variation may move a
  /// disc by up to that much (arc length or axial; the diameter may grow by twice that) without
  /// a new bank; the residual keeps the configured placement.
  ShellModalBank(const ShellModel& model, const ShellModes& modes, const MicArrayConfig& mics,
                 double sample_rate_hz, double decay_floor_db, bool residual,
                 double placement_margin_m = 0.0);
  /// The same from the shapes at the rows it reads (RowsRead of the same model, mics and margin,
  /// or a superset); a missing row is an Error.
  ShellModalBank(const ShellModel& model, const ModeRows& modes, const MicArrayConfig& mics,
                 double sample_rate_hz, double decay_floor_db, bool residual,
                 double placement_margin_m = 0.0);
  ~ShellModalBank();
  /// The DOFs whose rows of the mode shapes a bank of this model, array and margin reads
  /// (radial DOFs, and every DOF a disc reads), ascending: the rest may be left out (zero).
  static std::vector<int64_t> RowsRead(const ShellModel& model, const MicArrayConfig& mics,
                                       double placement_margin_m);
  ShellModalBank(const ShellModalBank&) = delete;
  ShellModalBank& operator=(const ShellModalBank&) = delete;

  int64_t modes() const;
  double max_frequency_hz() const;
  /// (modes) the frequencies the bank plays, ascending, Hz (shell.dispersion applied).
  const Eigen::VectorXd& frequencies_hz() const;
  /// Number of bank modes with frequency <= band_hz.
  int64_t ModesBelow(double band_hz) const;
  /// The wall seen at (z, theta) by a contact: modes up to band_hz (rigid part: held).
  /// structure: this sample's draw (randomize.h): a scaled modulus and density and its loss law,
  /// exact for the same geometry and Poisson ratio; a Nominal() one plays the modes as solved.
  DrivingPoint WallAt(double z_m, double theta_rad, double band_hz,
                      const StructureDraw& structure = {}) const;
  /// Sensor strain (mics x samples) of the structure from rest under the forces, using the
  /// lowest `mode_count` modes (plus the residual of the rest when enabled).
  Eigen::MatrixXd Render(std::span<const ForceInput> forces, int64_t mode_count, int64_t samples,
                         const StructureDraw& structure = {}) const;
  /// ModesBelow for the drawn structure (its frequencies scaled).
  int64_t ModesBelow(double band_hz, const StructureDraw& structure) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::acoustics
