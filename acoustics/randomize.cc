#include "sonicboom/acoustics/randomize.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <utility>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
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
  std::vector<double> ChainDraw::*channels;  // a per-channel list of the chain, or null
  std::function<void(Variation*, double value)> assign;
};

// every field in the fixed draw order (appending keeps earlier fields' numbers)
std::vector<Field> Fields(const RandomizeConfig& c) {
  using V = Variation;
  return {
      {"youngs_modulus_scale", &c.youngs_modulus_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->structure.youngs_modulus_scale *= x; }},
      {"density_scale", &c.density_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->structure.density_scale = x; }},
      {"temperature_c", &c.temperature_c, Law::kUniform, nullptr,
       [&c](V* v, double x) {
         v->structure.temperature_c = x;
         v->structure.youngs_modulus_scale *= 1.0 + c.modulus_per_c * (x - c.reference_temperature_c);
       }},
      {"loss_factor_scale", &c.loss_factor_scale, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->structure.loss_factor *= x; }},
      {"loss_exponent", &c.loss_exponent, Law::kUniform, nullptr,
       [](V* v, double x) { v->structure.loss_exponent = x; }},
      {"striker_mass_scale", &c.striker_mass_scale, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker.mass_scale = x; }},
      {"striker_radius_m", &c.striker_radius_m, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker.radius_m = x; }},
      {"striker_youngs_modulus_pa", &c.striker_youngs_modulus_pa, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->striker.youngs_modulus_pa = x; }},
      {"speed_scale", &c.speed_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->striker.speed_scale = x; }},
      {"sensitivity_scale", &c.sensitivity_scale, Law::kLogUniform, &ChainDraw::sensitivity_scale, {}},
      {"channel_gain_db", &c.channel_gain_db, Law::kUniform, &ChainDraw::channel_gain_db, {}},
      {"highpass_hz", &c.highpass_hz, Law::kLogUniform, &ChainDraw::highpass_hz, {}},
      {"noise_floor_v", &c.noise_floor_v, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->chain.noise_floor_v = x; }},
      {"hum_hz", &c.hum_hz, Law::kUniform, nullptr, [](V* v, double x) { v->chain.hum_hz = x; }},
      {"hum_rms_v", &c.hum_rms_v, Law::kLogUniform, nullptr,
       [](V* v, double x) { v->chain.hum_rms_v = x; }},
      {"record_level_db", &c.record_level_db, Law::kUniform, nullptr,
       [](V* v, double x) { v->chain.record_level_db = x; }},
      {"full_scale_scale", &c.full_scale_scale, Law::kUniform, nullptr,
       [](V* v, double x) { v->chain.full_scale_scale = x; }},
  };
}

double Draw(const std::vector<double>& range, Law law, double u) {
  if (law == Law::kLogUniform) {
    return std::exp(std::log(range[0]) + (std::log(range[1]) - std::log(range[0])) * u);
  }
  return range[0] + (range[1] - range[0]) * u;
}

