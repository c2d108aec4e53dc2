// The strike renderer on the discretized shell: the modal rung (numerical modes, contact solve,
// episodes) against the FD rung, the derived band, per-channel DAQ, noise injection, the extremes.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "../common/test_util.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;

// one mode cache for the whole suite (the coarse tube's modes are solved once)
const testing::TempDir& Cache() {
  static const testing::TempDir dir;
  return dir;
}

// a coarse seamed tube (10 mm grid), modes to 12 kHz, noise off, gain mismatch off
AcousticModelConfig Coarse(VibrationModel model = VibrationModel::kModal) {
  AcousticModelConfig c;
  c.shell.grid_spacing_m = 0.01;
  c.shell.axial_spacing_m = 0.01;
  // the thin shell the FD rung integrates (the thick-plate correction is dispersion_test's)
  c.shell.dispersion = Dispersion::kThin;
  c.shell.damping =
      DampingModel::kRayleigh;  // the damping the FD rung realizes too, so that rungs compare
  c.synth.model = model;
  c.synth.mode_band_hz = 12000;
  c.synth.mode_cache_dir = Cache().path().string();
  c.noise.ambient_rms_v = 0;
  c.noise.motor_rms_v_per_rad_s = 0;
  c.daq.preamp_noise_v = 0;
  c.daq.gain_mismatch_db = 0;
  return c;
}

ContactEvent Dowel(double z_m, double theta_rad, double speed_m_s, double time_s = 0.1) {
  ContactEvent c;
  c.time_s = time_s;
  c.z_m = z_m;
  c.theta_rad = theta_rad;
  c.normal_speed_m_s = speed_m_s;
  c.effective_mass_kg = 0.03;
  c.striker_radius_m = 0.011;
  c.striker_youngs_modulus_pa = 1e9;
  c.striker_poisson_ratio = 0.35;
  return c;
}

// first sample whose |x| exceeds frac of the channel's peak
int64_t Arrival(const Eigen::MatrixXf& audio, int ch, double frac) {
  const float peak = audio.row(ch).cwiseAbs().maxCoeff();
  for (int64_t k = 0; k < audio.cols(); ++k) {
    if (std::abs(audio(ch, k)) >= frac * peak) return k;
  }
  return -1;
}

TEST(StrikeRenderTest, ModalRungIsFiniteDeterministicAndCarriesTheCues) {
  const StrikeSynthesizer synth(Coarse());
  // near the first ring (z = -0.1 m side) at the first mic's angle
  const RenderedStrike a = synth.Render(Dowel(-0.09, 0.0, 0.1), {}, 0.0, 7);
  const RenderedStrike b = synth.Render(Dowel(-0.09, 0.0, 0.1), {}, 0.0, 7);
  ASSERT_TRUE(a.audio.allFinite());
  EXPECT_EQ(a.audio, b.audio);
  EXPECT_FALSE(a.clipped);
  EXPECT_GT(a.modes_used, 50);
  EXPECT_EQ(a.touches, 1);
  // the contact is coupled to the wall: the same order as the rigid-wall Hertz pulse
  const HertzImpact rigid =
      SolveHertzImpact(Dowel(-0.09, 0.0, 0.1), TubeConfig{}, MaterialConfig{});
  EXPECT_GT(a.duration_s, 0.9 * rigid.duration_s);
  EXPECT_LT(a.duration_s, 2.0 * rigid.duration_s);
  // the wall yields, so the contact lasts clearly longer than against a rigid wall (1.9x here; a
  // contact solved without the wall's compliance would give 1.0x)
  EXPECT_GT(a.duration_s, 1.2 * rigid.duration_s);
  EXPECT_LE(a.impulse_ns, 2 * 0.03 * 0.1 * 1.001);
  // arrival-time and level cues: the near ring (mics 0-2) hears first and louder than the far one
  const MicArrayConfig mics;
  int near = 0, far = 0;
  for (int i = 0; i < 6; ++i) (mics.z_m[i] < 0 ? near : far) = i;
  EXPECT_LT(Arrival(a.audio, near, 0.2), Arrival(a.audio, far, 0.2));
  double near_rms = 0, far_rms = 0;
  for (int i = 0; i < 6; ++i) {
    (mics.z_m[i] < 0 ? near_rms : far_rms) += a.audio.row(i).squaredNorm();
  }
  EXPECT_GT(near_rms, far_rms);
}

