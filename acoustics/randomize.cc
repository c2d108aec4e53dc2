#include "sonicboom/acoustics/randomize.h"

#include <array>
#include <cmath>
#include <functional>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::acoustics {
namespace {

enum class Law { kUniform, kLogUniform };

// one randomized quantity: its key, range and law, and where a draw lands in the Variation: a
// per-channel list (one draw per channel) or a scalar
struct Field {
  const char* name;
  const std::vector<double>* range;
  Law law;
  std::vector<double> Variation::*channels;
  std::function<void(Variation*, double value)> assign;
};

// every field in the fixed draw order (appending keeps earlier fields' numbers)
std::vector<Field> Fields(const RandomizeConfig& c) {
  using V = Variation;
  return {
      {"youngs_modulus_scale", &c.youngs_modulus_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->youngs_modulus_scale *= x; }},
      {"density_scale", &c.density_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->density_scale = x; }},
      {"temperature_c", &c.temperature_c, Law::kUniform, nullptr,
       [&c](V* v, double x) {
         v->temperature_c = x;
         v->youngs_modulus_scale *= 1.0 + c.modulus_per_c * (x - c.reference_temperature_c);
       }},
      {"loss_factor_scale", &c.loss_factor_scale, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->loss_factor *= x; }},
      {"loss_exponent", &c.loss_exponent, Law::kUniform, nullptr,
       [](V* v, double x) { v->loss_exponent = x; }},
      {"striker_mass_scale", &c.striker_mass_scale, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker_mass_scale = x; }},
      {"striker_radius_m", &c.striker_radius_m, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker_radius_m = x; }},
      {"striker_youngs_modulus_pa", &c.striker_youngs_modulus_pa, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker_youngs_modulus_pa = x; }},
      {"speed_scale", &c.speed_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->speed_scale = x; }},
      {"sensitivity_scale", &c.sensitivity_scale, Law::kLogUniform, &V::sensitivity_scale, {}},
      {"channel_gain_db", &c.channel_gain_db, Law::kUniform, &V::channel_gain_db, {}},
      {"highpass_hz", &c.highpass_hz, Law::kLogUniform, &V::highpass_hz, {}},
      {"noise_floor_v", &c.noise_floor_v, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->noise_floor_v = x; }},
      {"hum_hz", &c.hum_hz, Law::kUniform, nullptr, [](V* v, double x) { v->hum_hz = x; }},
      {"hum_rms_v", &c.hum_rms_v, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->hum_rms_v = x; }},
      {"record_level_db", &c.record_level_db, Law::kUniform, nullptr,
       [](V* v, double x) { v->record_level_db = x; }},
      {"full_scale_scale", &c.full_scale_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->full_scale_scale = x; }},
  };
}

double Draw(const std::vector<double>& range, Law law, double u) {
  if (law == Law::kLogUniform) {
    return std::exp(std::log(range[0]) + (std::log(range[1]) - std::log(range[0])) * u);
  }
  return range[0] + (range[1] - range[0]) * u;
}

}  // namespace

void RandomizeConfig::Serialize(Archive* a) {
  a->Visit("youngs_modulus_scale", &youngs_modulus_scale, {0.0, 10.0, true, false});
  a->Visit("density_scale", &density_scale, {0.0, 10.0, true, false});
  a->Visit("temperature_c", &temperature_c, Bounds::Closed(-40.0, 80.0));
  a->Visit("modulus_per_c", &modulus_per_c, Bounds::Closed(-0.05, 0.05));
  a->Visit("reference_temperature_c", &reference_temperature_c, Bounds::Closed(-40.0, 80.0));
  a->Visit("loss_factor_scale", &loss_factor_scale, {0.0, 100.0, true, false});
  a->Visit("loss_exponent", &loss_exponent, Bounds::Closed(-1.0, 2.0));
  a->Visit("loss_reference_hz", &loss_reference_hz, {0.0, 1e5, true, false});
  a->Visit("striker_mass_scale", &striker_mass_scale, {0.0, 100.0, true, false});
  a->Visit("striker_radius_m", &striker_radius_m, {0.0, 1.0, true, false});
  a->Visit("striker_youngs_modulus_pa", &striker_youngs_modulus_pa, {0.0, 1e12, true, false});
  a->Visit("speed_scale", &speed_scale, {0.0, 10.0, true, false});
  a->Visit("sensitivity_scale", &sensitivity_scale, {0.0, 100.0, true, false});
  a->Visit("channel_gain_db", &channel_gain_db, Bounds::Closed(-60.0, 60.0));
  a->Visit("highpass_hz", &highpass_hz, {0.0, 2e4, true, false});
  a->Visit("noise_floor_v", &noise_floor_v, {0.0, 1.0, true, false});
  a->Visit("hum_hz", &hum_hz, {0.0, 1000.0, true, false});
  a->Visit("hum_rms_v", &hum_rms_v, {0.0, 1.0, true, false});
  a->Visit("hum_harmonics", &hum_harmonics, Bounds::Closed(1, 40));
  a->Visit("record_level_db", &record_level_db, Bounds::Closed(-60.0, 60.0));
  a->Visit("full_scale_scale", &full_scale_scale, {0.0, 100.0, true, false});
}