// a whole number uniform in [r[0], r[1]] (whole bounds) from u in [0, 1)
int64_t WholeDraw(const std::vector<double>& r, double u) {
  const auto lo = static_cast<int64_t>(r[0]), hi = static_cast<int64_t>(r[1]);
  return std::min(hi, lo + static_cast<int64_t>(u * static_cast<double>(hi - lo + 1)));
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
  a->Visit("mic_z_offset_m", &mic_z_offset_m, Bounds::Closed(-0.01, 0.01));
  a->Visit("mic_theta_offset_deg", &mic_theta_offset_deg, Bounds::Closed(-10.0, 10.0));
  a->Visit("disc_diameter_m", &disc_diameter_m, {0.0, 0.04, true, false});
  a->Visit("structure_variants", &structure_variants, Bounds::Closed(0, 256));
  a->Visit("bolt_count", &bolt_count, Bounds::Closed(1, 12));
  a->Visit("bolt_z_jitter_m", &bolt_z_jitter_m, Bounds::Closed(-0.05, 0.05));
  a->Visit("bolt_stiffness_scale", &bolt_stiffness_scale, {0.0, 1e4, true, false});
  a->Visit("flange_mount_scale", &flange_mount_scale, {0.0, 1e4, true, false});
  a->Visit("tool_mount_scale", &tool_mount_scale, {0.0, 1e4, true, false});
  a->Visit("poisson_ratio", &poisson_ratio, {0.0, 0.5, true, true});
  a->Visit("attached_mass_count", &attached_mass_count,
           Bounds::Closed(0, static_cast<double>(kMaxAttachedMasses)));
  a->Visit("attached_mass_kg", &attached_mass_kg, {0.0, 1.0, true, false});
  a->Visit("disc_mass_kg", &disc_mass_kg, Bounds::Closed(0.0, 0.1));
  a->Visit("reference_fraction", &reference_fraction, Bounds::Closed(0.0, 1.0));
  a->Visit("reference_max_frequency_hz", &reference_max_frequency_hz,
           {100.0, 40000.0, true, false});
  a->Visit("reference_element_m", &reference_element_m, {0.0, 0.1, true, false});
  a->Visit("soft_striker_fraction", &soft_striker_fraction, Bounds::Closed(0.0, 1.0));
  a->Visit("soft_striker_youngs_modulus_pa", &soft_striker_youngs_modulus_pa,
           {1e4, 1e12, false, false});
  a->Visit("peak_to_noise_db", &peak_to_noise_db, Bounds::Closed(0.0, 120.0));
  a->Visit("highpass_order", &highpass_order, Bounds::Closed(1.0, 2.0));
  a->Visit("lowpass_hz", &lowpass_hz, {0.0, 2e4, true, false});
  a->Visit("lowpass_order", &lowpass_order, Bounds::Closed(1.0, 2.0));
}

namespace {

// the ranges drawn apart from Fields: microphone placement per sample, structure per variant
struct NamedRange {
  const char* name;
  const std::vector<double>* range;
};
std::vector<NamedRange> PlacementRanges(const RandomizeConfig& c) {
  return {{"mic_z_offset_m", &c.mic_z_offset_m},
          {"mic_theta_offset_deg", &c.mic_theta_offset_deg},
          {"disc_diameter_m", &c.disc_diameter_m}};
}
std::vector<NamedRange> StructureRanges(const RandomizeConfig& c) {
  return {{"bolt_count", &c.bolt_count},
          {"bolt_z_jitter_m", &c.bolt_z_jitter_m},
          {"bolt_stiffness_scale", &c.bolt_stiffness_scale},
          {"flange_mount_scale", &c.flange_mount_scale},
          {"tool_mount_scale", &c.tool_mount_scale},
          {"poisson_ratio", &c.poisson_ratio},
          {"attached_mass_count", &c.attached_mass_count},
          {"attached_mass_kg", &c.attached_mass_kg},
          {"disc_mass_kg", &c.disc_mass_kg}};
}

void CheckRange(const char* name, const std::vector<double>& r) {
  if (r.empty()) return;
  if (r.size() != 2) {
    throw ConfigError(
        fmt::format("randomize.{} has {} entries; a range is [min, max] (or [] for "
                    "none)",
                    name, r.size()));
  }
  if (!(r[0] <= r[1])) {
    throw ConfigError(fmt::format("randomize.{} = [{}, {}]: min exceeds max", name, r[0], r[1]));
  }
}

// the as-built ranges: drawn after the others, in this order (BuildRanges' names are stored)
std::vector<NamedRange> BuildRanges(const RandomizeConfig& c) {
  return {{"soft_striker_youngs_modulus_pa", &c.soft_striker_youngs_modulus_pa},
          {"peak_to_noise_db", &c.peak_to_noise_db},
          {"highpass_order", &c.highpass_order},
          {"lowpass_hz", &c.lowpass_hz},
          {"lowpass_order", &c.lowpass_order}};
}

void RequireWhole(const char* name, const std::vector<double>& r) {
  for (const double x : r) {
    if (x != std::floor(x)) {
      throw ConfigError(fmt::format("randomize.{} = {}: a filter order is a whole number", name, x));
    }
  }
}

void ValidateBuild(const RandomizeConfig& c) {
  for (const NamedRange& r : BuildRanges(c)) CheckRange(r.name, *r.range);
  RequireWhole("highpass_order", c.highpass_order);
  RequireWhole("lowpass_order", c.lowpass_order);
  if (c.soft_striker_fraction > 0.0 && c.soft_striker_youngs_modulus_pa.empty()) {
    throw ConfigError(
        fmt::format("randomize.soft_striker_fraction = {} needs "
                    "randomize.soft_striker_youngs_modulus_pa, the soft tips' modulus range",
                    c.soft_striker_fraction));
  }
  if (!c.peak_to_noise_db.empty() && !c.noise_floor_v.empty()) {
    throw ConfigError(
        "randomize.peak_to_noise_db and randomize.noise_floor_v both set the white floor: give "
        "one of them");
  }
  if (!c.lowpass_order.empty() && c.lowpass_hz.empty()) {
    throw ConfigError("randomize.lowpass_order is set but randomize.lowpass_hz is not: the "
                      "order belongs to the anti-alias low-pass");
  }
}

}  // namespace

