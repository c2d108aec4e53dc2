#pragma once
// The stages of one strike's render (StrikeSynthesizer::Render): the sample's draws applied once
// into a SampleView -> excitation (the record's episodes as wall forces, each impact solved
// against the wall of the rung that renders) -> a VibrationRenderer, one class per rung of the
// ladder, made by MakeVibrationRenderer -> the DAQ chain. Private to acoustics/.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/fd_render.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/synth.h"

namespace sonicboom::acoustics {

/// One sample as every stage reads it: its draws (the configured set-up when it has none) and
/// what they make of the first contact and the tube's material. Made once per sample, up front.
struct SampleView {
  const StructureDraw& structure;
  const StrikerDraw& striker;
  const ChainDraw& chain;
  ContactEvent contact;    // the first contact under the striker draw
  MaterialConfig material; // the tube's material under the structure draw
  HertzImpact impact;      // the rigid-wall Hertz impact of that contact (the first guess)
  int64_t frames{0};       // audio frames rendered from the record's start (the span)
  double end_s{0.0};       // the span's end from the record's start, s: later episodes are silent

  /// The view of `draws` (null: the configured set-up) for a first contact; throws
  /// NumericalError when the contact has no finite Hertz duration.
  static SampleView Of(const Variation* draws, const ContactEvent& first,
                       const AcousticModelConfig& config);
};

/// The lowest band a rung plays, Hz: a band below it holds no more than the tube's lowest ring
/// modes and no wavefront to time (on the default tube Rayleigh's n = 2, 3 rings lie near 0.22
/// and 0.62 kHz, n = 4 at 1.19 kHz; docs/robustness.md, "Bounds from physics"). A fixed band
/// below it is refused; a band derived from a long contact is raised to it.
inline constexpr double kLowestBandHz = 1000.0;

/// The band a rung plays for a first closure (ContactBandHz, clipped to what the rung has, and
/// at least kLowestBandHz).
struct BandRule {
  double limit_hz{0.0};      // max_frequency_hz, or 0.95 Nyquist
  double mode_band_hz{0.0};  // modes solved to here (modal); 0: none solved (closed form, fd)
  bool fixed{false};         // max_frequency_hz set: the limit, whatever the contact
  double band_factor{8.0};

  /// Hz, for a first closure of t_c s on a structure whose frequencies are scaled by
  /// frequency_scale (1: as solved).
  double operator()(double contact_duration_s, double frequency_scale = 1.0) const;
};

/// The forces a record puts on the wall.
struct Excitation {
  std::vector<ForceInput> forces;    // prescribed: solved impacts, presses, rustles
  std::vector<FdImpact> fd_impacts;  // impacts left to the FD run, which closes them itself
  ContactForce first;  // the first contact's force (its rigid-wall duration while pending)
};

/// How a rung's wall meets an impact.
struct ExcitationWall {
  // the wall's modes at (z, theta) to band_hz (a coupled contact on a modal wall); null: the
  // wall is held (acoustics.contact.wall = rigid) or the rung closes its impacts itself
  std::function<DrivingPoint(double z_m, double theta_rad, double band_hz)> modes_at;
  bool closes_impacts{false};      // the FD run closes the impacts against its own grid
  const ShellModel* shell{nullptr};  // brushes in a hole are not played; null: no holes
  double contact_band_hz{0.0};     // the band of the walls' modes
};

/// The excitation stage: the first contact, then every other episode of the record (bounces and
/// later impacts by the contact solve, presses as their mean force, foliage brushes as a rustle
/// force drawn from the sample seed).
Excitation Excite(const AcousticModelConfig& config, const SampleView& view,
                  std::span<const ContactEpisode> episodes, uint64_t sample_seed,
                  const ExcitationWall& wall);

/// One rung of the ladder: from a sample's contacts to disc strain.
class VibrationRenderer {
 public:
  virtual ~VibrationRenderer() = default;
  /// Disc strain (mics x frames) of the sample, and its contact's figures, band and modes in
  /// *out. Throws ConfigError when the rung cannot play the view's structure.
  virtual Eigen::MatrixXd Play(const SampleView& view, std::span<const ContactEpisode> episodes,
                               uint64_t sample_seed, RenderedStrike* out) const = 0;
  /// Modes in the rung's widest band (0 for the FD grid).
  virtual int64_t mode_count() const = 0;

  // Prescribed forces, for the fidelity ladder (ladder.h), which compares rungs on one set of
  // forces solved once: the configured structure, no excitation stage.
  /// Disc strain (mics x frames) of `forces` from rest, the modes at or below band_hz played
  /// (or acoustics.mode_count of them); the FD grid plays everything it resolves.
  virtual Eigen::MatrixXd PlayForces(std::span<const ForceInput> forces, double band_hz,
                                     int64_t frames) const = 0;
  /// The modes PlayForces plays for band_hz (0 for the FD grid).
  virtual int64_t ModesPlayed(double band_hz) const = 0;
  /// FD only (Error otherwise): disc strain (mics x frames) of impacts closed against the grid.
  virtual Eigen::MatrixXd PlayImpacts(std::span<const FdImpact> impacts, int64_t frames) const;
  /// Modal only (Error otherwise): the wall a contact sees at (z, theta) to band_hz.
  virtual DrivingPoint WallAt(double z_m, double theta_rad, double band_hz) const;
  /// (modes) the frequencies the rung plays in its widest band, ascending, Hz (shell.dispersion
  /// applied; empty for the FD grid).
  virtual Eigen::VectorXd FrequenciesHz() const { return {}; }
  /// (modes) the same as the grid solved them, before a dispersion correction (empty for the FD
  /// grid and the closed form).
  virtual Eigen::VectorXd GridFrequenciesHz() const { return {}; }
  virtual int64_t dofs() const { return 0; }
  /// FD time steps per audio sample (0: not stepped).
  virtual int64_t oversampling() const { return 0; }
  const BandRule& band() const { return band_; }
  /// The structure pool (randomize.structure_variants; the modal rung alone has one).
  virtual int64_t structure_variants() const { return 0; }
  virtual const std::vector<double>& StructureValues(int64_t variant) const;

 protected:
  explicit VibrationRenderer(const BandRule& band) : band_(band) {}
  BandRule band_;
};

/// The one factory: the rung acoustics.model names, set up for the config (modes solved or read
/// from the cache, the FD operator, the structure pool). Throws ConfigError naming the key of a
/// setting the rung cannot follow.
std::unique_ptr<VibrationRenderer> MakeVibrationRenderer(const AcousticModelConfig& config);

}  // namespace sonicboom::acoustics