TEST(StrikeRenderTest, BandFollowsTheContactUnlessOverridden) {
  const StrikeSynthesizer synth(Coarse());
  // a slow strike lasts longer, so its band and mode count are smaller
  const RenderedStrike slow = synth.Render(Dowel(0.02, 1.0, 0.01), {}, 0.0, 1);
  const RenderedStrike fast = synth.Render(Dowel(0.02, 1.0, 1.0), {}, 0.0, 1);
  EXPECT_GT(slow.duration_s, fast.duration_s);
  EXPECT_LT(slow.band_hz, fast.band_hz);
  EXPECT_LE(slow.modes_used, fast.modes_used);
  EXPECT_NEAR(slow.band_hz, synth.BandFor(slow.duration_s), 1e-9);  // one touch: closure = duration
  // a fixed mode count overrides the band
  AcousticModelConfig c = Coarse();
  c.synth.mode_count = 40;
  const RenderedStrike fixed = StrikeSynthesizer(c).Render(Dowel(0.02, 1.0, 1.0), {}, 0.0, 1);
  EXPECT_EQ(fixed.modes_used, 40);
}

// a fixed band needs no mode above it (the contact's wall and the signal play the band, the
// residual stands for the rest): solved to 1.25 x the band, the strike is the one solved to 12 kHz
TEST(StrikeRenderTest, AFixedBandSolvesOnlyTheModesItPlays) {
  AcousticModelConfig wide = Coarse();
  wide.shell.dispersion = Dispersion::kThickPlate;  // the correction the headroom is for
  wide.synth.max_frequency_hz = 3000;
  AcousticModelConfig narrow = wide;
  narrow.synth.mode_band_hz = 0;
  EXPECT_DOUBLE_EQ(SolvedModeBandHz(narrow.synth, 44100.0, narrow.randomize), 3750.0);
  EXPECT_DOUBLE_EQ(SolvedModeBandHz(wide.synth, 44100.0, wide.randomize), 12000.0);  // mode_band_hz set: as asked
  const StrikeSynthesizer a(wide), b(narrow);
  EXPECT_LT(b.mode_count(), a.mode_count() / 2);
  const RenderedStrike ra = a.Render(Dowel(0.03, 0.7, 0.5), {}, 0.0, 3);
  const RenderedStrike rb = b.Render(Dowel(0.03, 0.7, 0.5), {}, 0.0, 3);
  EXPECT_EQ(ra.modes_used, rb.modes_used);
  EXPECT_NEAR(ra.duration_s, rb.duration_s, 1e-6 * ra.duration_s);
  const double peak = ra.audio.cwiseAbs().maxCoeff();
  ASSERT_GT(peak, 0.0);
  EXPECT_LT((ra.audio - rb.audio).cwiseAbs().maxCoeff(), 1e-4 * peak);
  // a drawn material moves modes across the band: then every mode is solved
  AcousticModelConfig drawn = narrow;
  drawn.randomize.youngs_modulus_scale = {0.8, 1.2};
  EXPECT_DOUBLE_EQ(SolvedModeBandHz(drawn.synth, 44100.0, drawn.randomize), narrow.synth.ModeBandHz(44100.0));
}