void RandomizeConfig::Validate() const {
  for (const Field& f : Fields(*this)) CheckRange(f.name, *f.range);
  for (const NamedRange& r : PlacementRanges(*this)) CheckRange(r.name, *r.range);
  for (const NamedRange& r : StructureRanges(*this)) {
    CheckRange(r.name, *r.range);
    if (!r.range->empty() && structure_variants == 0) {
      throw ConfigError(
          fmt::format("randomize.{} is set but randomize.structure_variants is 0: "
                      "structure ranges are drawn per variant of the pool",
                      r.name));
    }
  }
  for (const auto& [name, range] : {std::pair{"bolt_count", &bolt_count},
                                    std::pair{"attached_mass_count", &attached_mass_count}}) {
    for (const double n : *range) {
      if (n != std::floor(n)) {
        throw ConfigError(fmt::format("randomize.{} = {}: a count is a whole number", name, n));
      }
    }
  }
  if (attached_mass_count.empty() != attached_mass_kg.empty()) {
    throw ConfigError(
        "randomize.attached_mass_count and randomize.attached_mass_kg go together: how many "
        "masses and how heavy each is");
  }
  ValidateBuild(*this);
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
  for (const NamedRange& r : BuildRanges(*this)) {
    if (!r.range->empty()) return true;
  }
  return mic_placement() || structure() || soft_striker_fraction > 0.0;
}

bool RandomizeConfig::mic_placement() const {
  for (const NamedRange& r : PlacementRanges(*this)) {
    if (!r.range->empty()) return true;
  }
  return false;
}

