// Randomized structures and sensor chains: ranges refused naming the key, draws fixed by the
// seed, the material scaling exact against a full solve, the sensor chain's hum, level and
// corners as drawn.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "../common/test_util.h"
#include "sonicboom/acoustics/daq.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;
using testing::ThrownMessage;

bool Names(const std::string& message, const std::string& key) {
  return message.find(key) != std::string::npos;
}

TEST(RandomizeConfigTest, BadRangesAreRefusedNamingTheKey) {
  RandomizeConfig c;
  c.youngs_modulus_scale = {1.2, 0.8};
  EXPECT_TRUE(
      Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.youngs_modulus_scale"));
  c = {};
  c.channel_gain_db = {-3, 0, 3};
  EXPECT_TRUE(
      Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.channel_gain_db"));
  // a temperature range that drives the modulus to nothing
  c = {};
  c.temperature_c = {20, 80};
  c.modulus_per_c = -0.02;
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.temperature_c"));
  // a loss law that overdamps the low modes
  c = {};
  c.loss_exponent = {-1.0, 0.0};
  c.loss_factor_scale = {1.0, 20.0};
  EXPECT_NO_THROW(c.Validate());
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.CheckLossLaw(0.02); }),
                    "randomize.loss_factor_scale"));
  c.loss_exponent = {-0.3, 0.3};
  c.loss_factor_scale = {1.0, 2.0};
  EXPECT_NO_THROW(c.CheckLossLaw(0.02));
  EXPECT_TRUE(c.material());
  EXPECT_TRUE(c.any());
  EXPECT_FALSE(RandomizeConfig{}.any());
}