void RandomizeConfig::Validate() const {
  for (const Field& f : Fields(*this)) {
    const std::vector<double>& r = *f.range;
    if (r.empty()) continue;
    if (r.size() != 2) {
      throw ConfigError(fmt::format("randomize.{} has {} entries; a range is [min, max] (or [] "
                                    "for none)",
                                    f.name, r.size()));
    }
    if (!(r[0] <= r[1])) {
      throw ConfigError(fmt::format("randomize.{} = [{}, {}]: min exceeds max", f.name, r[0], r[1]));
    }
  }
  // the modulus must stay positive over the temperature range
  if (temperature_c.size() == 2) {
    for (const double t : temperature_c) {
      const double factor = 1.0 + modulus_per_c * (t - reference_temperature_c);
      if (!(factor > 0.05)) {
        throw ConfigError(fmt::format(
            "randomize.temperature_c = {} with randomize.modulus_per_c = {} scales the modulus by "
            "{:.3g}; it must stay above 0.05",
            t, modulus_per_c, factor));
      }
    }
  }
}

void RandomizeConfig::CheckLossLaw(double base_loss_factor) const {
  if (loss_factor_scale.empty() && loss_exponent.empty()) return;
  const double scale_max = loss_factor_scale.empty() ? 1.0 : loss_factor_scale[1];
  const std::vector<double> exponents =
      loss_exponent.empty() ? std::vector<double>{0.0} : loss_exponent;
  // eta = 2 zeta: the largest loss factor over the audio band at the range's extremes
  double worst = 0.0;
  for (const double e : exponents) {
    for (const double f : {20.0, 20000.0}) {
      worst = std::max(worst, base_loss_factor * scale_max * std::pow(f / loss_reference_hz, e));
    }
  }
  if (!(worst < 2.0)) {
    throw ConfigError(fmt::format(
        "randomize.loss_factor_scale / randomize.loss_exponent: with material.loss_factor = {} the "
        "loss law reaches eta = {:.3g} between 20 Hz and 20 kHz; modes overdamp at eta >= 2",
        base_loss_factor, worst));
  }
}

bool RandomizeConfig::material() const {
  return !youngs_modulus_scale.empty() || !density_scale.empty() || !temperature_c.empty() ||
         !loss_factor_scale.empty() || !loss_exponent.empty();
}

bool RandomizeConfig::any() const {
  for (const Field& f : Fields(*this)) {
    if (!f.range->empty()) return true;
  }
  return false;
}

double Variation::frequency_scale() const { return std::sqrt(youngs_modulus_scale / density_scale); }

double Variation::DampingRatio(double frequency_hz) const {
  return 0.5 * loss_factor * std::pow(frequency_hz / loss_reference_hz, loss_exponent);
}

std::vector<std::string> VariationNames(const RandomizeConfig& config, int channels) {
  std::vector<std::string> names;
  for (const Field& f : Fields(config)) {
    if (f.range->empty()) continue;
    if (f.channels == nullptr) {
      names.emplace_back(f.name);
      continue;
    }
    for (int c = 0; c < channels; ++c) names.push_back(fmt::format("{}_{}", f.name, c));
  }
  return names;
}

Variation DrawVariation(const RandomizeConfig& config, double base_loss_factor, int channels,
                        uint64_t sample_seed) {
  Variation v;
  v.temperature_c = config.reference_temperature_c;
  v.loss_reference_hz = config.loss_reference_hz;
  const bool loss_law = !config.loss_factor_scale.empty() || !config.loss_exponent.empty();
  v.loss_factor = loss_law ? base_loss_factor : 0.0;
  v.sensitivity_scale.assign(static_cast<size_t>(channels), 1.0);
  Rng rng(sample_seed, Stream::kRandomize);
  for (const Field& f : Fields(config)) {
    const bool set = !f.range->empty();
    if (set && f.channels != nullptr) (v.*f.channels).resize(static_cast<size_t>(channels));
    for (int c = 0; c < (f.channels != nullptr ? channels : 1); ++c) {
      const double u = rng.Uniform();  // drawn whether the range is set or not
      if (!set) continue;
      const double x = Draw(*f.range, f.law, u);
      if (f.channels != nullptr) {
        (v.*f.channels)[static_cast<size_t>(c)] = x;
      } else {
        f.assign(&v, x);
      }
      v.values.push_back(x);
    }
  }
  // hum: a phase per harmonic, a pickup scale per channel
  for (int64_t k = 0; k < config.hum_harmonics; ++k) {
    const double u = rng.Uniform();
    if (!config.hum_rms_v.empty()) v.hum_phase_rad.push_back(2.0 * std::numbers::pi * u);
  }
  for (int c = 0; c < channels; ++c) {
    const double u = rng.Uniform();
    if (!config.hum_rms_v.empty()) v.hum_channel_scale.push_back(0.5 + u);
  }
  return v;
}

MaterialConfig VariedMaterial(const MaterialConfig& base, const Variation& v) {
  MaterialConfig m = base;
  m.youngs_modulus_pa *= v.youngs_modulus_scale;
  m.density_kg_m3 *= v.density_scale;
  return m;
}

}  // namespace sonicboom::acoustics
