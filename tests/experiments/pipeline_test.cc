// Determinism of generated data across thread counts and shards.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "common/test_util.h"
#include "experiments/dataset_expect.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::experiments {
namespace {

TEST(PipelineTest, BitIdenticalForOneAndTwoThreads) {
  testing::TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  GenerateDataset(config, dir / "t1.h5", {.count = 12});
  GenerateDataset(config, dir / "t2.h5", {.count = 12, .threads = 2});
  ExpectSameSamples(dir / "t1.h5", dir / "t2.h5");
}

TEST(PipelineTest, ShardsMergeToTheSingleFile) {
  testing::TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  GenerateDataset(config, dir / "all.h5", {.count = 9, .threads = 2});
  GenerateDataset(config, dir / "s0.h5", {.count = 9, .num_shards = 2});
  GenerateDataset(config, dir / "s1.h5", {.count = 9, .shard = 1, .num_shards = 2, .threads = 2});
  MergeDatasets({dir / "s1.h5", dir / "s0.h5"}, dir / "merged.h5");
  ExpectSameSamples(dir / "all.h5", dir / "merged.h5");
}

TEST(PipelineTest, MujocoEngineHitsWhereTheKinematicStrikeAims) {
  // the default engine is the dynamic rollout; it lands within 1 mm of the kinematic target
  SonicBoomConfig dynamic = ShortConfig();
  ASSERT_EQ(dynamic.strike.engine, sim::StrikeEngine::kMujoco);
  SonicBoomConfig kinematic = dynamic;
  kinematic.strike.engine = sim::StrikeEngine::kKinematic;
  const StrikePipeline a(dynamic), b(kinematic);
  for (uint64_t i = 0; i < 4; ++i) {
    const StrikeSample sa = a.Simulate(i), sb = b.Simulate(i);
    ASSERT_TRUE(sa.valid) << sa.invalid_reason;
    EXPECT_NEAR(sa.label.z_m, sb.label.z_m, 1e-3);
    EXPECT_NE(sa.label.z_m, sb.label.z_m);  // a real contact, not the kinematic label
    EXPECT_GT(sa.label.impulse_Ns, 0.0);
    EXPECT_TRUE(sa.audio.allFinite());
    // the rollout keeps every contact; the first is the impact that acoustics played
    ASSERT_FALSE(sa.contacts.empty());
    EXPECT_EQ(sa.contacts.front().kind, ContactEpisode::Kind::kImpact);
    EXPECT_EQ(sa.contacts.front().z_m, sa.label.z_m);
    EXPECT_EQ(sa.contacts.front().object, "rod T22L42");
    ASSERT_EQ(sb.contacts.size(), 1u);
  }
}

TEST(PipelineTest, SplitDependsOnlyOnSampleIndex) {
  std::vector<uint64_t> idx(1000);
  for (uint64_t i = 0; i < idx.size(); ++i) idx[i] = i;
  const auto [train, val] = SplitRows(idx, 0.2, 3);
  EXPECT_NEAR(static_cast<double>(val.size()) / idx.size(), 0.2, 0.04);
  EXPECT_EQ(train.size() + val.size(), idx.size());
  // the same indices in another order land on the same side
  std::vector<uint64_t> rev(idx.rbegin(), idx.rend());
  const auto [train_r, val_r] = SplitRows(rev, 0.2, 3);
  ASSERT_EQ(val_r.size(), val.size());
  std::vector<uint64_t> a, b;
  for (auto r : val) a.push_back(idx[r]);
  for (auto r : val_r) b.push_back(rev[r]);
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
  // a few strikes all of whose draws fall on one side still split, one row moved, and a split
  // that has both sides stays as drawn (10 strikes from index 120000, seed 1: a fine-tune's pool
  // that once validated on nothing)
  for (uint64_t first = 0; first < 200000; first += 1000) {
    std::vector<uint64_t> few(3);
    for (uint64_t i = 0; i < few.size(); ++i) few[i] = first + i;
    const auto [t, v] = SplitRows(few, 0.2, 1);
    ASSERT_FALSE(t.empty()) << first;
    ASSERT_FALSE(v.empty()) << first;
    ASSERT_EQ(t.size() + v.size(), few.size());
  }
  std::vector<uint64_t> pool(10);
  for (uint64_t i = 0; i < pool.size(); ++i) pool[i] = 120000 + i;
  EXPECT_EQ(SplitRows(pool, 0.2, 1).second.size(), 1u);
  EXPECT_EQ(SplitRows(idx, 0.2, 3).second, val);
  EXPECT_TRUE(SplitRows({7}, 0.2, 3).second.empty() || SplitRows({7}, 0.2, 3).first.empty());
}

// SplitFeatures gives the rows SplitRows draws, validation copied out and training kept in the
// set's own arrays (a set near the size of memory is not copied whole); one strike cannot split
TEST(PipelineTest, SplitFeaturesSplitsInPlaceAsSplitRowsDraws) {
  SonicBoomConfig config;
  config.seed = 3;
  config.train.val_fraction = 0.2;
  learning::FeatureSet all;
  all.channels = 1;
  all.mels = 1;
  all.frames = 3;
  all.gcc_pairs = 1;
  all.gcc_lags = 2;
  all.proprio_rows = 1;
  all.proprio_features = 1;
  std::vector<uint64_t> idx;
  for (int r = 0; r < 50; ++r) {
    idx.push_back(1000 + 7 * r);
    all.z_m.push_back(0.001 * r);
    all.theta_rad.push_back(0.01 * r);
    for (int k = 0; k < 3; ++k) all.mel.push_back(100.0f * r + k);
    for (int k = 0; k < 2; ++k) all.gcc.push_back(-100.0f * r - k);
    all.proprio.push_back(static_cast<float>(r));
  }
  const auto [train_rows, val_rows] = SplitRows(idx, 0.2, 3);
  const learning::FeatureSet want_train = all.SelectRows(train_rows);
  const learning::FeatureSet want_val = all.SelectRows(val_rows);
  const float* mel_data = all.mel.data();
  const FeatureSplit split = SplitFeatures(config, std::move(all), idx, "D.h5");
  EXPECT_EQ(split.train.mel, want_train.mel);
  EXPECT_EQ(split.train.gcc, want_train.gcc);
  EXPECT_EQ(split.train.proprio, want_train.proprio);
  EXPECT_EQ(split.train.z_m, want_train.z_m);
  EXPECT_EQ(split.train.theta_rad, want_train.theta_rad);
  EXPECT_EQ(split.val.mel, want_val.mel);
  EXPECT_EQ(split.val.z_m, want_val.z_m);
  EXPECT_EQ(split.train.mel.data(), mel_data);
  ASSERT_GT(split.val.size(), 0);
  learning::FeatureSet one = want_val.SelectRows({0});
  try {
    SplitFeatures(config, std::move(one), {idx[val_rows[0]]}, "D.h5");
    FAIL() << "one strike split";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("D.h5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("train.val_fraction"), std::string::npos) << e.what();
  }
}

// acoustics.render_span = features renders the vibration only as long after the contact as the
// features read: every audio sample before the span's fade is the whole record's, bit for bit
// (the sensor chain is causal and draws the same noise), the window's features agree, the record
// after the span holds the chain's noise alone, and features reading further are refused
// naming the key.
// shell.grid_spacing_m = 0 is resolved with the config from the band the modes are solved to:
// the default band, or 1.25 x a fixed band; the resolved spacing is what the dataset records
TEST(PipelineTest, AZeroGridSpacingIsDerivedFromTheSolvedBand) {
  ConfigSources sources;
  sources.overrides = {"shell.grid_spacing_m=0", "shell.axial_spacing_m=0"};
  const SonicBoomConfig full = ResolveConfig(sources);
  EXPECT_DOUBLE_EQ(full.shell.grid_spacing_m,
                   acoustics::DerivedGridSpacing(full.tube, full.material, 20000.0));
  EXPECT_EQ(full.shell.AxialSpacing(), full.shell.grid_spacing_m);
  sources.overrides.push_back("acoustics.max_frequency_hz=4000");
  const SonicBoomConfig fixed = ResolveConfig(sources);
  EXPECT_NEAR(fixed.shell.grid_spacing_m, 2.0 * full.shell.grid_spacing_m, 1e-12);  // 5 kHz
  // the resolved config reads back as itself
  ConfigSources again;
  again.embedded_yaml = ConfigToYaml(fixed);
  again.embedded_name = "resolved";
  EXPECT_DOUBLE_EQ(ResolveConfig(again).shell.grid_spacing_m, fixed.shell.grid_spacing_m);
}

TEST(PipelineTest, FeatureSpanKeepsTheWindowAndRefusesWiderFeatures) {
  testing::TempDir dir;
  SonicBoomConfig whole = ShortConfig();
  whole.strike.engine = sim::StrikeEngine::kKinematic;
  whole.features.window_s = 0.02;
  whole.features.audio_representation = dsp::AudioRepresentation::kWaveform;
  whole.features.gating = false;
  whole.features.gcc_max_lag = 96;
  whole.features.onset_frame_s = 0.0007;
  SonicBoomConfig span = whole;
  span.acoustics.render_span = acoustics::RenderSpan::kFeatures;
  GenerateDataset(whole, dir / "whole.h5", {.count = 4});
  GenerateDataset(span, dir / "span.h5", {.count = 4});
  DatasetReader a(dir / "whole.h5"), b(dir / "span.h5");
  const double fs = whole.audio.sample_rate_hz;
  const double after_s = FeatureSpanAfterContact(whole.features);
  for (int64_t i = 0; i < a.size(); ++i) {
    const StrikeSample sa = a.Read(i), sb = b.Read(i);
    const int64_t end = std::llround((sa.label.time_s + after_s) * fs);
    const int64_t same = end - std::llround(acoustics::kSpanFadeS * fs);
    ASSERT_LT(end + 2000, sa.audio.cols());
    EXPECT_TRUE(sa.audio.leftCols(same).cwiseEqual(sb.audio.leftCols(same)).all()) << i;
    // after the span: the noise floor, far below the strike that rings on in the whole record
    const auto rms = [](const Eigen::MatrixXf& x) { return std::sqrt(x.squaredNorm() / x.size()); };
    EXPECT_LT(rms(sb.audio.middleCols(end + 1000, 1000)),
              0.1 * rms(sa.audio.middleCols(end + 1000, 1000)))
        << i;
  }
  const learning::FeatureSet fa = ComputeDatasetFeatures(dir / "whole.h5", whole, 1, false);
  const learning::FeatureSet fb = ComputeDatasetFeatures(dir / "span.h5", span, 1, false);
  ASSERT_EQ(fa.mel.size(), fb.mel.size());
  float peak = 0, diff = 0;
  for (size_t k = 0; k < fa.mel.size(); ++k) {
    peak = std::max(peak, std::abs(fa.mel[k]));
    diff = std::max(diff, std::abs(fa.mel[k] - fb.mel[k]));
  }
  EXPECT_LT(diff, 1e-3f * peak);
  // a wider window reads past what the file holds
  SonicBoomConfig wider = span;
  wider.features.window_s = 0.1;
  const std::string message = testing::ThrownMessage<ConfigError>(
      [&] { ComputeDatasetFeatures(dir / "span.h5", wider, 1, false); });
  EXPECT_NE(message.find("features.window_s = 0.1"), std::string::npos) << message;
  EXPECT_NE(message.find("acoustics.render_span"), std::string::npos) << message;
}

}  // namespace
}  // namespace sonicboom::experiments