TEST(RandomizeDrawTest, DrawsFollowTheSeedAndStayInRange) {
  RandomizeConfig c;
  c.youngs_modulus_scale = {0.9, 1.1};
  c.sensitivity_scale = {0.5, 2.0};
  c.hum_rms_v = {1e-5, 1e-3};
  const Variation a = DrawVariation(c, 0.02, 6, 1234);
  const Variation b = DrawVariation(c, 0.02, 6, 1234);
  const Variation other = DrawVariation(c, 0.02, 6, 1235);
  EXPECT_EQ(a.values, b.values);
  EXPECT_NE(a.values, other.values);
  // the stored values line up with the names: one modulus, six sensitivities, one hum level
  const std::vector<std::string> names = VariationNames(c, 6);
  ASSERT_EQ(names.size(), 8u);
  ASSERT_EQ(a.values.size(), 8u);
  EXPECT_EQ(names[0], "youngs_modulus_scale");
  EXPECT_EQ(names[1], "sensitivity_scale_0");
  EXPECT_EQ(names[7], "hum_rms_v");
  EXPECT_EQ(a.values[0], a.structure.youngs_modulus_scale);
  EXPECT_EQ(a.values[3], a.chain.sensitivity_scale[2]);
  EXPECT_EQ(a.chain.hum_phase_rad.size(), 5u);
  EXPECT_EQ(a.chain.hum_channel_scale.size(), 6u);
  // over many seeds every draw stays inside its range and spans it
  double lo = 10, hi = 0;
  for (uint64_t s = 0; s < 400; ++s) {
    const Variation v = DrawVariation(c, 0.02, 6, s);
    ASSERT_GE(v.structure.youngs_modulus_scale, 0.9);
    ASSERT_LE(v.structure.youngs_modulus_scale, 1.1);
    for (const double x : v.chain.sensitivity_scale) {
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
  }
  EXPECT_GE(lo, 0.5);
  EXPECT_LE(hi, 2.0);
  EXPECT_LT(lo, 0.55);
  EXPECT_GT(hi, 1.8);
}

TEST(RandomizeDrawTest, TurningOneRangeOnKeepsTheOthersNumbers) {
  RandomizeConfig c;
  c.speed_scale = {0.5, 1.5};
  c.record_level_db = {-6, 6};
  const Variation before = DrawVariation(c, 0.02, 6, 99);
  c.youngs_modulus_scale = {0.8, 1.2};
  c.channel_gain_db = {-3, 3};
  const Variation after = DrawVariation(c, 0.02, 6, 99);
  EXPECT_EQ(before.striker.speed_scale, after.striker.speed_scale);
  EXPECT_EQ(before.chain.record_level_db, after.chain.record_level_db);
  EXPECT_NE(after.structure.youngs_modulus_scale, 1.0);
  // temperature shifts the modulus by modulus_per_c per kelvin
  RandomizeConfig t;
  t.temperature_c = {35, 35};
  const Variation warm = DrawVariation(t, 0.02, 6, 5);
  EXPECT_NEAR(warm.structure.youngs_modulus_scale, 1.0 - 0.004 * 15, 1e-12);
  EXPECT_NEAR(warm.structure.frequency_scale(), std::sqrt(0.94), 1e-12);
}

// a coarse seamed tube (10 mm grid), modes to 8 kHz, no noise or gain draw, one cache
const testing::TempDir& Cache() {
  static const testing::TempDir dir;
  return dir;
}

AcousticModelConfig Coarse() {
  AcousticModelConfig c;
  c.shell.grid_spacing_m = 0.01;
  c.shell.axial_spacing_m = 0.01;
  // the thin shell these margins were set on: the wall's compliance in series with the tip
  // dominates the contact, so a soft tip lowers the peak force by 10.4 % here and by 9.6 % on the
  // thick-plate wall, against the striker check's 10 %
  c.shell.dispersion = Dispersion::kThin;
  c.synth.model = VibrationModel::kModal;
  c.synth.mode_band_hz = 8000;
  c.synth.mode_cache_dir = Cache().path().string();
  c.noise.ambient_rms_v = 0;
  c.noise.motor_rms_v_per_rad_s = 0;
  c.daq.preamp_noise_v = 0;
  c.daq.gain_mismatch_db = 0;
  return c;
}

ContactEvent Ball(double z_m, double theta_rad, double speed_m_s) {
  ContactEvent e;
  e.time_s = 0.02;
  e.z_m = z_m;
  e.theta_rad = theta_rad;
  e.normal_speed_m_s = speed_m_s;
  e.effective_mass_kg = 0.03;
  e.striker_radius_m = 0.011;
  e.striker_youngs_modulus_pa = 1e9;
  e.striker_poisson_ratio = 0.35;
  return e;
}

TEST(RandomizeRenderTest, ScaledMaterialMatchesAFullSolveOfThatMaterial) {
  // E x 1.2 and rho x 0.9 applied to the base modes against modes solved for that material
  AcousticModelConfig base = Coarse();
  base.audio.record_duration_s = 0.06;
  AcousticModelConfig solved = base;
  solved.material.youngs_modulus_pa *= 1.2;
  solved.material.density_kg_m3 *= 0.9;
  // the bolt and mount springs count as part of the material: they scale with E
  solved.shell.bolt_stiffness_n_m *= 1.2;
  solved.shell.flange_mount_stiffness_n_m2 *= 1.2;
  solved.shell.tool_mount_stiffness_n_m2 *= 1.2;
  // the varied model renders modes below the same band of varied frequencies
  solved.synth.mode_band_hz = 8000 * std::sqrt(1.2 / 0.9);
  const StrikeSynthesizer a(base), b(solved);
  Variation v;
  v.structure.youngs_modulus_scale = 1.2;
  v.structure.density_scale = 0.9;
  v.chain.sensitivity_scale.assign(6, 1.0);
  const ContactEvent strike = Ball(0.04, 1.0, 0.3);
  const RenderedStrike va = a.Render(strike, {}, {}, 0.0, 7, &v);
  const RenderedStrike vb = b.Render(strike, {}, {}, 0.0, 7, nullptr);
  const RenderedStrike plain = a.Render(strike, {}, {}, 0.0, 7, nullptr);
  EXPECT_EQ(va.modes_used, vb.modes_used);
  EXPECT_NEAR(va.duration_s, vb.duration_s, 1e-6 * vb.duration_s);
  // the signals agree to the 16-bit grid; the unvaried render differs far more
  const double ref = vb.audio.cast<double>().norm();
  const double err = (va.audio - vb.audio).cast<double>().norm() / ref;
  const double change = (plain.audio - vb.audio).cast<double>().norm() / ref;
  EXPECT_LT(err, 2e-3);
  EXPECT_GT(change, 0.1);
}

TEST(RandomizeRenderTest, StrikerDrawsChangeTheContactAsHertzSays) {
  const StrikeSynthesizer synth(Coarse());
  Variation v;
  v.chain.sensitivity_scale.assign(6, 1.0);
  const ContactEvent strike = Ball(-0.05, 0.3, 0.3);
  const RenderedStrike base = synth.Render(strike, {}, {}, 0.0, 1, &v);
  // a soft tip lengthens the contact and lowers its force; a steel one raises the force (the
  // wall's own compliance, in series, keeps its duration near the wooden one's)
  v.striker.youngs_modulus_pa = 3e8;
  const RenderedStrike soft = synth.Render(strike, {}, {}, 0.0, 1, &v);
  v.striker.youngs_modulus_pa = 200e9;
  const RenderedStrike steel = synth.Render(strike, {}, {}, 0.0, 1, &v);
  EXPECT_GT(soft.duration_s, 1.2 * base.duration_s);
  EXPECT_LT(soft.peak_force_n, 0.9 * base.peak_force_n);
  EXPECT_GT(steel.peak_force_n, 1.2 * base.peak_force_n);
  // a heavier striker at the same speed: a longer contact and a larger impulse
  v.striker.youngs_modulus_pa = 0.0;
  v.striker.mass_scale = 4.0;
  const RenderedStrike heavy = synth.Render(strike, {}, {}, 0.0, 1, &v);
  EXPECT_GT(heavy.duration_s, 1.5 * base.duration_s);
  EXPECT_GT(heavy.impulse_ns, 2.0 * base.impulse_ns);
  // a faster one: a shorter contact (Hertz: t_c ~ v^-1/5) and more impulse
  v.striker.mass_scale = 1.0;
  v.striker.speed_scale = 3.0;
  const RenderedStrike fast = synth.Render(strike, {}, {}, 0.0, 1, &v);
  EXPECT_LT(fast.duration_s, base.duration_s);
  EXPECT_GT(fast.impulse_ns, 2.0 * base.impulse_ns);
}

TEST(RandomizeDaqTest, LevelHighPassAndHumAsDrawn) {
  AcousticModelConfig c = Coarse();
  const DaqChain chain(c.daq, c.noise, 6, 44100, 44100);
  // a constant strain step on every channel, converted plain and with a draw
  const Eigen::MatrixXd strain = Eigen::MatrixXd::Constant(6, 44100, 1e-5);
  Eigen::MatrixXf plain, varied;
  chain.Convert(strain, {}, 0.0, 1, &plain);
  Variation v;
  v.chain.sensitivity_scale = {1, 2, 1, 1, 1, 1};
  v.chain.record_level_db = 6.0206;
  v.chain.highpass_hz = {10, 10, 10, 10, 10, 300};
  v.chain.noise_floor_v = 0.0;
  chain.Convert(strain, {}, 0.0, 1, &varied, v.chain);
  // record level x2 on every channel, bonding x2 on channel 1
  EXPECT_NEAR(varied(0, 0) / plain(0, 0), 2.0, 2e-3);
  EXPECT_NEAR(varied(1, 0) / plain(1, 0), 4.0, 4e-3);
  // the 300 Hz corner removes the step within 5 ms
  EXPECT_LT(std::abs(varied(5, 221)), 0.01 * std::abs(varied(5, 0)));
  // hum alone: 50 Hz and harmonics at the drawn rms, scaled per channel, on no strain
  Variation hum;
  hum.chain.sensitivity_scale.assign(6, 1.0);
  hum.chain.noise_floor_v = 0.0;
  hum.chain.hum_hz = 50.0;
  hum.chain.hum_rms_v = 0.01;
  hum.chain.hum_phase_rad = {0.1, 0.2, 0.3, 0.4, 0.5};
  hum.chain.hum_channel_scale = {1, 0.5, 1, 1, 1, 1.5};
  Eigen::MatrixXf out;
  chain.Convert(Eigen::MatrixXd::Zero(6, 44100), {}, 0.0, 1, &out, hum.chain);
  const auto rms = [&](int ch) {
    return std::sqrt(out.row(ch).cast<double>().squaredNorm() / 44100);
  };
  EXPECT_NEAR(rms(0), 0.01, 2e-4);
  EXPECT_NEAR(rms(1), 0.005, 1e-4);
  EXPECT_NEAR(rms(5), 0.015, 3e-4);
  // its fundamental: correlation with a 50 Hz sinusoid carries 1 / sum(1/k^2) of the power
  double s = 0, co = 0;
  for (int k = 0; k < 44100; ++k) {
    s += out(0, k) * std::sin(2 * kPi * 50 * k / 44100.0);
    co += out(0, k) * std::cos(2 * kPi * 50 * k / 44100.0);
  }
  const double fundamental_rms = std::sqrt(2.0) * std::hypot(s, co) / 44100;
  const double share = 1.0 / (1 + 1 / 4.0 + 1 / 9.0 + 1 / 16.0 + 1 / 25.0);
  EXPECT_NEAR(fundamental_rms * fundamental_rms / (0.01 * 0.01), share, 0.02);
  // a noise floor leaves no exact zeros in a silent record
  Variation noisy;
  noisy.chain.sensitivity_scale.assign(6, 1.0);
  noisy.chain.noise_floor_v = 1e-3;
  chain.Convert(Eigen::MatrixXd::Zero(6, 44100), {}, 0.0, 1, &out, noisy.chain);
  EXPECT_LT((out.array() == 0.0f).cast<double>().mean(), 0.02);
}

// The as-built ranges: a share of soft strikers, a floor set by the strike's peak, filter orders.
// They are drawn after everything else, so turning them on leaves every other number alone.
TEST(RandomizeBuildTest, SoftStrikersShareAndOrdersAsDrawnOtherDrawsKept) {
  RandomizeConfig c;
  c.striker_youngs_modulus_pa = {5e8, 2e11};
  c.noise_floor_v = {5e-4, 3e-3};
  c.mic_z_offset_m = {-0.002, 0.002};
  const Variation before = DrawVariation(c, 0.02, 6, 77);
  c.soft_striker_fraction = 0.25;
  c.soft_striker_youngs_modulus_pa = {3e6, 1e8};
  c.highpass_order = {1, 2};
  c.lowpass_hz = {5000, 18000};
  c.lowpass_order = {1, 2};
  EXPECT_NO_THROW(c.Validate());
  const Variation after = DrawVariation(c, 0.02, 6, 77);
  ASSERT_GE(after.values.size(), before.values.size());
  EXPECT_TRUE(std::equal(before.values.begin(), before.values.end(), after.values.begin()));
  EXPECT_EQ(before.structure.mic_z_offset_m, after.structure.mic_z_offset_m);
  // names line up with values: soft flag, soft modulus, then the filter draws
  const std::vector<std::string> names = VariationNames(c, 6);
  ASSERT_EQ(names.size(), after.values.size());
  const size_t at = before.values.size();
  EXPECT_EQ(names[at], "soft_striker");
  EXPECT_EQ(names[at + 1], "soft_striker_youngs_modulus_pa");
  EXPECT_EQ(names[at + 4], "lowpass_order");
  // over many seeds: about a quarter soft, the soft modulus in its range; orders 1 and 2 both
  int soft = 0, order2 = 0, low2 = 0;
  for (uint64_t s = 0; s < 2000; ++s) {
    const Variation v = DrawVariation(c, 0.02, 6, s);
    const bool is_soft = v.values[at] == 1.0;
    soft += is_soft;
    const double e = v.striker.youngs_modulus_pa;
    ASSERT_TRUE(is_soft ? (e >= 3e6 && e <= 1e8) : (e >= 5e8 && e <= 2e11)) << e;
    ASSERT_TRUE(v.chain.highpass_order == 1 || v.chain.highpass_order == 2);
    ASSERT_GE(v.chain.lowpass_hz, 5000.0);
    ASSERT_LE(v.chain.lowpass_hz, 18000.0);
    order2 += v.chain.highpass_order == 2;
    low2 += v.chain.lowpass_order == 2;
  }
  EXPECT_NEAR(soft / 2000.0, 0.25, 0.03);
  EXPECT_NEAR(order2 / 2000.0, 0.5, 0.04);
  EXPECT_NEAR(low2 / 2000.0, 0.5, 0.04);
}

TEST(RandomizeBuildTest, BadBuildRangesAreRefusedNamingTheKeys) {
  RandomizeConfig c;
  c.soft_striker_fraction = 0.2;
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }),
                    "randomize.soft_striker_youngs_modulus_pa"));
  c = {};
  c.peak_to_noise_db = {20, 45};
  c.noise_floor_v = {1e-4, 1e-3};
  const std::string both = ThrownMessage<ConfigError>([&] { c.Validate(); });
  EXPECT_TRUE(Names(both, "randomize.peak_to_noise_db") && Names(both, "randomize.noise_floor_v"))
      << both;
  c = {};
  c.highpass_order = {1, 1.5};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.highpass_order"));
  c = {};
  c.lowpass_order = {1, 2};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.lowpass_hz"));
}

