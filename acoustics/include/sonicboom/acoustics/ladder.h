#pragma once
/// The vibration ladder (docs/fidelity.md): the rungs that turn contact forces into sensor strain,
/// each on its own grid of the same seamed shell, so that a study can time every rung and compare
/// it with the finest one. A rung is built once (its modes solved or read from the cache, or its
/// FD operator set up) and rendered many times.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/fd_render.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// The damping every rung of a comparison shares: under shell.damping law, the Rayleigh curve
/// through the law at shell.loss_low_hz and loss_high_hz (what the FD rung realizes: the material's
/// loss_factor and the shell's loss_factor_high become the law's values there, damping rayleigh);
/// under damping rayleigh, unchanged. Rungs then differ in discretization and truncation alone.
void UseFdDamping(const TubeConfig& tube, MaterialConfig* material, ShellConfig* shell);

/// One rung: the model, its grid, and its truncation.
struct RungSpec {
  VibrationModel model{VibrationModel::kModal};  // modal, fd or modal-closed-form
  double arc_m{0.0025};                          // grid spacing around the tube
  double axial_m{0.005};                         // grid spacing along it
  double band_hz{0.0};    // modal: the modes below this; 0 = the strike's derived band
  int64_t mode_count{0};  // modal: the lowest N modes (overrides band_hz)
  bool residual{true};    // modal: the static residual of the modes left out
  double mode_band_hz{0.0};  // modal: modes solved to here; 0 = the ladder's full band
};

/// The configuration of the rung `spec` names on `base`: base's tube, material, mics, sample
/// rate, contact, decay floor and mode cache, its shell on spec's grid, modes solved to
/// spec.mode_band_hz or full_band_hz (the closed form's widest band), the configured structure
/// (no randomization),
/// the whole record rendered. An FD rung runs to the end of every render (decay floor -300 dB):
/// the ladder compares whole windows.
AcousticModelConfig RungConfig(const AcousticModelConfig& base, const RungSpec& spec,
                               double full_band_hz);

/// A rung made by the strike renderer's one factory (MakeVibrationRenderer) from
/// RungConfig(base, spec, full_band_hz), so the ladder times and measures exactly what
/// `generate` renders. Modal rungs read their modes from the mode cache when solved before.
/// Render is const.
class VibrationRung {
 public:
  /// Throws ConfigError for a bad grid or model (naming the key). A closed-form rung (the ideal
  /// simply supported tube, closed_form_bank.h) has no grid and no DOFs.
  VibrationRung(const AcousticModelConfig& base, const RungSpec& spec, double full_band_hz);
  ~VibrationRung();
  VibrationRung(const VibrationRung&) = delete;
  VibrationRung& operator=(const VibrationRung&) = delete;

  /// Sensor strain (mics x samples) of the forces from rest; a modal rung plays the modes its
  /// spec asks for, or those below derived_band_hz.
  Eigen::MatrixXd Render(std::span<const ForceInput> forces, int64_t samples,
                         double derived_band_hz) const;
  /// FD rungs only (Error otherwise): sensor strain (mics x samples) of impacts closed against
  /// the FD wall itself (fd_render.h; base's acoustics.contact), from rest.
  Eigen::MatrixXd RenderImpacts(std::span<const FdImpact> impacts, int64_t samples) const;
  /// The band a render plays: the spec's, or the strike's derived band.
  double PlayedBand(double derived_band_hz) const;
  /// Modes a render plays (0 for an FD rung).
  int64_t ModesPlayed(double derived_band_hz) const;
  /// The wall a contact sees at (z, theta) through the modes up to band_hz (modal rungs only;
  /// Error for an FD or closed-form rung).
  DrivingPoint WallAt(double z_m, double theta_rad, double band_hz) const;
  /// (modes) the modal rung's elastic mode frequencies as it plays them, ascending, Hz
  /// (shell.dispersion applied; empty for an FD rung).
  Eigen::VectorXd FrequenciesHz() const;
  /// (modes) the grid's frequencies as solved, ascending, Hz (empty for an FD rung and the
  /// closed form).
  Eigen::VectorXd GridFrequenciesHz() const;
  int64_t dofs() const;
  int64_t oversampling() const;  // FD steps per audio sample (0 for a modal rung)
  bool fd() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A strike's contact force against a modal rung's wall, as the production renderer solves it:
/// the Hertz stiffness of the striker on the tube, the wall's modes up to twice the strike's
/// Hertz-derived band, a rigid striker of contact.effective_mass_kg. Its derived band
/// (synth.band_factor over the solved first closure) is clipped to full_band_hz.
struct SolvedForce {
  ForceInput force;
  double derived_band_hz{0.0};
};
SolvedForce SolveRigidStrikeForce(const ContactEvent& contact, const VibrationRung& wall,
                                  const TubeConfig& tube, const MaterialConfig& material,
                                  const SynthConfig& synth, double sample_rate_hz,
                                  double full_band_hz);

/// The same strike as an impact an FD rung closes against its own wall: the striker's Hertz
/// stiffness on the tube, a rigid striker of contact.effective_mass_kg, the tube held.
FdImpact RigidStrikeImpact(const ContactEvent& contact, const TubeConfig& tube,
                           const MaterialConfig& material);

}  // namespace sonicboom::acoustics