TEST(StrikeRenderTest, FdRungAgreesWithModalRung) {
  // the same structure, force and sensors: only time integration and truncation differ
  AcousticModelConfig c = Coarse(VibrationModel::kFd);
  c.audio.record_duration_s = 0.03;
  c.audio.onset_time_s = 0.005;
  c.daq.input_resistance_ohm = 1e9;  // high-pass far below the record's band
  c.daq.adc_bits = 32;
  c.daq.output_bits = 32;
  const RenderedStrike fd = StrikeSynthesizer(c).Render(Dowel(0.03, 0.7, 0.3, 0.005), {}, 0.0, 3);
  c.synth.model = VibrationModel::kModal;
  c.synth.max_frequency_hz = 12000;
  const RenderedStrike modal =
      StrikeSynthesizer(c).Render(Dowel(0.03, 0.7, 0.3, 0.005), {}, 0.0, 3);
  ASSERT_TRUE(fd.audio.allFinite());
  const double err = (fd.audio - modal.audio).norm() / fd.audio.norm();
  std::printf("FD vs modal (10 mm grid, 12 kHz band + residual): relative error %.4f\n", err);
  EXPECT_LT(err, 0.05);
}

TEST(StrikeRenderTest, EpisodesPlayBouncesPressesAndBrushes) {
  const StrikeSynthesizer synth(Coarse());
  const ContactEvent first = Dowel(0.0, 0.5, 0.2);
  const RenderedStrike alone = synth.Render(first, {}, 0.0, 2);
  // the same impact, a bounce 20 ms later, then a press and a foliage brush
  std::vector<ContactEpisode> eps(4);
  eps[0].time_s = first.time_s;
  eps[0].z_m = first.z_m;
  eps[0].theta_rad = first.theta_rad;
  eps[0].normal_speed_m_s = 0.2;
  eps[0].effective_mass_kg = 0.03;
  eps[1] = eps[0];
  eps[1].kind = ContactEpisode::Kind::kBounce;
  eps[1].time_s = first.time_s + 0.02;
  eps[1].normal_speed_m_s = 0.05;
  eps[2] = eps[0];
  eps[2].kind = ContactEpisode::Kind::kPress;
  eps[2].time_s = first.time_s + 0.1;
  eps[2].duration_s = 0.2;
  eps[2].impulse_Ns = 2.0;
  eps[2].normal_speed_m_s = 0;
  eps[3].kind = ContactEpisode::Kind::kBrush;
  eps[3].time_s = 0.5;
  eps[3].duration_s = 0.1;
  eps[3].z_m = 0.1;
  eps[3].theta_rad = -2.0;
  const RenderedStrike all = synth.Render(first, eps, {}, 0.0, 2);
  EXPECT_EQ(alone.forces_played, 1);
  EXPECT_EQ(all.forces_played, 4);
  // up to the bounce the two records agree; after it they differ
  const double fs = AudioConfig{}.sample_rate_hz;
  const int64_t bounce = static_cast<int64_t>(eps[1].time_s * fs);
  EXPECT_EQ(all.audio.leftCols(bounce), alone.audio.leftCols(bounce));
  EXPECT_GT((all.audio - alone.audio).middleCols(bounce, 400).norm(), 0.0f);
  // the brush adds energy in its span that the lone impact lacks
  const int64_t b0 = static_cast<int64_t>(0.52 * fs), len = static_cast<int64_t>(0.06 * fs);
  EXPECT_GT(all.audio.middleCols(b0, len).squaredNorm(),
            4 * alone.audio.middleCols(b0, len).squaredNorm());
  // the first contact's figures are the same with or without the other episodes
  EXPECT_EQ(all.impulse_ns, alone.impulse_ns);
}