// steady-state gain of the chain's filters for a sine at f (the second half of 1 s)
double FilterGain(double f_hz, double highpass_hz, const ChainDraw& chain) {
  const int n = 44100;
  Eigen::ArrayXd x(n);
  for (int k = 0; k < n; ++k) x[k] = std::sin(2 * kPi * f_hz * k / 44100.0);
  Eigen::ArrayXd y = x;
  ApplyChainFilters(highpass_hz, chain, 44100.0, y);
  return std::sqrt(y.tail(n / 2).square().mean() / x.tail(n / 2).square().mean());
}

// First-order and Butterworth sections: -3 dB at the corner; a decade below the high-pass corner
// -20 dB for one order and -40 dB for two; an octave above a low-pass corner -7 / -12.3 dB.
TEST(RandomizeBuildTest, ChainFiltersHaveTheirOrdersSlopes) {
  ChainDraw one, two;
  two.highpass_order = 2;
  const double db = 20 * std::log10(1.0);
  EXPECT_NEAR(20 * std::log10(FilterGain(1000, 1000, one)), db - 3.01, 0.05);
  EXPECT_NEAR(20 * std::log10(FilterGain(1000, 1000, two)), db - 3.01, 0.05);
  EXPECT_NEAR(20 * std::log10(FilterGain(100, 1000, one)), -20.04, 0.1);
  EXPECT_NEAR(20 * std::log10(FilterGain(100, 1000, two)), -40.0, 0.1);
  ChainDraw low1, low2;
  low1.lowpass_hz = low2.lowpass_hz = 4000;
  low2.lowpass_order = 2;
  // the bilinear map puts digital f at the analog tan(pi f / fs) / tan(pi fc / fs) of the corner
  // (-7.63 and -13.79 dB an octave above 4 kHz); the high-pass at 1 Hz is flat there
  const double w = std::tan(kPi * 8000 / 44100.0) / std::tan(kPi * 4000 / 44100.0);
  EXPECT_NEAR(20 * std::log10(FilterGain(4000, 1, low1)), -3.01, 0.05);
  EXPECT_NEAR(20 * std::log10(FilterGain(8000, 1, low1)), -10 * std::log10(1 + w * w), 0.05);
  EXPECT_NEAR(20 * std::log10(FilterGain(8000, 1, low2)), -10 * std::log10(1 + w * w * w * w),
              0.05);
  ChainDraw nyquist;
  nyquist.lowpass_hz = 30000;
  Eigen::ArrayXd y = Eigen::ArrayXd::Zero(16);
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>(
                        [&] { ApplyChainFilters(10, nyquist, 44100.0, y); }),
                    "randomize.lowpass_hz"));
}

