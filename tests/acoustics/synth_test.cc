// Strike rendering: Hertz contact, arrival-time and level cues, DAQ chain, determinism, limits.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>

#include "common/test_util.h"

#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

ContactEvent DowelContact(double z_m, double theta_rad, double speed) {
  ContactEvent c;
  c.time_s = 0.5;
  c.z_m = z_m;
  c.theta_rad = theta_rad;
  c.normal_speed_m_s = speed;
  c.effective_mass_kg = 0.010;
  c.striker_radius_m = 0.00635;
  c.striker_youngs_modulus_pa = 1e9;
  c.striker_poisson_ratio = 0.35;
  return c;
}

// the closed-form rung (ideal simply-supported tube) with default sensors
AcousticModelConfig ClosedForm(NoiseConfig noise = {}, DaqConfig daq = {}) {
  AcousticModelConfig c;
  c.synth.model = VibrationModel::kModalClosedForm;
  c.noise = noise;
  c.daq = daq;
  return c;
}

StrikeSynthesizer MakeSynth(NoiseConfig noise = {}, DaqConfig daq = {}) {
  return StrikeSynthesizer(ClosedForm(noise, daq));
}

// first sample whose |x| exceeds frac of the channel's peak
int64_t Arrival(const Eigen::MatrixXf& audio, int ch, double frac) {
  const float peak = audio.row(ch).cwiseAbs().maxCoeff();
  for (int64_t k = 0; k < audio.cols(); ++k) {
    if (std::abs(audio(ch, k)) >= frac * peak) return k;
  }
  return -1;
}

TEST(HertzTest, DowelCrossingPipeMatchesClosedForm) {
  // docs/physics.md, "Hertz impact": dowel side (Ø12.7 mm, E_T 1 GPa) across R 55 mm, 10 g, 0.5 m/s
  TubeConfig tube;
  tube.outer_radius_m = 0.055;
  const HertzImpact h = SolveHertzImpact(DowelContact(0, 0, 0.5), tube, MaterialConfig{});
  EXPECT_NEAR(h.max_compression_m, 52.5e-6, 0.01 * 52.5e-6);
  EXPECT_NEAR(h.peak_force_n, 59.6, 0.01 * 59.6);
  EXPECT_NEAR(h.duration_s, 309e-6, 0.01 * 309e-6);
  // an elastic impact returns twice the momentum
  EXPECT_NEAR(h.impulse_ns, 2 * 0.010 * 0.5, 0.01 * 0.010);
  // t_c grows as v^(-1/5)
  const HertzImpact slow = SolveHertzImpact(DowelContact(0, 0, 0.05), tube, MaterialConfig{});
  EXPECT_NEAR(slow.duration_s / h.duration_s, std::pow(10.0, 0.2), 1e-9);
}

TEST(SynthTest, FiniteNonSilentAndDeterministic) {
  NoiseConfig noise;
  const StrikeSynthesizer synth = MakeSynth(noise);
  const std::vector<double> speed(200, 0.2);
  const RenderedStrike a = synth.Render(DowelContact(0.03, 1.0, 0.1), speed, 100.0, 77);
  const RenderedStrike b = synth.Render(DowelContact(0.03, 1.0, 0.1), speed, 100.0, 77);
  ASSERT_EQ(a.audio.rows(), 6);
  ASSERT_EQ(a.audio.cols(), 88200);
  EXPECT_TRUE(a.audio.allFinite());
  EXPECT_FALSE(a.clipped);
  EXPECT_GT(a.audio.cwiseAbs().maxCoeff(), 0.01);
  EXPECT_TRUE(a.audio.isApprox(b.audio, 0.0f));
  EXPECT_GT(a.modes_used, 50);
  // 16-bit output: every value on the 1/32767 grid
  for (int k = 0; k < 1000; ++k) {
    const double q = a.audio(0, 44000 + k) * 32767.0;
    EXPECT_NEAR(q, std::round(q), 1e-3);
  }
}

TEST(SynthTest, NearRingHearsFirstAndLouder) {
  // no noise: a contact near the +z ring reaches mics 3-5 before mics 0-2
  NoiseConfig quiet;
  quiet.ambient_rms_v = 0;
  quiet.motor_rms_v_per_rad_s = 0;
  DaqConfig daq;
  daq.preamp_noise_v = 0;
  daq.gain_mismatch_db = 0;
  const StrikeSynthesizer synth = MakeSynth(quiet, daq);
  const RenderedStrike r = synth.Render(DowelContact(0.09, 0.0, 0.1), {}, 100.0, 1);
  const int64_t near = Arrival(r.audio, 3, 0.1), far = Arrival(r.audio, 0, 0.1);
  EXPECT_LT(near, far);
  EXPECT_GT(r.audio.row(3).cwiseAbs().maxCoeff(), r.audio.row(0).cwiseAbs().maxCoeff());
  // nothing before the contact
  EXPECT_EQ(r.audio.block(0, 0, 6, 22000).cwiseAbs().maxCoeff(), 0.0f);
}