// A brush that lands in a cable hole has no wall to act on: its rustle is skipped and the rest
// of the record is played (it threw from the bank, outside the catch meant for it, and ended
// the whole generation run).
TEST(StrikeRenderTest, ABrushInAHoleIsSkippedNotFatal) {
  AcousticModelConfig c = Coarse();
  c.shell.hole_diameter_m = 0.02;  // wider than the coarse grid's cells: nodes are removed
  c.noise.foliage_force_rms_n = 0.05;
  const StrikeSynthesizer synth(c);
  const ContactEvent first = Dowel(0.0, 0.5, 0.2);
  std::vector<ContactEpisode> eps(1);
  eps[0].kind = ContactEpisode::Kind::kBrush;
  eps[0].time_s = 0.5;
  eps[0].duration_s = 0.1;
  eps[0].z_m = c.shell.hole_z_m[0];
  eps[0].theta_rad = c.shell.hole_theta_deg[0] * kPi / 180.0;
  const ShellModel shell(c.tube, c.material, c.shell);
  ASSERT_FALSE(shell.AcceptsForce(eps[0].z_m, eps[0].theta_rad));
  EXPECT_THROW(shell.RadialForceWeights(eps[0].z_m, eps[0].theta_rad), ConfigError);
  const RenderedStrike in_hole = synth.Render(first, eps, {}, 0.0, 2);
  EXPECT_EQ(in_hole.forces_played, 1);
  EXPECT_TRUE(in_hole.audio.allFinite());
  // beside the hole the same brush is played
  eps[0].theta_rad += 0.5;
  ASSERT_TRUE(shell.AcceptsForce(eps[0].z_m, eps[0].theta_rad));
  EXPECT_EQ(synth.Render(first, eps, {}, 0.0, 2).forces_played, 2);
}

TEST(StrikeRenderTest, ExtremesStayFiniteAndFlagClipping) {
  // speeds 0.01-10 m/s, both ends of the contact region, theta at +-pi
  const StrikeSynthesizer synth(Coarse());
  const TubeConfig tube;
  for (double v : {0.01, 10.0}) {
    for (double z : {tube.contact_z_min_m, tube.contact_z_max_m}) {
      for (double th : {kPi, -kPi + 1e-12}) {
        const RenderedStrike r = synth.Render(Dowel(z, th, v), {}, 0.0, 5);
        ASSERT_TRUE(r.audio.allFinite()) << v << " " << z << " " << th;
        EXPECT_GT(r.audio.cwiseAbs().maxCoeff(), 0.0f);
        // the hardest strike clips the converter and says so; the softest does not
        EXPECT_EQ(r.clipped, v == 10.0);
      }
    }
  }
  // loss factors 1e-4 and 0.2, sample rates 16 and 192 kHz
  for (double loss : {1e-4, 0.2}) {
    for (double fs : {16000.0, 192000.0}) {
      AcousticModelConfig c = Coarse();
      c.material.loss_factor = loss;
      c.audio.sample_rate_hz = fs;
      c.audio.record_duration_s = 0.3;
      c.synth.mode_band_hz = std::min(12000.0, 0.45 * fs);
      const RenderedStrike r = StrikeSynthesizer(c).Render(Dowel(0.05, -1.0, 1.0), {}, 0.0, 9);
      ASSERT_TRUE(r.audio.allFinite()) << loss << " " << fs;
      EXPECT_GT(r.audio.cwiseAbs().maxCoeff(), 0.0f) << loss << " " << fs;
      EXPECT_GT(r.modes_used, 0);
    }
  }
  // acoustics.band_factor at its smallest values derives a band of a few Hz from the contact (it
  // left the bank no mode and crashed with SIGSEGV): the band is raised to 1 kHz and plays
  for (const double factor : {1e-3, 1e-2}) {
    AcousticModelConfig c = Coarse();
    c.synth.band_factor = factor;
    c.audio.record_duration_s = 0.3;
    const RenderedStrike r = StrikeSynthesizer(c).Render(Dowel(0.05, -1.0, 1.0), {}, 0.0, 9);
    ASSERT_TRUE(r.audio.allFinite()) << factor;
    EXPECT_GT(r.modes_used, 0) << factor;
    EXPECT_GT(r.audio.cwiseAbs().maxCoeff(), 0.0f) << factor;
  }
}