// A floor set by the strike: the loudest channel's peak stands the drawn dB above the noise rms.
TEST(RandomizeBuildTest, PeakToNoiseSetsTheFloorFromTheStrike) {
  AcousticModelConfig c = Coarse();
  const DaqChain chain(c.daq, c.noise, 6, 44100, 44100);
  // a decaying 2 kHz burst from 0.5 s, ten times stronger on channel 3
  Eigen::MatrixXd strain = Eigen::MatrixXd::Zero(6, 44100);
  for (int k = 22050; k < 44100; ++k) {
    const double t = (k - 22050) / 44100.0;
    for (int ch = 0; ch < 6; ++ch) {
      strain(ch, k) = (ch == 3 ? 1e-5 : 1e-6) * std::exp(-t / 0.02) * std::sin(2 * kPi * 2000 * t);
    }
  }
  ChainDraw draw;
  draw.sensitivity_scale.assign(6, 1.0);
  draw.channel_gain_db.assign(6, 0.0);
  draw.peak_to_noise_db = 120;  // the strike's own peak, nearly clean
  Eigen::MatrixXf out;
  chain.Convert(strain, {}, 0.0, 3, &out, draw);
  const double peak = out.cwiseAbs().maxCoeff();
  for (const double target_db : {20.0, 35.0}) {
    draw.peak_to_noise_db = target_db;
    chain.Convert(strain, {}, 0.0, 3, &out, draw);
    // the noise before the strike, every channel
    const double rms = std::sqrt(out.leftCols(22000).cast<double>().squaredNorm() / (6.0 * 22000));
    EXPECT_NEAR(20 * std::log10(peak / rms), target_db, 0.5) << target_db;
  }
}

}  // namespace
}  // namespace sonicboom::acoustics