namespace {

// A place on the wall clear of the holes: one within a hole's diameter of a hole's centre is
// moved a diameter and a half towards the tube's middle
std::pair<double, double> ClearOfHoles(const StructureBase& base, double z_m, double theta_deg) {
  const ShellConfig& s = base.shell;
  const double r = base.tube.mid_radius_m(), d = s.hole_diameter_m;
  for (size_t k = 0; k < s.hole_z_m.size(); ++k) {
    const double arc = r * std::abs(WrapAngle((theta_deg - s.hole_theta_deg[k]) * kDeg));
    if (std::hypot(z_m - s.hole_z_m[k], arc) < d) z_m -= std::copysign(1.5 * d, s.hole_z_m[k]);
  }
  return {z_m, theta_deg};
}

// The attached masses of a variant, after every other structure draw: the count, then per slot
// (drawn whether the mass exists or not) its mass, z and theta, then each disc's load
void DrawAttachedMasses(const RandomizeConfig& config, const StructureBase& base, Rng* rng,
                        StructureVariant* out) {
  ShellConfig& shell = out->shell;
  const double u_count = rng->Uniform();
  const int64_t count =
      config.attached_mass_count.empty() ? 0 : WholeDraw(config.attached_mass_count, u_count);
  const double half_m = 0.5 * base.tube.length_m - 0.005;  // a mass's centre 5 mm inside the ends
  double attached_kg = 0.0;
  for (int64_t k = 0; k < kMaxAttachedMasses; ++k) {
    const double u_mass = rng->Uniform(), u_z = rng->Uniform(), u_theta = rng->Uniform();
    if (k >= count) continue;
    const double kg = Draw(config.attached_mass_kg, Law::kLogUniform, u_mass);
    const auto [z, theta] = ClearOfHoles(base, half_m * (2.0 * u_z - 1.0), 360.0 * u_theta - 180.0);
    shell.attached_mass_kg.push_back(kg);
    shell.attached_mass_z_m.push_back(z);
    shell.attached_mass_theta_deg.push_back(theta);
    attached_kg += kg;
  }
  if (!config.attached_mass_count.empty()) {
    out->values.push_back(static_cast<double>(count));
    out->values.push_back(attached_kg);
  }
  double disc_kg = 0.0;
  for (int c = 0; c < base.mics.count(); ++c) {
    const double u = rng->Uniform();
    if (config.disc_mass_kg.empty()) continue;
    const double kg = Draw(config.disc_mass_kg, Law::kUniform, u);
    shell.attached_mass_kg.push_back(kg);
    shell.attached_mass_z_m.push_back(base.mics.z_m[static_cast<size_t>(c)]);
    shell.attached_mass_theta_deg.push_back(base.mics.theta_deg[static_cast<size_t>(c)]);
    disc_kg += kg;
  }
  if (!config.disc_mass_kg.empty()) out->values.push_back(disc_kg / base.mics.count());
}

}  // namespace

std::vector<std::string> StructureValueNames(const RandomizeConfig& config) {
  std::vector<std::string> names;
  if (!config.structure()) return names;
  names.emplace_back("structure_variant");
  for (const NamedRange& r : StructureRanges(config)) {
    if (!r.range->empty() && std::string(r.name) != "bolt_z_jitter_m") names.emplace_back(r.name);
  }
  return names;
}

