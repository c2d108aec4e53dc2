#pragma once
/// Strike audio: Hertz contact force -> modal tube vibration -> piezo strain at six discs
/// -> disc/preamp high-pass, gain mismatch, noise -> 24-bit ADC with clipping -> 16-bit output.
/// The model (modes, sensor gains, filters) is built once and shared across threads; Render
/// is const and depends only on its inputs and the sample seed.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/daq.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// The band derived from a contact (acoustics.band_factor, docs/acoustics.md), Hz: band_factor
/// times the first spectral minimum of the contact force, about 1.8 / t_c for a first closure of
/// t_c s. The one rule every renderer and study uses; callers clip it to the modes they have.
inline double ContactBandHz(double band_factor, double first_closure_s) {
  return band_factor * 1.8 / first_closure_s;
}

/// The vibration model. modal: the discretized shell's numerical modes (shell.h), the production
/// rung; fd: the finite-difference solver of the same shell, the cross-check (it closes its own
/// impacts and needs no modes, fd_render.h); modal-closed-form:
/// ideal simply-supported tube, Flügge modes (the first rung, no seam).
enum class VibrationModel { kModal, kFd, kModalClosedForm };
inline constexpr EnumName<VibrationModel> kVibrationModelNames[] = {
    {VibrationModel::kModal, "modal"},
    {VibrationModel::kFd, "fd"},
    {VibrationModel::kModalClosedForm, "modal-closed-form"}};
inline std::span<const EnumName<VibrationModel>> EnumNames(VibrationModel) {
  return kVibrationModelNames;
}

/// How much of the record the vibration is rendered over. record: all of it; features: only as
/// long after the first contact as the features read (SynthConfig::span_after_contact_s, derived
/// from the features' window by the pipeline), then faded out over kSpanFadeS and silent (the
/// sensor chain's noise runs on).
enum class RenderSpan { kRecord, kFeatures };
inline constexpr EnumName<RenderSpan> kRenderSpanNames[] = {{RenderSpan::kRecord, "record"},
                                                            {RenderSpan::kFeatures, "features"}};
inline std::span<const EnumName<RenderSpan>> EnumNames(RenderSpan) {
  return kRenderSpanNames;
}
/// The fade that ends a span shorter than the record, s (raised cosine).
inline constexpr double kSpanFadeS = 0.002;

/// Vibration model fidelity: the rung of the ladder (docs/fidelity.md). Keys under "acoustics".
struct SynthConfig {
  VibrationModel model{VibrationModel::kModal};
  double max_frequency_hz{0.0};   // mode band; 0 = derive from the contact (and Nyquist)
  int64_t mode_count{0};          // modal: play the lowest N modes (overrides the band)
  double band_factor{8.0};        // auto band = band_factor x first spectral minimum (1.8 / t_c);
                                  // 8 keeps the arrival-time cues (docs/fidelity.md)
  double decay_floor_db{-100.0};  // a mode (the FD run) stops once it decayed this far
  int64_t force_substeps{8};      // modal-closed-form: force averaged over this many points
  bool residual{true};            // modal: static part of the modes above the band
  double mode_band_hz{0.0};  // modes solved (and cached) up to here; 0 = min(20 kHz, 0.95 Nyquist)
  int64_t fd_oversampling{0};  // fd: steps per audio sample; 0 = smallest stable
  std::string mode_cache_dir;  // "" = $SONICBOOM_CACHE_DIR or ~/.cache/sonicboom/modes
  ContactConfig contact;       // the striker-tube contact solve
  RenderSpan render_span{RenderSpan::kRecord};
  // derived, not a key: with render_span = features, the vibration is rendered this long after
  // the first contact (then faded out over kSpanFadeS), s
  double span_after_contact_s{0.0};

  void Serialize(Archive* a);

  /// The band the shell's modes are solved to: mode_band_hz, or by default what the grid
  /// resolves (20 kHz) below 0.95 of the Nyquist frequency of sample_rate_hz.
  double ModeBandHz(double sample_rate_hz) const;
  /// The mode cache: mode_cache_dir, or DefaultModeCacheDir() (shell_modes.h) when empty.
  std::string ModeCacheDir() const;
};