namespace sonicboom::acoustics {
namespace {

TEST(RandomizeStructureTest, RangesNeedAPoolAndWholeBoltCounts) {
  RandomizeConfig c;
  c.bolt_stiffness_scale = {0.5, 2.0};
  EXPECT_TRUE(
      Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.structure_variants"));
  c.structure_variants = 4;
  EXPECT_NO_THROW(c.Validate());
  c.bolt_count = {2.5, 4};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.bolt_count"));
  c.bolt_count = {5, 2};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.bolt_count"));
  c = {};
  c.mic_z_offset_m = {0.002, -0.002};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { c.Validate(); }), "randomize.mic_z_offset_m"));
}

TEST(RandomizeStructureTest, VariantsFollowTheSeedAndTheRanges) {
  RandomizeConfig c;
  c.structure_variants = 16;
  c.bolt_count = {2, 5};
  c.bolt_z_jitter_m = {-0.01, 0.01};
  c.bolt_stiffness_scale = {0.1, 10.0};
  c.flange_mount_scale = {0.2, 5.0};
  c.poisson_ratio = {0.35, 0.42};
  const TubeConfig tube;
  const ShellConfig shell;
  const MicArrayConfig mics;
  const StructureBase base{tube, shell, mics, 0.38};
  std::set<size_t> counts;
  for (int64_t v = 0; v < c.structure_variants; ++v) {
    const StructureVariant a = DrawStructure(c, base, 7, v);
    const StructureVariant b = DrawStructure(c, base, 7, v);
    EXPECT_EQ(a.shell.bolt_z_m, b.shell.bolt_z_m);
    EXPECT_EQ(a.values, b.values);
    ASSERT_EQ(a.values.size(), StructureValueNames(c).size());
    EXPECT_EQ(a.values[0], static_cast<double>(v));
    counts.insert(a.shell.bolt_z_m.size());
    ASSERT_GE(a.shell.bolt_z_m.size(), 2u);
    ASSERT_LE(a.shell.bolt_z_m.size(), 5u);
    ASSERT_EQ(a.shell.bolt_stiffness_scale.size(), a.shell.bolt_z_m.size());
    for (size_t k = 0; k < a.shell.bolt_z_m.size(); ++k) {
      // even spacing over the base's outer bolts (-0.1 .. 0.1) plus the jitter
      EXPECT_LE(std::abs(a.shell.bolt_z_m[k]), 0.1 + 0.01 + 1e-12);
      EXPECT_GE(a.shell.bolt_stiffness_scale[k], 0.1);
      EXPECT_LE(a.shell.bolt_stiffness_scale[k], 10.0);
    }
    EXPECT_GE(a.poisson_ratio, 0.35);
    EXPECT_LE(a.poisson_ratio, 0.42);
    EXPECT_NEAR(a.shell.tool_mount_stiffness_n_m2, shell.tool_mount_stiffness_n_m2, 0.0);
  }
  EXPECT_GE(counts.size(), 3u);  // the counts spread over the range
  // another global seed, another pool
  EXPECT_NE(DrawStructure(c, base, 8, 0).values, DrawStructure(c, base, 7, 0).values);
  // a sample picks a variant in range, and the placement draws per channel
  c.mic_z_offset_m = {-0.002, 0.002};
  c.disc_diameter_m = {0.015, 0.025};
  std::set<int64_t> picked;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    const Variation v = DrawVariation(c, 0.02, 6, seed);
    ASSERT_GE(v.structure.structure_variant, 0);
    ASSERT_LT(v.structure.structure_variant, 16);
    picked.insert(v.structure.structure_variant);
    ASSERT_EQ(v.structure.mic_z_offset_m.size(), 6u);
    ASSERT_EQ(v.structure.disc_diameter_m.size(), 6u);
    EXPECT_TRUE(v.structure.mic_theta_offset_deg.empty());
    for (double d : v.structure.disc_diameter_m) EXPECT_TRUE(d >= 0.015 && d <= 0.025);
  }
  EXPECT_EQ(picked.size(), 16u);
  // names: the per-sample draws (placement per channel), then the variant's values
  const std::vector<std::string> names = VariationNames(c, 6);
  EXPECT_EQ(names.front(), "mic_z_offset_m_0");
  EXPECT_EQ(names[12], "structure_variant");
  EXPECT_EQ(names.size(), 12 + StructureValueNames(c).size());
}