StructureVariant DrawStructure(const RandomizeConfig& config, const StructureBase& base,
                               uint64_t global_seed, int64_t variant) {
  const ShellConfig& base_shell = base.shell;
  StructureVariant out;
  out.shell = base_shell;
  out.poisson_ratio = base.poisson_ratio;
  out.values.push_back(static_cast<double>(variant));
  // the variant's own stream: sample seeds count down from the top of the index space
  Rng rng(SampleSeed(global_seed, ~uint64_t{0} - 1024 - static_cast<uint64_t>(variant)),
          Stream::kRandomize);
  const auto draw = [&](const std::vector<double>& r, Law law) {
    const double u = rng.Uniform();  // drawn whether the range is set or not
    return r.empty() ? std::nan("") : Draw(r, law, u);
  };
  // bolts: count, even spacing between the base's outer bolts, jitter, stiffness each
  const double u_count = rng.Uniform();
  std::vector<double>& z = out.shell.bolt_z_m;
  if (!config.bolt_count.empty() && !base_shell.bolt_z_m.empty()) {
    const int64_t n = WholeDraw(config.bolt_count, u_count);
    const auto [lo_it, hi_it] =
        std::minmax_element(base_shell.bolt_z_m.begin(), base_shell.bolt_z_m.end());
    const double lo = *lo_it, hi = *hi_it;
    z.clear();
    for (int64_t b = 0; b < n; ++b)
      z.push_back(n == 1 ? 0.5 * (lo + hi) : lo + (hi - lo) * b / (n - 1));
    out.values.push_back(static_cast<double>(n));
  }
  out.shell.bolt_stiffness_scale.assign(z.size(), 1.0);
  constexpr size_t kMaxBolts = 12;  // draws per bolt, whether the bolt exists or not
  double log_scale_sum = 0.0;
  for (size_t b = 0; b < kMaxBolts; ++b) {
    const double jitter = draw(config.bolt_z_jitter_m, Law::kUniform);
    const double scale = draw(config.bolt_stiffness_scale, Law::kLogUniform);
    if (b >= z.size()) continue;
    if (!config.bolt_z_jitter_m.empty()) z[b] += jitter;
    if (!config.bolt_stiffness_scale.empty()) out.shell.bolt_stiffness_scale[b] = scale;
    log_scale_sum += std::log(out.shell.bolt_stiffness_scale[b]);
  }
  if (!config.bolt_stiffness_scale.empty()) {
    out.values.push_back(z.empty() ? 1.0 : std::exp(log_scale_sum / static_cast<double>(z.size())));
  }
  const double flange = draw(config.flange_mount_scale, Law::kLogUniform);
  const double tool = draw(config.tool_mount_scale, Law::kLogUniform);
  const double nu = draw(config.poisson_ratio, Law::kUniform);
  if (!config.flange_mount_scale.empty()) {
    out.shell.flange_mount_stiffness_n_m2 *= flange;
    out.values.push_back(flange);
  }
  if (!config.tool_mount_scale.empty()) {
    out.shell.tool_mount_stiffness_n_m2 *= tool;
    out.values.push_back(tool);
  }
  if (!config.poisson_ratio.empty()) {
    out.poisson_ratio = nu;
    out.values.push_back(nu);
  }
  DrawAttachedMasses(config, base, &rng, &out);
  return out;
}

double StructureDraw::frequency_scale() const {
  return std::sqrt(youngs_modulus_scale / density_scale);
}

double StructureDraw::DampingRatio(double frequency_hz) const {
  return 0.5 * loss_factor * std::pow(frequency_hz / loss_reference_hz, loss_exponent);
}

bool StructureDraw::placed() const {
  return !mic_z_offset_m.empty() || !mic_theta_offset_deg.empty() || !disc_diameter_m.empty();
}

bool StructureDraw::Nominal() const {
  return frequency_scale() == 1.0 && density_scale == 1.0 && !(loss_factor > 0.0) &&
         structure_variant < 0 && !placed();
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
  for (const NamedRange& r : PlacementRanges(config)) {
    if (r.range->empty()) continue;
    for (int c = 0; c < channels; ++c) names.push_back(fmt::format("{}_{}", r.name, c));
  }
  if (config.soft_striker_fraction > 0.0) names.emplace_back("soft_striker");
  for (const NamedRange& r : BuildRanges(config)) {
    if (!r.range->empty()) names.emplace_back(r.name);
  }
  for (std::string& name : StructureValueNames(config)) names.push_back(std::move(name));
  return names;
}

namespace {

// the as-built draws, after every other draw of the sample (their numbers stay as they were):
// one uniform each whether its range is set or not; the set ones stored in BuildRanges' order
void DrawBuild(const RandomizeConfig& c, Rng* rng, Variation* v) {
  const double u_soft = rng->Uniform(), u_modulus = rng->Uniform(), u_snr = rng->Uniform(),
               u_highpass = rng->Uniform(), u_lowpass = rng->Uniform(),
               u_lowpass_order = rng->Uniform();
  const auto keep = [v](double x) {
    v->values.push_back(x);
    return x;
  };
  const bool soft = c.soft_striker_fraction > 0.0 && u_soft < c.soft_striker_fraction;
  if (c.soft_striker_fraction > 0.0) keep(soft ? 1.0 : 0.0);
  if (!c.soft_striker_youngs_modulus_pa.empty()) {
    const double e = keep(Draw(c.soft_striker_youngs_modulus_pa, Law::kLogUniform, u_modulus));
    if (soft) v->striker.youngs_modulus_pa = e;
  }
  if (!c.peak_to_noise_db.empty()) {
    v->chain.peak_to_noise_db = keep(Draw(c.peak_to_noise_db, Law::kUniform, u_snr));
  }
  if (!c.highpass_order.empty()) {
    v->chain.highpass_order = static_cast<int>(keep(WholeDraw(c.highpass_order, u_highpass)));
  }
  if (!c.lowpass_hz.empty()) {
    v->chain.lowpass_hz = keep(Draw(c.lowpass_hz, Law::kLogUniform, u_lowpass));
  }
  if (!c.lowpass_order.empty()) {
    v->chain.lowpass_order = static_cast<int>(keep(WholeDraw(c.lowpass_order, u_lowpass_order)));
  }
}

}  // namespace

