// One strike's audio rendered by the reference solid with its own striker, damping and sensor
// chain, drawn from the sample's seed (stream kReference): what `rerender` does to every strike
// of a dataset and `generate` to the fraction randomize.reference_fraction picks.
#include <cmath>

#include <fmt/format.h>

#include "internal/reference.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/solid/reference_chain.h"
#include "sonicboom/solid/reference_render.h"

namespace sonicboom::experiments {

void CheckReferenceBand(double band_hz, double sample_rate_hz, const std::string& name,
                        const std::string& rate_of) {
  if (!(band_hz > 100.0 && band_hz < 0.5 * sample_rate_hz)) {
    throw ConfigError(
        fmt::format("{} = {} Hz must lie in (100, {}) Hz: below the Nyquist frequency of {}", name,
                    band_hz, 0.5 * sample_rate_hz, rate_of));
  }
}

const std::vector<std::string>& ReferenceVariationNames() {
  static const std::vector<std::string> names{
      "ref_striker_modulus_pa", "ref_tip_radius_m", "ref_loss_factor", "ref_loss_exponent",
      "ref_full_scale_strain",  "ref_high_pass_hz", "ref_low_pass_hz", "ref_noise_dbfs"};
  return names;
}

std::vector<double> RenderReferenceSample(const solid::ReferenceTube& tube, double sample_rate_hz,
                                          int64_t frames, StrikeSample* sample) {
  Rng rng(sample->seed, Stream::kReference);
  // the label's contact, struck by a striker drawn here
  solid::ReferenceStrike strike;
  strike.z_m = sample->label.z_m;
  strike.theta_rad = sample->label.theta_rad;
  strike.speed_m_s = sample->label.normal_speed_m_s > 0.0 ? sample->label.normal_speed_m_s : 0.3;
  strike.onset_s = sample->label.time_s;
  const double mass = sample->contacts.empty() ? 0.0 : sample->contacts.front().effective_mass_kg;
  strike.striker_mass_kg = mass > 0.0 ? mass : 0.01;
  // its own ranges: wood across and along the grain, hard plastics; tips 3-15 mm
  strike.striker_youngs_modulus_pa = 1e9 * std::pow(15.0, rng.Uniform());
  strike.striker_radius_m = 0.003 * std::pow(5.0, rng.Uniform());
  solid::ReferenceRenderConfig render;
  render.sample_rate_hz = sample_rate_hz;
  render.samples = frames;
  render.loss_factor = 0.01 * std::pow(4.0, rng.Uniform());
  render.loss_exponent = rng.Uniform(-0.3, 0.3);
  const solid::ReferenceRender r = solid::RenderReferenceStrike(tube, strike, render);
  // its own sensor chain and noise
  const solid::ReferenceChainDraw chain =
      solid::DrawReferenceChain(&rng, static_cast<int>(r.strain.rows()));
  Rng noise(sample->seed, Stream::kNoise);
  sample->audio =
      solid::ApplyReferenceChain(r.strain, chain, sample_rate_hz, &noise, &sample->clipped);
  sample->label.impulse_Ns = r.impulse_ns;
  sample->label.duration_s = r.duration_s;
  double hp = 0.0;
  for (double f : chain.high_pass_hz) hp += f / chain.high_pass_hz.size();
  return {strike.striker_youngs_modulus_pa,
          strike.striker_radius_m,
          render.loss_factor,
          render.loss_exponent,
          chain.full_scale_strain,
          hp,
          chain.low_pass_hz,
          chain.noise_dbfs};
}

}  // namespace sonicboom::experiments