TEST(RandomizeStructureTest, MovedDiscsRenderAsABankBuiltForThem) {
  // a disc placement drawn per sample against an array configured at that placement
  AcousticModelConfig moved = Coarse();
  moved.audio.record_duration_s = 0.06;
  moved.synth.residual = false;  // the residual keeps the configured placement
  AcousticModelConfig drawn = moved;
  // (offsets of the order of the coarse grid's 10 mm: the disc reads the nodes under it)
  drawn.randomize.mic_z_offset_m = {-0.008, 0.008};
  drawn.randomize.mic_theta_offset_deg = {-8, 8};
  drawn.randomize.disc_diameter_m = {0.012, 0.026};
  Variation v;
  v.chain.sensitivity_scale.assign(6, 1.0);
  v.structure.mic_z_offset_m = {0.006, -0.005, 0.004, 0.007, -0.006, 0.005};
  v.structure.mic_theta_offset_deg = {-6.0, 5.0, 4.0, 6.0, -4.0, 3.0};
  v.structure.disc_diameter_m = {0.012, 0.026, 0.02, 0.015, 0.022, 0.018};
  for (int c = 0; c < 6; ++c) {
    moved.mics.z_m[c] += v.structure.mic_z_offset_m[c];
    moved.mics.theta_deg[c] += v.structure.mic_theta_offset_deg[c];
  }
  const StrikeSynthesizer a(drawn);
  const ContactEvent strike = Ball(-0.03, 2.0, 0.4);
  const RenderedStrike placed = a.Render(strike, {}, {}, 0.0, 7, &v);
  const RenderedStrike nominal = a.Render(strike, {}, {}, 0.0, 7, nullptr);
  // the per-channel diameters: one array per channel's diameter, compared channel by channel
  for (int c = 0; c < 6; ++c) {
    AcousticModelConfig one = moved;
    one.mics.disc_diameter_m = v.structure.disc_diameter_m[c];
    const RenderedStrike ref = StrikeSynthesizer(one).Render(strike, {}, {}, 0.0, 7, nullptr);
    const double norm = ref.audio.row(c).cast<double>().norm();
    ASSERT_GT(norm, 0.0);
    EXPECT_LT((placed.audio.row(c) - ref.audio.row(c)).cast<double>().norm() / norm, 2e-3) << c;
    EXPECT_GT((nominal.audio.row(c) - ref.audio.row(c)).cast<double>().norm() / norm, 2e-2) << c;
  }
}

