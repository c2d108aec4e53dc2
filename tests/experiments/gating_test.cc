// The spectral gate's reference noise clip and its wiring into both feature paths.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/dsp/spectral_gate.h"
#include "sonicboom/experiments/pipeline.h"

namespace sonicboom::experiments {
namespace {

using testing::ThrownMessage;

using ::testing::HasSubstr;

SonicBoomConfig Config(const std::vector<std::string>& overrides = {}) {
  ConfigSources sources;
  sources.overrides = overrides;
  return ResolveConfig(sources);
}

std::string Sci(double v) {
  std::ostringstream out;
  out << std::scientific << std::setprecision(3) << v;
  return out.str();
}

TEST(ReferenceNoiseClipTest, RecordsOfTheNoiseModelDeterministicInTheSeed) {
  const SonicBoomConfig config = Config();
  const Eigen::MatrixXf a = ReferenceNoiseClip(config);
  ASSERT_EQ(a.rows(), config.mics.count());
  ASSERT_EQ(a.cols(), acoustics::kReferenceNoiseRecords * config.audio.num_samples());
  EXPECT_TRUE(a.allFinite());
  EXPECT_TRUE(a == ReferenceNoiseClip(config));  // bit for bit
  // the 16-bit converter's output: whole steps of 1 / 32767
  for (int64_t t = 0; t < 1000; ++t) {
    const double steps = a(0, t) * 32767.0;
    EXPECT_NEAR(steps, std::round(steps), 1e-3) << "sample " << t;
  }
  // no contact: motor tones at a held joint speed over the ambient and preamp floor, the same
  // level in both halves (a stationary clip)
  const int64_t half = a.cols() / 2;
  const double first_db = 10 * std::log10(a.leftCols(half).squaredNorm());
  const double second_db = 10 * std::log10(a.rightCols(half).squaredNorm());
  RecordProperty("rms", Sci(std::sqrt(a.squaredNorm() / a.size())));
  EXPECT_NEAR(first_db, second_db, 1.0);
  // another seed, another draw
  const Eigen::MatrixXf b = ReferenceNoiseClip(Config({"seed=2"}));
  EXPECT_GT((a - b).cwiseAbs().maxCoeff(), 1e-4f);
  // a robot that holds still has no motor tones: the floor alone (3.6e-5 rms plus the
  // converter's rounding)
  SonicBoomConfig still = config;
  still.scene.mode = sim::SceneMode::kStationary;
  const Eigen::MatrixXf c = ReferenceNoiseClip(still);
  const double still_rms = std::sqrt(c.squaredNorm() / c.size());
  RecordProperty("stationary_rms", Sci(still_rms));
  EXPECT_GT(still_rms, 2e-5);
  EXPECT_LT(still_rms, 6e-5);
  EXPECT_GT(a.squaredNorm(), 10 * c.squaredNorm());
}

// Noise drawn as the reference clip is (another seed: other channel gains, tone phases and
// noise) is attenuated by more than 20 dB over a 1.5 s window, on every channel.
TEST(ReferenceNoiseClipTest, NoiseOfAnotherSeedIsGatedByMoreThan20Db) {
  const SonicBoomConfig config = Config();
  const dsp::SpectralGate gate(dsp::GatingConfig(config.features), ReferenceNoiseClip(config),
                               config.audio.sample_rate_hz);
  const int64_t n = std::llround(config.features.window_s * config.audio.sample_rate_hz);
  for (const char* seed : {"seed=2", "seed=3"}) {
    const Eigen::MatrixXf other = ReferenceNoiseClip(Config({seed}));
    for (int c = 0; c < config.mics.count(); ++c) {
      const Eigen::VectorXf x = other.row(c).head(n).transpose();
      Eigen::VectorXf y(n);
      gate.Apply(x.data(), n, c, y.data());
      const double attenuation_db = 10 * std::log10(x.squaredNorm() / y.squaredNorm());
      RecordProperty(std::string(seed) + "_ch" + std::to_string(c) + "_attenuation_db",
                     Sci(attenuation_db));
      EXPECT_GT(attenuation_db, 20.0) << seed << " channel " << c;
    }
  }
}

TEST(ReferenceNoiseClipTest, ReadsTheConfiguredWavAndChecksIt) {
  testing::TempDir dir;
  SonicBoomConfig config = Config();
  AudioClip clip;
  clip.sample_rate_hz = config.audio.sample_rate_hz;
  clip.samples = ReferenceNoiseClip(Config({"seed=5"})).leftCols(30000);
  WriteWav(dir / "noise.wav", clip);
  config.features.gating_noise_wav = dir / "noise.wav";
  const Eigen::MatrixXf read = ReferenceNoiseClip(config);
  ASSERT_EQ(read.rows(), 6);
  ASSERT_EQ(read.cols(), 30000);
  EXPECT_LT((read - clip.samples).cwiseAbs().maxCoeff(), 1e-6f);

  auto error_for = [&](const AudioClip& bad) {
    WriteWav(dir / "bad.wav", bad);
    config.features.gating_noise_wav = dir / "bad.wav";
    return ThrownMessage<Error>([&] { ReferenceNoiseClip(config); });
  };
  AudioClip rate = clip;
  rate.sample_rate_hz = 22050;
  EXPECT_THAT(error_for(rate), HasSubstr("features.gating_noise_wav: " + (dir / "bad.wav") +
                                         " is sampled at 22050 Hz"));
  AudioClip channels = clip;
  channels.samples = clip.samples.topRows(2);
  EXPECT_THAT(error_for(channels), HasSubstr("has 2 channels; it needs one per microphone (6)"));
  AudioClip short_clip = clip;
  short_clip.samples = clip.samples.leftCols(500);
  EXPECT_THAT(error_for(short_clip),
              HasSubstr("has 500 frames, shorter than one gate frame (features.gating_n_fft = "
                        "1024)"));
  // a float WAV holding a NaN (WriteWav refuses to write one): header and samples by hand
  {
    const int channels_out = 6, frames = 2048;
    std::vector<float> data(static_cast<size_t>(channels_out * frames), 0.0f);
    data[77 * channels_out + 3] = std::nanf("");
    const uint32_t data_bytes = static_cast<uint32_t>(data.size() * sizeof(float));
    std::ofstream out(dir / "nan.wav", std::ios::binary);
    auto u32 = [&](uint32_t v) { out.write(reinterpret_cast<const char*>(&v), 4); };
    auto u16 = [&](uint16_t v) { out.write(reinterpret_cast<const char*>(&v), 2); };
    out.write("RIFF", 4);
    u32(36 + data_bytes);
    out.write("WAVEfmt ", 8);
    u32(16);
    u16(3);  // IEEE float
    u16(channels_out);
    u32(44100);
    u32(44100 * channels_out * 4);
    u16(channels_out * 4);
    u16(32);
    out.write("data", 4);
    u32(data_bytes);
    out.write(reinterpret_cast<const char*>(data.data()), data_bytes);
  }
  config.features.gating_noise_wav = dir / "nan.wav";
  const std::string nan = ThrownMessage<IoError>([&] { ReferenceNoiseClip(config); });
  EXPECT_THAT(nan, HasSubstr("features.gating_noise_wav"));
  EXPECT_THAT(nan, HasSubstr("nan.wav: frame 77 (0.0017 s) of channel 3 is nan"));
  config.features.gating_noise_wav = dir / "missing.wav";
  const std::string missing = ThrownMessage<IoError>([&] { ReferenceNoiseClip(config); });
  EXPECT_THAT(missing, HasSubstr("features.gating_noise_wav"));
  EXPECT_THAT(missing, HasSubstr("missing.wav: no such file"));
}

// Both feature paths gate with the same clip: a dataset's rows equal the record path on the
// same audio, and differ from the ungated features.
TEST(GatedFeaturesTest, DatasetAndRecordPathsGateAlike) {
  testing::TempDir dir;
  const SonicBoomConfig config =
      Config({"audio.record_duration_s=0.6", "audio.onset_time_s=0.25", "seed=11"});
  ASSERT_TRUE(config.features.gating);
  GenerateDataset(config, dir / "d.h5", {.count = 3});
  std::vector<uint64_t> indices;
  const learning::FeatureSet gated =
      ComputeDatasetFeatures(dir / "d.h5", config, 1, false, &indices);
  SonicBoomConfig off = config;
  off.features.gating = false;
  const learning::FeatureSet plain = ComputeDatasetFeatures(dir / "d.h5", off, 1, false);
  ASSERT_GT(gated.size(), 0);
  ASSERT_EQ(gated.mel.size(), plain.mel.size());
  EXPECT_NE(gated.mel, plain.mel);
  EXPECT_NE(gated.gcc, plain.gcc);

  DatasetReader reader(dir / "d.h5");
  int64_t row = 0;
  for (int64_t i = 0; i < reader.size(); ++i) {
    const StrikeSample sample = reader.Read(i);
    if (!sample.valid) continue;
    const learning::FeatureSet one =
        ComputeRecordFeatures(sample.audio, reader.info().sample_rate_hz, sample.proprio, config);
    const size_t mel_size = one.mel.size(), gcc_size = one.gcc.size();
    EXPECT_TRUE(std::equal(one.mel.begin(), one.mel.end(), gated.mel.begin() + row * mel_size))
        << "sample " << i;
    EXPECT_TRUE(std::equal(one.gcc.begin(), one.gcc.end(), gated.gcc.begin() + row * gcc_size))
        << "sample " << i;
    // what a model reads (localize): 20 centre frames and no GCC-PHAT, the same gated values
    const learning::FeatureNeeds needs{true, false, true, 30, 20};
    const RecordFeaturizer only(config, reader.info().sample_rate_hz, 6, needs);
    const learning::FeatureSet part = only.Compute(sample.audio, sample.proprio);
    ASSERT_EQ(part.frames, 20);
    EXPECT_TRUE(part.gcc.empty());
    EXPECT_EQ(part.proprio, one.proprio);
    ASSERT_EQ(part.mel.size(), static_cast<size_t>(6 * one.mels * 20));
    for (int64_t band = 0; band < 6 * one.mels; ++band) {
      EXPECT_TRUE(std::equal(part.mel.begin() + band * 20, part.mel.begin() + (band + 1) * 20,
                             one.mel.begin() + band * one.frames + 30))
          << "sample " << i << " channel-band " << band;
    }
    ++row;
  }
  EXPECT_EQ(row, gated.size());
}

TEST(GatedFeaturesTest, RecordsThatDoNotMatchTheClipAreRejected) {
  const SonicBoomConfig config = Config();
  const Eigen::MatrixXf four = Eigen::MatrixXf::Zero(4, 88200);
  EXPECT_THAT(ThrownMessage<ConfigError>([&] {
                ComputeRecordFeatures(four, config.audio.sample_rate_hz, Eigen::MatrixXf(), config);
              }),
              HasSubstr("records at 44100 Hz with 4 channels, but this command's config gates "
                        "(features.gating)"));
  SonicBoomConfig off = config;
  off.features.gating = false;
  EXPECT_NO_THROW(ComputeRecordFeatures(four, config.audio.sample_rate_hz, Eigen::MatrixXf(), off));
}

}  // namespace
}  // namespace sonicboom::experiments