TEST(DaqChainTest, PerChannelGainAndHighPass) {
  AcousticModelConfig c = Coarse();
  c.daq.channel_gain_db = {0, 6.0206, 0, 0, 0, 0};  // channel 1 at twice the gain
  c.daq.channel_input_resistance_ohm = {1e6, 1e6, 1e6, 1e6, 1e6, 5e4};
  EXPECT_NEAR(c.daq.highpass_hz(5), 1.0 / (2 * kPi * 5e4 * 16e-9), 1e-6);
  // strain equal on channels 0 and 1 (a constant-strain step), converted
  const DaqChain chain(c.daq, c.noise, 6, 44100, 4410);
  Eigen::MatrixXd strain = Eigen::MatrixXd::Constant(6, 4410, 1e-5);
  Eigen::MatrixXf audio;
  EXPECT_FALSE(chain.Convert(strain, {}, 0.0, 1, &audio));
  EXPECT_NEAR(audio(1, 0) / audio(0, 0), 2.0, 1e-3);
  // the 200 Hz high-pass of channel 5 removes the step far faster than the 10 Hz one of channel 0
  EXPECT_LT(std::abs(audio(5, 441)), 0.01 * std::abs(audio(5, 0)));
  EXPECT_GT(std::abs(audio(0, 441)), 0.5 * std::abs(audio(0, 0)));
  // a list of the wrong length is refused, naming the key
  c.daq.channel_gain_db = {0, 1};
  try {
    c.daq.Validate(6);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("daq.channel_gain_db"), std::string::npos);
  }
}

TEST(DaqChainTest, RecordedNoiseIsInjectedAndCheckedWhenLoaded) {
  const testing::TempDir dir;
  // one-channel background of 0.5 s at 44.1 kHz: a 1 kHz tone at 0.01 full scale
  AudioClip clip;
  clip.sample_rate_hz = 44100;
  clip.samples.resize(1, 22050);
  for (int64_t k = 0; k < 22050; ++k)
    clip.samples(0, k) = 0.01f * std::sin(2 * kPi * 1000 * k / 44100.0);
  WriteWav(dir / "bg.wav", clip, false);
  AcousticModelConfig c = Coarse();
  c.noise.wav_files = {dir / "bg.wav"};
  c.noise.wav_gain = 1.0;
  const DaqChain chain(c.daq, c.noise, 6, 44100, 4410);
  Eigen::MatrixXf audio;
  chain.Convert(Eigen::MatrixXd::Zero(6, 4410), {}, 0.0, 3, &audio);
  // every channel carries the tone at 0.01 full scale (rms 0.00707)
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(std::sqrt(audio.row(i).squaredNorm() / 4410), 0.00707, 0.0005);
  }
  // a recording at the wrong rate or shorter than a record is refused, naming the file
  clip.sample_rate_hz = 48000;
  WriteWav(dir / "bg48.wav", clip, false);
  c.noise.wav_files = {dir / "bg48.wav"};
  try {
    DaqChain bad(c.daq, c.noise, 6, 44100, 4410);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bg48.wav"), std::string::npos);
  }
  c.noise.wav_files = {dir / "bg.wav"};
  EXPECT_THROW(DaqChain(c.daq, c.noise, 6, 44100, 44100), ConfigError);
}