// attached masses are drawn after every other structure draw: turning them on leaves the bolts,
// mounts and Poisson's ratio of every variant as they were, and adds the count, the masses in
// range at places on the wall clear of the holes, and a load at each disc's mark
TEST(RandomizeStructureTest, AttachedMassesLeaveTheOtherDrawsAsTheyWere) {
  RandomizeConfig c;
  c.structure_variants = 16;
  c.bolt_count = {2, 5};
  c.bolt_stiffness_scale = {0.1, 10.0};
  c.poisson_ratio = {0.35, 0.42};
  RandomizeConfig massed = c;
  massed.attached_mass_count = {1, 4};
  massed.attached_mass_kg = {0.002, 0.03};
  massed.disc_mass_kg = {0.0005, 0.002};
  massed.Validate();
  const TubeConfig tube;
  const ShellConfig shell;
  const MicArrayConfig mics;
  const StructureBase base{tube, shell, mics, 0.38};
  const std::vector<std::string> names = StructureValueNames(massed);
  ASSERT_EQ(names.size(), StructureValueNames(c).size() + 3);
  EXPECT_EQ(names.back(), "disc_mass_kg");
  std::set<int64_t> counts;
  for (int64_t v = 0; v < c.structure_variants; ++v) {
    const StructureVariant a = DrawStructure(c, base, 7, v);
    const StructureVariant b = DrawStructure(massed, base, 7, v);
    EXPECT_EQ(a.shell.bolt_z_m, b.shell.bolt_z_m);
    EXPECT_EQ(a.shell.bolt_stiffness_scale, b.shell.bolt_stiffness_scale);
    EXPECT_EQ(a.poisson_ratio, b.poisson_ratio);
    ASSERT_EQ(b.values.size(), names.size());
    EXPECT_TRUE(std::equal(a.values.begin(), a.values.end(), b.values.begin()));
    EXPECT_TRUE(a.shell.attached_mass_kg.empty());
    const auto count = static_cast<int64_t>(b.values[a.values.size()]);
    counts.insert(count);
    ASSERT_GE(count, 1);
    ASSERT_LE(count, 4);
    ASSERT_EQ(b.shell.attached_mass_kg.size(), static_cast<size_t>(count) + 6);
    double total = 0.0;
    for (int64_t k = 0; k < count; ++k) {
      const double kg = b.shell.attached_mass_kg[static_cast<size_t>(k)];
      const double z = b.shell.attached_mass_z_m[static_cast<size_t>(k)];
      EXPECT_GE(kg, 0.002);
      EXPECT_LE(kg, 0.03);
      EXPECT_LE(std::abs(z), 0.5 * tube.length_m - 0.005);
      total += kg;
      for (size_t h = 0; h < shell.hole_z_m.size(); ++h) {
        const double arc = tube.mid_radius_m() *
                           std::abs(WrapAngle((b.shell.attached_mass_theta_deg[k] -
                                               shell.hole_theta_deg[h]) * kDeg));
        EXPECT_GE(std::hypot(z - shell.hole_z_m[h], arc), shell.hole_diameter_m) << v << " " << k;
      }
    }
    EXPECT_NEAR(b.values[a.values.size() + 1], total, 1e-15);
    for (int d = 0; d < 6; ++d) {
      const size_t k = static_cast<size_t>(count + d);
      EXPECT_EQ(b.shell.attached_mass_z_m[k], mics.z_m[d]);
      EXPECT_EQ(b.shell.attached_mass_theta_deg[k], mics.theta_deg[d]);
      EXPECT_GE(b.shell.attached_mass_kg[k], 0.0005);
      EXPECT_LE(b.shell.attached_mass_kg[k], 0.002);
    }
  }
  EXPECT_GE(counts.size(), 3u);
  // a count without masses, or a fractional count, is refused naming the key
  RandomizeConfig bad = c;
  bad.attached_mass_count = {0, 3};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { bad.Validate(); }),
                    "randomize.attached_mass_kg"));
  bad.attached_mass_kg = {0.001, 0.01};
  bad.attached_mass_count = {0, 2.5};
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { bad.Validate(); }),
                    "randomize.attached_mass_count"));
}