/// Everything the strike renderer depends on.
struct AcousticModelConfig {
  TubeConfig tube;
  MaterialConfig material;
  MicArrayConfig mics;
  AudioConfig audio;
  ShellConfig shell;
  SynthConfig synth;
  DaqConfig daq;
  NoiseConfig noise;
  RandomizeConfig randomize;  // the structure pool and the placement margin
  uint64_t seed{0};           // global seed: the structure pool's draws
};

/// The band the modal rung solves its modes to, Hz, from the acoustics keys, the sample rate and
/// the randomize ranges: acoustics.mode_band_hz when set;
/// else, for a fixed acoustics.max_frequency_hz and no draw that moves modes (no material or
/// structure ranges), 1.25 x that band (the dispersion correction's headroom): nothing above a
/// fixed band is played, neither in the signal nor in the contact's wall, and the residual stands
/// for the rest; else SynthConfig::ModeBandHz.
double SolvedModeBandHz(const SynthConfig& synth, double sample_rate_hz,
                        const RandomizeConfig& randomize);

/// The Hertz impact of a striker on the wall (rigid target): docs/physics.md, "Hertz impact".
struct HertzImpact {
  double stiffness_n_m15{0.0};  // K in F = K delta^1.5
  double max_compression_m{0.0};
  double peak_force_n{0.0};
  double duration_s{0.0};
  double impulse_ns{0.0};  // 0.5436 F_max t_c
};
HertzImpact SolveHertzImpact(const ContactEvent& contact, const TubeConfig& tube,
                             const MaterialConfig& material);
/// Force of that impact at time t after first touch (F_max sin^1.5(pi t / t_c)), N.
double HertzForce(const HertzImpact& impact, double t_s);

/// Result of rendering one strike.
struct RenderedStrike {
  Eigen::MatrixXf audio;  // (mics x T), full scale 1, quantized to output_bits
  bool clipped{false};
  double impulse_ns{0.0};  // of the first (localized) contact
  double duration_s{0.0};
  double peak_force_n{0.0};
  int64_t touches{0};   // closures of the first contact (> 1: chatter)
  double band_hz{0.0};  // mode band used (modal rungs)
  int64_t modes_used{0};
  int64_t forces_played{0};  // impacts, bounces, presses and brushes rendered
  double vibration_s{0.0};   // wall time of the vibration model alone, s
};

/// Immutable acoustic model of one tube + sensor set-up, shared across threads; Render is const
/// and depends only on its inputs and the sample seed. Building a modal model solves (or reads
/// from the cache) the shell's modes once; an fd model sets up its grid's operator.
class StrikeSynthesizer {
 public:
  explicit StrikeSynthesizer(const AcousticModelConfig& config);
  ~StrikeSynthesizer();
  StrikeSynthesizer(const StrikeSynthesizer&) = delete;
  StrikeSynthesizer& operator=(const StrikeSynthesizer&) = delete;

  /// Renders one record: the first hard contact, plus every other episode of the record
  /// (bounces and impacts by the contact solve, presses as their mean force, foliage brushes as
  /// a rustle force; the episode at the first contact's time is that contact). joint_speed_rad_s
  /// is sampled at joint_speed_rate_hz from the record start. variation: this sample's
  /// randomized structure, striker and sensor chain (randomize.h); null = as configured. Its
  /// material part needs the modal rung (ConfigError otherwise).
  RenderedStrike Render(const ContactEvent& contact, std::span<const ContactEpisode> episodes,
                        std::span<const double> joint_speed_rad_s, double joint_speed_rate_hz,
                        uint64_t sample_seed, const Variation* variation = nullptr) const;
  /// The first contact alone.
  RenderedStrike Render(const ContactEvent& contact, std::span<const double> joint_speed_rad_s,
                        double joint_speed_rate_hz, uint64_t sample_seed) const {
    return Render(contact, {}, joint_speed_rad_s, joint_speed_rate_hz, sample_seed);
  }

  /// Modes in the model's widest band (for inspection).
  int64_t mode_count() const;
  /// Variants of the structure pool (randomize.structure_variants), and the drawn values of one
  /// (StructureValueNames' order).
  int64_t structure_variants() const;
  const std::vector<double>& StructureValues(int64_t variant) const;
  /// The modal rung's band for a first contact of duration t_c (what Render derives), Hz.
  double BandFor(double contact_duration_s) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::acoustics
