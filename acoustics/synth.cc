#include "sonicboom/acoustics/synth.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "internal/render_stages.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// the default grid (2.5 mm) has >= 6 points per bending wavelength up to about here
constexpr double kDefaultModeBandHz = 20000.0;

}  // namespace

double SynthConfig::ModeBandHz(double sample_rate_hz) const {
  return mode_band_hz > 0 ? mode_band_hz
                          : std::min(0.95 * 0.5 * sample_rate_hz, kDefaultModeBandHz);
}

double SolvedModeBandHz(const SynthConfig& s, double sample_rate_hz,
                        const RandomizeConfig& randomize) {
  const double band = s.ModeBandHz(sample_rate_hz);
  const bool drawn = randomize.material() || randomize.structure();
  if (s.mode_band_hz > 0 || !(s.max_frequency_hz > 0) || drawn) return band;
  // the thick-plate correction carries a grid mode down by less than 20 % below 20 kHz
  // (docs/shell.md, "Dispersion"): the modes solved to 1.25 x the band hold every mode it plays
  constexpr double kCorrectionHeadroom = 1.25;
  return std::min(band, kCorrectionHeadroom * s.max_frequency_hz);
}

std::string SynthConfig::ModeCacheDir() const {
  return mode_cache_dir.empty() ? DefaultModeCacheDir() : mode_cache_dir;
}

void SynthConfig::Serialize(Archive* a) {
  a->Visit("model", &model);
  a->Visit("max_frequency_hz", &max_frequency_hz, Bounds::NonNegative());
  a->Visit("mode_count", &mode_count, Bounds::Closed(0, 20000));
  a->Visit("band_factor", &band_factor, Bounds::Open(0.0, 100.0));
  a->Visit("decay_floor_db", &decay_floor_db, Bounds::Open(-300.0, 0.0));
  a->Visit("force_substeps", &force_substeps, Bounds::Closed(1, 1024));
  a->Visit("residual", &residual);
  a->Visit("mode_band_hz", &mode_band_hz, Bounds::NonNegative());
  a->Visit("fd_oversampling", &fd_oversampling, Bounds::Closed(0, 4096));
  a->Visit("mode_cache_dir", &mode_cache_dir);
  a->Visit("contact", &contact);
  a->Visit("render_span", &render_span);
}

HertzImpact SolveHertzImpact(const ContactEvent& contact, const TubeConfig& tube,
                             const MaterialConfig& material) {
  // effective modulus and radius of a rod crossing the tube (crossed cylinders, R_e = sqrt(R1 R2))
  const double inv_e =
      (1 - material.poisson_ratio * material.poisson_ratio) / material.youngs_modulus_pa +
      (1 - contact.striker_poisson_ratio * contact.striker_poisson_ratio) /
          contact.striker_youngs_modulus_pa;
  const double e_star = 1.0 / inv_e;
  const double r_e = std::sqrt(contact.striker_radius_m * tube.outer_radius_m);
  HertzImpact impact;
  impact.stiffness_n_m15 = 4.0 / 3.0 * e_star * std::sqrt(r_e);
  const double m = contact.effective_mass_kg, v = contact.normal_speed_m_s;
  impact.max_compression_m = std::pow(5 * m * v * v / (4 * impact.stiffness_n_m15), 0.4);
  impact.peak_force_n = impact.stiffness_n_m15 * std::pow(impact.max_compression_m, 1.5);
  impact.duration_s = 2.9432 * impact.max_compression_m / v;
  impact.impulse_ns = 0.5436 * impact.peak_force_n * impact.duration_s;
  return impact;
}

double HertzForce(const HertzImpact& impact, double t_s) {
  if (t_s <= 0.0 || t_s >= impact.duration_s) return 0.0;
  return impact.peak_force_n * std::pow(std::sin(kPi * t_s / impact.duration_s), 1.5);
}

namespace {

// strain rendered over the first `span` frames of the record: faded out over the span's last
// kSpanFadeS (raised cosine) and silent to the record's end
void EndSpan(int64_t span, const AudioConfig& audio, Eigen::MatrixXd* strain) {
  const int64_t frames = audio.num_samples();
  if (span >= frames) return;
  SONICBOOM_DEMAND(strain->cols() == span);
  const int64_t fade = std::min<int64_t>(span, std::llround(kSpanFadeS * audio.sample_rate_hz));
  for (int64_t k = 0; k < fade; ++k) {
    const double w = 0.5 - 0.5 * std::cos(kPi * (k + 0.5) / fade);  // 0 -> 1 towards the start
    strain->col(span - 1 - k) *= w;
  }
  strain->conservativeResize(Eigen::NoChange, frames);
  strain->rightCols(frames - span).setZero();
}

}  // namespace

struct StrikeSynthesizer::Impl {
  AcousticModelConfig c;
  std::unique_ptr<DaqChain> daq;
  std::unique_ptr<VibrationRenderer> rung;
};

StrikeSynthesizer::StrikeSynthesizer(const AcousticModelConfig& config)
    : impl_(std::make_unique<Impl>()) {
  config.tube.Validate();
  config.mics.Validate(config.tube);
  impl_->c = config;
  impl_->daq = std::make_unique<DaqChain>(config.daq, config.noise, config.mics.count(),
                                          config.audio.sample_rate_hz, config.audio.num_samples());
  impl_->rung = MakeVibrationRenderer(config);
}

StrikeSynthesizer::~StrikeSynthesizer() = default;

int64_t StrikeSynthesizer::structure_variants() const {
  return impl_->rung->structure_variants();
}

const std::vector<double>& StrikeSynthesizer::StructureValues(int64_t variant) const {
  return impl_->rung->StructureValues(variant);
}

int64_t StrikeSynthesizer::mode_count() const {
  return impl_->rung->mode_count();
}

double StrikeSynthesizer::BandFor(double contact_duration_s) const {
  return impl_->rung->band()(contact_duration_s);
}

RenderedStrike StrikeSynthesizer::Render(const ContactEvent& contact,
                                         std::span<const ContactEpisode> episodes,
                                         std::span<const double> joint_speed_rad_s,
                                         double joint_speed_rate_hz, uint64_t sample_seed,
                                         const Variation* variation) const {
  const Impl& m = *impl_;
  // the sample's draws, applied once: every stage reads this view
  const SampleView view = SampleView::Of(variation, contact, m.c);
  // excitation and vibration by the rung, over the view's span
  RenderedStrike out;
  const auto t0 = std::chrono::steady_clock::now();
  Eigen::MatrixXd strain = m.rung->Play(view, episodes, sample_seed, &out);
  EndSpan(view.frames, m.c.audio, &strain);
  out.vibration_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // piezo, background, converter
  out.clipped = m.daq->Convert(strain, joint_speed_rad_s, joint_speed_rate_hz, sample_seed,
                               &out.audio, view.chain);
  return out;
}

}  // namespace sonicboom::acoustics