TEST(SynthTest, HardHitClipsAndIsFlagged) {
  const StrikeSynthesizer synth = MakeSynth();
  const RenderedStrike r = synth.Render(DowelContact(0.1, 0.0, 10.0), {}, 100.0, 3);
  EXPECT_TRUE(r.clipped);
  EXPECT_TRUE(r.audio.allFinite());
  EXPECT_LE(r.audio.cwiseAbs().maxCoeff(), 1.0f);
}

TEST(SynthTest, ExtremesStayFinite) {
  // slowest and fastest strikes, both ends of the contact region, theta at +-pi
  const StrikeSynthesizer synth = MakeSynth();
  for (double v : {0.01, 10.0}) {
    for (double z : {-0.1015, 0.1015}) {
      for (double th : {std::numbers::pi, -std::numbers::pi + 1e-12}) {
        const RenderedStrike r = synth.Render(DowelContact(z, th, v), {}, 100.0, 5);
        EXPECT_TRUE(r.audio.allFinite());
        EXPECT_GT(r.audio.cwiseAbs().maxCoeff(), 0.0f);
      }
    }
  }
}

TEST(SynthTest, RefusesBandAboveNyquist) {
  AcousticModelConfig c = ClosedForm();
  c.synth.max_frequency_hz = 30000;
  try {
    StrikeSynthesizer s(c);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("Nyquist"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("22050"), std::string::npos);
  }
}

// A band below 1 kHz (it crashed the renderer at 10, 50 and 200 Hz) and a wall too thin for the
// solved band (1 um: the solve ran for minutes without a line) are refused at once, naming the
// key, its value and the limit; the closed form and the shell's modal rung alike.
TEST(ExtremesTest, DegenerateBandsAndWallsAreRefusedNamingTheKeyAndTheLimit) {
  for (const VibrationModel model : {VibrationModel::kModalClosedForm, VibrationModel::kModal}) {
    // the ConfigError message of this rung's synthesizer on the default set-up after `edit`
    auto refusal = [model](const std::function<void(AcousticModelConfig*)>& edit) {
      AcousticModelConfig c = ClosedForm();
      c.synth.model = model;
      edit(&c);
      return sonicboom::testing::ThrownMessage<ConfigError>([&] { StrikeSynthesizer s(c); });
    };
    for (const double hz : {10.0, 50.0, 200.0}) {
      const std::string message =
          refusal([hz](AcousticModelConfig* c) { c->synth.max_frequency_hz = hz; });
      EXPECT_NE(message.find("acoustics.max_frequency_hz = " + fmt::format("{}", hz)),
                std::string::npos)
          << message;
      EXPECT_NE(message.find("below 1000 Hz"), std::string::npos) << message;
    }
    EXPECT_NE(refusal([](AcousticModelConfig* c) { c->synth.mode_band_hz = 100.0; })
                  .find("acoustics.mode_band_hz = 100 Hz"),
              std::string::npos);
    const auto start = std::chrono::steady_clock::now();
    const std::string thin =
        refusal([](AcousticModelConfig* c) { c->tube.wall_thickness_m = 1e-6; });
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
              1.0);
    EXPECT_NE(thin.find("tube.wall_thickness_m = 1e-06 m"), std::string::npos) << thin;
    EXPECT_NE(thin.find("more than the 5000 a modal solve takes"), std::string::npos) << thin;
    // the same count bounds the other axes that grow it: a 9 m tube, a 10 MPa wall
    EXPECT_NE(refusal([](AcousticModelConfig* c) { c->tube.length_m = 9.0; })
                  .find("tube.length_m = 9 m"),
              std::string::npos);
    EXPECT_NE(refusal([](AcousticModelConfig* c) { c->material.youngs_modulus_pa = 1e7; })
                  .find("material.youngs_modulus_pa = 10000000 Pa"),
              std::string::npos);
  }
  // the default wall at the default band, and the lowest band allowed, still render
  AcousticModelConfig c = ClosedForm();
  c.synth.max_frequency_hz = 1000.0;
  const StrikeSynthesizer low(c);
  EXPECT_TRUE(low.Render(DowelContact(0.05, 0.3, 0.5), {}, 100.0, 5).audio.allFinite());
}

TEST(DaqTest, HighPassCornerFromDiscAndInput) {
  DaqConfig daq;
  EXPECT_NEAR(daq.highpass_hz(), 1.0 / (2 * std::numbers::pi * 1e6 * 16e-9), 1e-9);
  daq.input_resistance_ohm = 50e3;  // line input: ~200 Hz
  EXPECT_NEAR(daq.highpass_hz(), 199, 1);
}

}  // namespace
}  // namespace sonicboom::acoustics