Variation DrawVariation(const RandomizeConfig& config, double base_loss_factor, int channels,
                        uint64_t sample_seed) {
  Variation v;
  v.structure.temperature_c = config.reference_temperature_c;
  v.structure.loss_reference_hz = config.loss_reference_hz;
  const bool loss_law = !config.loss_factor_scale.empty() || !config.loss_exponent.empty();
  v.structure.loss_factor = loss_law ? base_loss_factor : 0.0;
  v.chain.sensitivity_scale.assign(static_cast<size_t>(channels), 1.0);
  Rng rng(sample_seed, Stream::kRandomize);
  for (const Field& f : Fields(config)) {
    const bool set = !f.range->empty();
    if (set && f.channels != nullptr) (v.chain.*f.channels).resize(static_cast<size_t>(channels));
    for (int c = 0; c < (f.channels != nullptr ? channels : 1); ++c) {
      const double u = rng.Uniform();  // drawn whether the range is set or not
      if (!set) continue;
      const double x = Draw(*f.range, f.law, u);
      if (f.channels != nullptr) {
        (v.chain.*f.channels)[static_cast<size_t>(c)] = x;
      } else {
        f.assign(&v, x);
      }
      v.values.push_back(x);
    }
  }
  // hum: a phase per harmonic, a pickup scale per channel
  for (int64_t k = 0; k < config.hum_harmonics; ++k) {
    const double u = rng.Uniform();
    if (!config.hum_rms_v.empty()) v.chain.hum_phase_rad.push_back(2.0 * std::numbers::pi * u);
  }
  for (int c = 0; c < channels; ++c) {
    const double u = rng.Uniform();
    if (!config.hum_rms_v.empty()) v.chain.hum_channel_scale.push_back(0.5 + u);
  }
  // microphone placement per channel, then the structure variant
  for (const auto& [field, name] :
       {std::pair{&StructureDraw::mic_z_offset_m, &config.mic_z_offset_m},
        std::pair{&StructureDraw::mic_theta_offset_deg, &config.mic_theta_offset_deg},
        std::pair{&StructureDraw::disc_diameter_m, &config.disc_diameter_m}}) {
    for (int c = 0; c < channels; ++c) {
      const double u = rng.Uniform();
      if (name->empty()) continue;
      const double x = Draw(*name, Law::kUniform, u);
      (v.structure.*field).push_back(x);
      v.values.push_back(x);
    }
  }
  const double u = rng.Uniform();
  if (config.structure()) {
    v.structure.structure_variant =
        std::min<int64_t>(static_cast<int64_t>(u * static_cast<double>(config.structure_variants)),
                          config.structure_variants - 1);
  }
  DrawBuild(config, &rng, &v);
  return v;
}

MaterialConfig VariedMaterial(const MaterialConfig& base, const StructureDraw& v) {
  MaterialConfig m = base;
  m.youngs_modulus_pa *= v.youngs_modulus_scale;
  m.density_kg_m3 *= v.density_scale;
  return m;
}

}  // namespace sonicboom::acoustics