TEST(RandomizeStructureTest, PoolVariantsAreDrawnStructuresWithTheirOwnModes) {
  AcousticModelConfig c = Coarse();
  c.audio.record_duration_s = 0.06;
  c.randomize.structure_variants = 3;
  c.randomize.bolt_stiffness_scale = {0.1, 10.0};
  c.randomize.flange_mount_scale = {0.2, 5.0};
  c.randomize.attached_mass_count = {1, 3};
  c.randomize.attached_mass_kg = {0.005, 0.03};
  c.randomize.disc_mass_kg = {0.001, 0.002};
  c.seed = 11;
  const StrikeSynthesizer synth(c);
  ASSERT_EQ(synth.structure_variants(), 3);
  const ContactEvent strike = Ball(0.05, -1.0, 0.4);
  Variation v;
  v.chain.sensitivity_scale.assign(6, 1.0);
  std::vector<Eigen::MatrixXf> audio;
  for (int64_t k = 0; k < 3; ++k) {
    v.structure.structure_variant = k;
    EXPECT_EQ(synth.StructureValues(k)[0], static_cast<double>(k));
    audio.push_back(synth.Render(strike, {}, {}, 0.0, 7, &v).audio);
  }
  // each variant sounds different from the others
  for (int a = 0; a < 3; ++a) {
    for (int b = a + 1; b < 3; ++b) {
      EXPECT_GT((audio[a] - audio[b]).cast<double>().norm() / audio[a].cast<double>().norm(), 0.05);
    }
  }
  // a variant renders as the same structure solved in full (the Ritz error, to 1 %)
  const StructureVariant draw =
      DrawStructure(c.randomize, {c.tube, c.shell, c.mics, c.material.poisson_ratio}, 11, 1);
  AcousticModelConfig full = Coarse();
  full.audio.record_duration_s = 0.06;
  full.shell = draw.shell;
  v.structure.structure_variant = 1;
  const RenderedStrike exact = StrikeSynthesizer(full).Render(strike, {}, {}, 0.0, 7, nullptr);
  const double err =
      (audio[1] - exact.audio).cast<double>().norm() / exact.audio.cast<double>().norm();
  std::cout << "Ritz variant against its full solve: " << err << " relative\n";
  EXPECT_LT(err, 0.05);
  // the fd rung cannot take a pool
  AcousticModelConfig fd = c;
  fd.synth.model = VibrationModel::kFd;
  EXPECT_TRUE(Names(ThrownMessage<ConfigError>([&] { StrikeSynthesizer s(fd); }),
                    "randomize.structure_variants"));
}

}  // namespace
}  // namespace sonicboom::acoustics