// The render's stages read one view of a sample's draws: an empty draw is the configured set-up
// on every rung (bit for bit), a striker draw alone leaves the structure nominal (every rung
// plays it, as the contact with that striker), and a structure draw is refused by the rungs that
// cannot follow it, naming acoustics.model.
TEST(RenderStagesTest, AnEmptyDrawIsTheConfiguredSetUpAndOnlyTheModalRungFollowsAStructure) {
  EXPECT_TRUE(StructureDraw{}.Nominal());
  StructureDraw moved;
  moved.mic_z_offset_m.assign(6, 0.0);
  EXPECT_FALSE(moved.Nominal());  // placed, even by zero: the placed-disc tables are used
  StructureDraw pooled;
  pooled.structure_variant = 0;
  EXPECT_FALSE(pooled.Nominal());
  for (const VibrationModel model :
       {VibrationModel::kModal, VibrationModel::kFd, VibrationModel::kModalClosedForm}) {
    SCOPED_TRACE(std::string(NameOf(model)));
    AcousticModelConfig c = Coarse(model);
    c.audio.record_duration_s = 0.02;
    c.audio.onset_time_s = 0.005;
    const StrikeSynthesizer synth(c);
    const ContactEvent strike = Dowel(0.04, 0.9, 0.3, 0.005);
    const Variation empty;
    const RenderedStrike plain = synth.Render(strike, {}, {}, 0.0, 5, nullptr);
    const RenderedStrike drawn = synth.Render(strike, {}, {}, 0.0, 5, &empty);
    EXPECT_TRUE(plain.audio.cwiseEqual(drawn.audio).all());
    EXPECT_EQ(plain.duration_s, drawn.duration_s);
    // a striker draw is the contact with that striker, bit for bit, on every rung
    Variation hard;
    hard.striker.youngs_modulus_pa = 200e9;
    hard.striker.speed_scale = 2.0;
    EXPECT_TRUE(hard.structure.Nominal());
    ContactEvent steel = strike;
    steel.striker_youngs_modulus_pa = 200e9;
    steel.normal_speed_m_s = 0.6;
    const RenderedStrike by_draw = synth.Render(strike, {}, {}, 0.0, 5, &hard);
    EXPECT_TRUE(by_draw.audio.cwiseEqual(synth.Render(steel, {}, {}, 0.0, 5, nullptr).audio).all());
    EXPECT_GT((by_draw.audio - plain.audio).norm(), 0.05 * plain.audio.norm());
    // a stiffer tube: the modal rung plays it, the others name the key they need
    Variation stiff;
    stiff.structure.youngs_modulus_scale = 1.2;
    if (model == VibrationModel::kModal) {
      const RenderedStrike r = synth.Render(strike, {}, {}, 0.0, 5, &stiff);
      EXPECT_GT((r.audio - plain.audio).norm(), 0.05 * plain.audio.norm());
    } else {
      const std::string message = testing::ThrownMessage<ConfigError>(
          [&] { synth.Render(strike, {}, {}, 0.0, 5, &stiff); });
      EXPECT_NE(message.find("acoustics.model = modal"), std::string::npos) << message;
    }
  }
}


// acoustics.render_span = features without the span the pipeline derives from the features is
// refused naming the key; with it, the strain after the span is silent (noise off: the record
// ends in zeros) while the whole record rings on.
TEST(RenderStagesTest, AFeatureSpanNeedsItsLengthAndSilencesTheRestOfTheRecord) {
  AcousticModelConfig c = Coarse();
  c.audio.record_duration_s = 0.1;
  c.audio.onset_time_s = 0.01;
  c.synth.render_span = RenderSpan::kFeatures;
  const std::string message = testing::ThrownMessage<ConfigError>([&] { StrikeSynthesizer s(c); });
  EXPECT_NE(message.find("acoustics.render_span = features"), std::string::npos) << message;
  c.synth.span_after_contact_s = 0.02;
  const RenderedStrike span = StrikeSynthesizer(c).Render(Dowel(0.04, 0.9, 0.3, 0.01), {}, 0.0, 5);
  c.synth.render_span = RenderSpan::kRecord;
  const RenderedStrike whole = StrikeSynthesizer(c).Render(Dowel(0.04, 0.9, 0.3, 0.01), {}, 0.0, 5);
  // the span ends 30 ms into the record; the DAQ's high-pass lets the last value decay
  const Eigen::MatrixXf tail_span = span.audio.rightCols(2205);  // the last 50 ms
  const Eigen::MatrixXf tail_whole = whole.audio.rightCols(2205);
  EXPECT_LT(tail_span.cwiseAbs().maxCoeff(), 0.01 * tail_whole.cwiseAbs().maxCoeff());
  EXPECT_TRUE(span.audio.leftCols(1200).cwiseEqual(whole.audio.leftCols(1200)).all());
}

}  // namespace
}  // namespace sonicboom::acoustics
