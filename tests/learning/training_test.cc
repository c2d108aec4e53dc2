// Training on tiny synthetic features: overfitting, determinism of resume, the Localizer
// round trip, run-directory errors and modality subsets.

#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "internal/data.h"
#include "internal/loaded_run.h"
#include "internal/network.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr double kRadius = 0.05;

// Tiny features whose labels are a learnable function of every modality: the height picks
// the bright mel band and a proprio feature, the angle sets the per-mic loudness, the GCC
// peak lag and two proprio features.
FeatureSet MakeFeatures(int64_t n, uint64_t seed) {
  FeatureSet f;
  f.channels = 6;
  f.mels = 12;
  f.frames = 40;
  f.gcc_pairs = 3;
  f.gcc_lags = 21;
  f.proprio_rows = 12;
  f.proprio_features = 4;
  f.mel.resize(n * f.channels * f.mels * f.frames);
  f.gcc.resize(n * f.gcc_pairs * f.gcc_lags);
  f.proprio.resize(n * f.proprio_rows * f.proprio_features);
  Rng rng(seed);
  for (int64_t i = 0; i < n; ++i) {
    const double z = rng.Uniform(-0.1, 0.1);
    const double theta = rng.Uniform(-std::numbers::pi, std::numbers::pi);
    f.z_m.push_back(z);
    f.theta_rad.push_back(theta);
    const int64_t band = std::lround((z + 0.1) / 0.2 * double(f.mels - 1));
    for (int64_t c = 0; c < f.channels; ++c) {
      const double gain = 1.5 + std::cos(theta - 2.0 * std::numbers::pi * double(c) / 6.0);
      for (int64_t m = 0; m < f.mels; ++m) {
        for (int64_t t = 0; t < f.frames; ++t) {
          const double bright = (m == band) ? 4.0 * gain : 0.0;
          f.mel[((i * f.channels + c) * f.mels + m) * f.frames + t] =
              static_cast<float>(bright + 0.1 * rng.Uniform());
        }
      }
    }
    for (int64_t p = 0; p < f.gcc_pairs; ++p) {
      const double phase = theta + 2.0 * std::numbers::pi * double(p) / 3.0;
      const int64_t lag = std::lround((std::sin(phase) + 1.0) / 2.0 * double(f.gcc_lags - 1));
      f.gcc[(i * f.gcc_pairs + p) * f.gcc_lags + lag] = 1.0f;
    }
    for (int64_t r = 0; r < f.proprio_rows; ++r) {
      float* row = f.proprio.data() + (i * f.proprio_rows + r) * f.proprio_features;
      row[0] = static_cast<float>(10.0 * z);
      row[1] = static_cast<float>(std::cos(theta));
      row[2] = static_cast<float>(std::sin(theta));
      row[3] = static_cast<float>(0.1 * rng.Uniform());
    }
  }
  return f;
}

ModelConfig TinyModel() {
  ModelConfig config;
  config.audio_encoder = AudioEncoderKind::kCompact;
  config.width = 32;
  config.blocks = 1;
  config.heads = 2;
  config.dropout = 0.0;
  config.crop_frames = 32;
  return config;
}

TrainConfig TinyTraining(int64_t epochs) {
  TrainConfig config;
  config.epochs = epochs;
  config.batch_size = 8;
  config.learning_rate = 3e-3;
  config.lr_step_epochs = 20;
  config.lr_gamma = 0.5;
  config.augment = true;
  config.time_shift_frames = 3;
  config.time_mask_frames = 4;
  config.freq_mask_bands = 1;
  config.threads = 1;
  return config;
}

// A fresh directory under the system temp dir, removed at the end of the test.
class RunDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / ("sonicboom_learning_" + std::string(info->name()) + "_" +
                                         std::to_string(static_cast<long>(::getpid())));
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }
  std::string Dir(const std::string& name) const { return (root_ / name).string(); }

  fs::path root_;
};

std::vector<nlohmann::json> ReadMetricsLines(const std::string& run_dir) {
  std::ifstream in(fs::path(run_dir) / "metrics.jsonl");
  std::vector<nlohmann::json> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(nlohmann::json::parse(line));
  return lines;
}

using TrainingTest = RunDirTest;

// Train refuses `config` on `train` with a ConfigError naming `key` and `reason`, and leaves no
// model in `run_dir`
void ExpectTrainRefuses(const FeatureSet& train, const ModelConfig& model,
                        const TrainConfig& config, const std::string& run_dir,
                        const std::string& key, const std::string& reason) {
  try {
    Train(train, train, model, config, kRadius, 1, run_dir, false, false);
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr(key));
    EXPECT_THAT(e.what(), HasSubstr(reason));
  }
  EXPECT_FALSE(fs::exists(run_dir + "/model.pt"));
}

TEST_F(TrainingTest, OverfitsTinySetAndLocalizerReproducesFinalMetrics) {
  const FeatureSet train = MakeFeatures(32, 1);
  const FeatureSet val = MakeFeatures(8, 2);
  const std::string run = Dir("overfit");
  const Metrics metrics =
      Train(train, val, TinyModel(), TinyTraining(40), kRadius, 7, run, false, false);

  // The training loss falls by a large factor.
  const auto lines = ReadMetricsLines(run);
  ASSERT_EQ(lines.size(), 40u);
  const double first = lines.front()["train_loss"].get<double>();
  const double last = lines.back()["train_loss"].get<double>();
  EXPECT_LT(last, first / 10.0) << "first " << first << " last " << last;
  EXPECT_EQ(lines.back()["epoch"], 40);
  EXPECT_DOUBLE_EQ(lines.back()["lr"].get<double>(), 3e-3 * 0.5);
  EXPECT_EQ(metrics.n, 8);
  EXPECT_TRUE(std::isfinite(metrics.med_cm));
  EXPECT_TRUE(std::isfinite(metrics.angle_err_deg));
  EXPECT_TRUE(std::isfinite(metrics.reference_med_cm));

  // The run directory holds the final files and no partial ones.
  for (const char* name : {"model.pt", "model.json", "checkpoint.pt", "checkpoint.json"}) {
    EXPECT_TRUE(fs::exists(fs::path(run) / name)) << name;
  }
  for (const auto& entry : fs::directory_iterator(run)) {
    EXPECT_NE(entry.path().extension(), ".partial") << entry.path();
  }

  // The loaded model predicts what the trained model predicted in its last validation.
  const Localizer localizer(run);
  EXPECT_EQ(localizer.model_config().width, 32);
  EXPECT_EQ(localizer.model_config().crop_frames, 32);
  EXPECT_DOUBLE_EQ(localizer.surface_radius_m(), kRadius);
  const Metrics again = ComputeMetrics(localizer.Predict(val), val, kRadius);
  EXPECT_EQ(again.n, metrics.n);
  EXPECT_DOUBLE_EQ(again.med_cm, metrics.med_cm);
  EXPECT_DOUBLE_EQ(again.angle_err_deg, metrics.angle_err_deg);
  EXPECT_DOUBLE_EQ(again.height_err_cm, metrics.height_err_cm);
  // A strike alone (localize's batch of one: matrix-vector products) is predicted as within
  // the batch (matrix products), up to float summation order.
  const std::vector<Prediction> batched = localizer.Predict(val);
  for (int64_t i = 0; i < val.size(); ++i) {
    const Prediction alone = localizer.Predict(val.SelectRows({i})).front();
    EXPECT_NEAR(alone.z_m, batched[i].z_m, 1e-6) << "row " << i;
    EXPECT_NEAR(alone.theta_rad, batched[i].theta_rad, 1e-5) << "row " << i;
    EXPECT_NEAR(alone.z_std_m / batched[i].z_std_m, 1.0, 1e-4) << "row " << i;
    EXPECT_NEAR(alone.theta_kappa / batched[i].theta_kappa, 1.0, 1e-4) << "row " << i;
  }
  // What the model reads: every modality and the centre 32 of 40 frames. Features holding only
  // those frames (localize's featurizer) predict exactly what the whole window does.
  const FeatureNeeds needs = localizer.needs();
  EXPECT_TRUE(needs.audio && needs.gcc && needs.proprio);
  EXPECT_EQ(needs.mel_first_frame, 4);
  EXPECT_EQ(needs.mel_frames, 32);
  FeatureSet cropped = val;
  cropped.frames = needs.mel_frames;
  cropped.mel.clear();
  for (int64_t row = 0; row < val.size() * val.channels * val.mels; ++row) {
    const auto first = val.mel.begin() + row * val.frames + needs.mel_first_frame;
    cropped.mel.insert(cropped.mel.end(), first, first + needs.mel_frames);
  }
  const std::vector<Prediction> from_crop = localizer.Predict(cropped);
  for (int64_t i = 0; i < val.size(); ++i) {
    EXPECT_EQ(from_crop[i].z_m, batched[i].z_m) << "row " << i;
    EXPECT_EQ(from_crop[i].theta_rad, batched[i].theta_rad) << "row " << i;
  }
  // any other frame count is a shape error naming the key
  cropped.frames = 33;
  cropped.mel.resize(val.size() * val.channels * val.mels * 33);
  EXPECT_THROW(localizer.Predict(cropped), SchemaError);
  // On its own training data the fit is good.
  const Metrics fit = ComputeMetrics(localizer.Predict(train), train, kRadius);
  EXPECT_LT(fit.height_err_cm, 1.5);
  EXPECT_LT(fit.angle_err_deg, 15.0);
}

TEST_F(TrainingTest, ResumeMatchesStraightRun) {
  const FeatureSet train = MakeFeatures(20, 3);
  const FeatureSet val = MakeFeatures(6, 4);
  TrainConfig config = TinyTraining(4);
  config.lr_step_epochs = 3;  // the schedule changes inside the resumed part
  ModelConfig model = TinyModel();
  model.dropout = 0.1;  // dropout draws must resume too

  const std::string straight = Dir("straight");
  const Metrics m_straight = Train(train, val, model, config, kRadius, 11, straight, false, false);

  const std::string resumed = Dir("resumed");
  TrainConfig first_half = config;
  first_half.epochs = 2;
  Train(train, val, model, first_half, kRadius, 11, resumed, false, false);
  ASSERT_EQ(ReadMetricsLines(resumed).size(), 2u);
  // the finished run's checkpoint keeps Adam's state and the epoch count, not a second copy of
  // the weights: they are its model.pt's, and training further continues from them exactly
  torch::serialize::InputArchive checkpoint, weights;
  checkpoint.load_from(resumed + "/checkpoint.pt");
  EXPECT_FALSE(checkpoint.try_read("model", weights));
  // A line of an epoch whose checkpoint never got written (as after a crash) is dropped.
  std::ofstream(fs::path(resumed) / "metrics.jsonl", std::ios::app)
      << R"({"epoch": 3, "train_loss": 999.0})"
      << "\n";
  const Metrics m_resumed = Train(train, val, model, config, kRadius, 11, resumed, true, false);

  EXPECT_NEAR(m_resumed.med_cm, m_straight.med_cm, 1e-6);
  EXPECT_NEAR(m_resumed.angle_err_deg, m_straight.angle_err_deg, 1e-6);
  const auto a = Localizer(straight).Predict(val);
  const auto b = Localizer(resumed).Predict(val);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a[i].z_m, b[i].z_m, 1e-6);
    EXPECT_NEAR(a[i].theta_rad, b[i].theta_rad, 1e-6);
  }
  const auto lines_a = ReadMetricsLines(straight);
  const auto lines_b = ReadMetricsLines(resumed);
  ASSERT_EQ(lines_b.size(), 4u);
  for (size_t e = 0; e < 4; ++e) {
    EXPECT_EQ(lines_b[e]["epoch"], e + 1);
    EXPECT_NEAR(lines_a[e]["train_loss"].get<double>(), lines_b[e]["train_loss"].get<double>(),
                1e-6);
  }

  // A different seed changes the result (the comparison above can fail).
  const Metrics m_other = Train(train, val, model, config, kRadius, 12, Dir("other"), false, false);
  EXPECT_NE(m_other.med_cm, m_straight.med_cm);
}

TEST_F(TrainingTest, ResumeRejectsADifferentModel) {
  const FeatureSet train = MakeFeatures(8, 5);
  const FeatureSet val = MakeFeatures(4, 6);
  const std::string run = Dir("run");
  Train(train, val, TinyModel(), TinyTraining(1), kRadius, 1, run, false, false);
  ModelConfig wider = TinyModel();
  wider.width = 64;
  EXPECT_THROW(Train(train, val, wider, TinyTraining(2), kRadius, 1, run, true, false),
               SchemaError);
}

TEST_F(TrainingTest, LocalizerReportsMissingAndCorruptFiles) {
  EXPECT_THROW(Localizer(Dir("does_not_exist")), IoError);
  // A directory without model.json.
  fs::create_directories(Dir("empty"));
  try {
    Localizer localizer(Dir("empty"));
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_THAT(e.what(), HasSubstr("model.json"));
  }

  const FeatureSet train = MakeFeatures(8, 5);
  const FeatureSet val = MakeFeatures(4, 6);
  const std::string run = Dir("run");
  Train(train, val, TinyModel(), TinyTraining(1), kRadius, 1, run, false, false);

  // Features of another shape.
  FeatureSet other = MakeFeatures(kMinFitRecords, 9);
  other.mels = 10;
  other.mel.resize(kMinFitRecords * other.channels * other.mels * other.frames);
  try {
    Localizer(run).Predict(other);
    FAIL() << "expected SchemaError";
  } catch (const SchemaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("mels"));
  }

  // Weights missing.
  fs::rename(fs::path(run) / "model.pt", fs::path(run) / "moved.pt");
  EXPECT_THROW(Localizer{run}, IoError);
  fs::rename(fs::path(run) / "moved.pt", fs::path(run) / "model.pt");
  EXPECT_NO_THROW(Localizer{run});

  // model.json with shapes that disagree with the weights.
  const fs::path json_path = fs::path(run) / "model.json";
  nlohmann::json j;
  std::ifstream(json_path) >> j;
  nlohmann::json changed = j;
  changed["shapes"]["gcc_lags"] = 30;
  std::ofstream(json_path) << changed.dump();
  EXPECT_THROW(Localizer{run}, SchemaError);
  // A file from before model.arrival_picks reads as none; a misspelt value is an error.
  changed = j;
  changed["model"].erase("arrival_picks");
  std::ofstream(json_path) << changed.dump();
  EXPECT_EQ(Localizer{run}.model_config().arrival_picks, ArrivalPicks::kNone);
  changed["model"]["arrival_picks"] = "tokens";
  std::ofstream(json_path) << changed.dump();
  EXPECT_THROW(Localizer{run}, SchemaError);
  // An unknown model config key.
  changed = j;
  changed["model"]["colour"] = "red";
  std::ofstream(json_path) << changed.dump();
  EXPECT_THROW(Localizer{run}, SchemaError);
  // Not JSON at all.
  std::ofstream(json_path) << "{ this is not json";
  try {
    Localizer localizer(run);
    FAIL() << "expected SchemaError";
  } catch (const SchemaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("model.json"));
  }
}

TEST_F(TrainingTest, CropLongerThanFeaturesIsAConfigError) {
  const FeatureSet train = MakeFeatures(4, 5);
  ModelConfig model = TinyModel();
  model.crop_frames = 41;
  try {
    Train(train, train, model, TinyTraining(1), kRadius, 1, Dir("run"), false, false);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("model.crop_frames"));
  }
}

TEST_F(TrainingTest, FrequencyMaskAsWideAsTheFeatureRowsIsAConfigError) {
  // a waveform has one row: a one-band mask would blank the whole input
  FeatureSet train = MakeFeatures(4, 5);
  train.mels = 1;
  train.mel.resize(train.size() * train.channels * train.frames);
  ModelConfig model = TinyModel();
  model.audio_encoder = AudioEncoderKind::kConv1d;
  try {
    Train(train, train, model, TinyTraining(1), kRadius, 1, Dir("run"), false, false);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("train.freq_mask_bands"));
    EXPECT_THAT(e.what(), HasSubstr("waveform"));
  }
  EXPECT_FALSE(fs::exists(Dir("run") + "/model.pt"));
}

TEST(AssembleBatchTest, ProprioceptionShiftsByTheAudioShiftsTime) {
  FeatureSet f = MakeFeatures(1, 9);
  internal::ModalitySet use;
  use.audio = true;
  use.proprio = true;
  internal::Augmentation a;
  a.shift_frames = 3;
  const std::vector<internal::Augmentation> augment{a};
  const std::vector<float> fill(f.channels, 0.0f);
  // proprio row r of the batch is row r + shift of the record (zero past the end)
  auto shifted_rows = [&](int64_t hop) {
    f.frame_hop_samples = hop;
    const internal::Batch b = internal::AssembleBatch(f, {0}, use, 32, &augment, fill);
    const torch::Tensor record =
        torch::from_blob(f.proprio.data(), {f.proprio_rows, f.proprio_features}, torch::kFloat32);
    for (int64_t shift = 0; shift < f.proprio_rows; ++shift) {
      if (torch::equal(b.proprio[0].slice(0, 0, f.proprio_rows - shift),
                       record.slice(0, shift, f.proprio_rows))) {
        return shift;
      }
    }
    return int64_t{-1};
  };
  // 3 frames of 8 samples (0.54 ms) is no 10 ms row; of 128 samples (8.7 ms) one row; 3
  // waveform samples nothing; 3 frames of 441 samples (30 ms) three rows
  EXPECT_EQ(shifted_rows(8), 0);
  EXPECT_EQ(shifted_rows(128), 1);
  EXPECT_EQ(shifted_rows(1), 0);
  EXPECT_EQ(shifted_rows(441), 3);
}

TEST(AugmentationTest, PolarityFlipInvertsHalfTheRecordsAndChangesNothingElse) {
  TrainConfig off, on;
  on.polarity_flip = true;
  int flipped = 0;
  for (int64_t r = 0; r < 400; ++r) {
    const internal::Augmentation a = internal::DrawAugmentation(off, 32, 50, 7, 3, r);
    const internal::Augmentation b = internal::DrawAugmentation(on, 32, 50, 7, 3, r);
    EXPECT_EQ(a.sign, 1.0f);
    // the other draws are the ones made without the flip
    EXPECT_EQ(a.shift_frames, b.shift_frames);
    EXPECT_EQ(a.time_mask_start, b.time_mask_start);
    EXPECT_EQ(a.freq_mask_width, b.freq_mask_width);
    flipped += b.sign < 0 ? 1 : 0;
  }
  EXPECT_GT(flipped, 160);  // binomial(400, 1/2): 200 +- 10
  EXPECT_LT(flipped, 240);
  // a flipped record's audio is the record's negated, its masks and fills untouched
  FeatureSet f = MakeFeatures(1, 3);
  internal::ModalitySet use;
  use.audio = true;
  const std::vector<float> fill(f.channels, 0.25f);
  internal::Augmentation plain, inverted;
  plain.time_mask_width = inverted.time_mask_width = 4;
  inverted.sign = -1.0f;
  const std::vector<internal::Augmentation> p{plain}, n{inverted};
  const torch::Tensor a = internal::AssembleBatch(f, {0}, use, 32, &p, fill).mel;
  const torch::Tensor b = internal::AssembleBatch(f, {0}, use, 32, &n, fill).mel;
  EXPECT_TRUE(torch::equal(a.select(3, 0), b.select(3, 0)));  // masked frame: the fill
  EXPECT_TRUE(torch::equal(a.slice(3, 4, 32), -b.slice(3, 4, 32)));
}

// train.time_stretch: off changes no draw; on, factors stay in [1 / (1 + r), 1 + r] and reach
// both sides; a stretched waveform moves a pulse d samples from the crop's centre to d * s (so
// inter-channel delays scale alike) and keeps the centre where it was.
TEST(AugmentationTest, TimeStretchScalesDelaysAboutTheCentre) {
  TrainConfig off, on;
  on.time_stretch = 0.2;
  double lo = 2.0, hi = 0.0;
  for (int64_t r = 0; r < 400; ++r) {
    const internal::Augmentation a = internal::DrawAugmentation(off, 64, 1, 7, 3, r);
    const internal::Augmentation b = internal::DrawAugmentation(on, 64, 1, 7, 3, r);
    EXPECT_EQ(a.stretch, 1.0);
    EXPECT_EQ(a.shift_frames, b.shift_frames);
    EXPECT_EQ(a.time_mask_start, b.time_mask_start);
    lo = std::min(lo, b.stretch);
    hi = std::max(hi, b.stretch);
  }
  EXPECT_GE(lo, 1.0 / 1.2 - 1e-12);
  EXPECT_LE(hi, 1.2 + 1e-12);
  EXPECT_LT(lo, 0.9);
  EXPECT_GT(hi, 1.1);
  // a waveform record (one row per channel): a unit pulse 20 samples after the centre on
  // channel 0, 10 before it on channel 1
  FeatureSet f = MakeFeatures(1, 3);
  f.mels = 1;
  f.frames = 201;  // the crop's centre is sample 100
  f.frame_hop_samples = 1;
  f.mel.assign(f.channels * f.frames, 0.0f);
  f.mel[0 * f.frames + 120] = 1.0f;
  f.mel[1 * f.frames + 90] = 1.0f;
  internal::ModalitySet use;
  use.audio = true;
  const std::vector<float> fill(f.channels, 0.0f);
  internal::Augmentation slow;
  slow.stretch = 1.25;
  const std::vector<internal::Augmentation> augment{slow};
  const torch::Tensor x = internal::AssembleBatch(f, {0}, use, 201, &augment, fill).mel;
  // the pulse's centroid in the output, samples
  const auto centroid = [&](int64_t c) {
    double sum = 0.0, weight = 0.0;
    for (int64_t t = 0; t < 201; ++t) {
      const double v = x[0][c][0][t].item<float>();
      sum += v * t;
      weight += v;
    }
    return sum / weight;
  };
  EXPECT_NEAR(centroid(0), 100 + 20 * 1.25, 1e-4);
  EXPECT_NEAR(centroid(1), 100 - 10 * 1.25, 1e-4);
  // the delay between them: 30 samples became 37.5
  EXPECT_NEAR(centroid(0) - centroid(1), 37.5, 1e-4);
}

// train.rotate_rings: a third of the records each turn by 0, 120 or 240 degrees; a turned
// record's channel p of each ring reads disc p - 1 of that ring and its label's theta grows by
// 120 degrees (what a strike 120 degrees on would give on a tube with the discs' symmetry);
// off changes no other draw.
TEST(AugmentationTest, RotateRingsMovesEveryRingOneDiscOnWithTheLabel) {
  TrainConfig off, on;
  on.rotate_rings = true;
  int64_t count[3] = {0, 0, 0};
  for (int64_t r = 0; r < 600; ++r) {
    const internal::Augmentation a = internal::DrawAugmentation(off, 32, 12, 7, 3, r);
    const internal::Augmentation b = internal::DrawAugmentation(on, 32, 12, 7, 3, r);
    EXPECT_EQ(a.rotation, 0);
    EXPECT_EQ(a.shift_frames, b.shift_frames);
    ASSERT_GE(b.rotation, 0);
    ASSERT_LT(b.rotation, 3);
    ++count[b.rotation];
  }
  for (int64_t k : count) EXPECT_NEAR(static_cast<double>(k), 200.0, 45.0);
  FeatureSet f = MakeFeatures(1, 3);
  internal::ModalitySet use;
  use.audio = true;
  const std::vector<float> fill(f.channels, 0.0f);
  internal::Augmentation turned;
  turned.rotation = 1;
  const std::vector<internal::Augmentation> one{turned};
  const torch::Tensor x = internal::AssembleBatch(f, {0}, use, f.frames, &one, fill).mel;
  const torch::Tensor plain = internal::AssembleBatch(f, {0}, use, f.frames, nullptr, fill).mel;
  for (int64_t c = 0; c < 6; ++c) {
    const int64_t read = c / 3 * 3 + (c % 3 + 2) % 3;  // disc p - 1 of the same ring
    EXPECT_TRUE(torch::equal(x[0][c], plain[0][read])) << c;
  }
  const torch::Tensor t = internal::AssembleTargets(f, {0}, &one);
  const double theta = std::atan2(t[0][2].item<float>(), t[0][1].item<float>());
  EXPECT_NEAR(
      std::remainder(theta - f.theta_rad[0] - 2.0 * std::numbers::pi / 3.0, 2.0 * std::numbers::pi),
      0.0, 1e-5);
  EXPECT_NEAR(t[0][0].item<float>(), f.z_m[0] * 100.0, 1e-4);
}

// train.mirror_rings: half the records mirrored about theta 0 after their turn; a record turned
// by one disc and mirrored has channel p of each ring read disc -p - 1 of that ring, and its
// label's theta is -(theta + 120 degrees); off changes no other draw (the turn included).
TEST(AugmentationTest, MirrorRingsSwapsTheDiscsBesideDiscZeroAndNegatesTheta) {
  TrainConfig turned, mirrored;
  turned.rotate_rings = mirrored.rotate_rings = true;
  mirrored.mirror_rings = true;
  int64_t count = 0;
  for (int64_t r = 0; r < 400; ++r) {
    const internal::Augmentation a = internal::DrawAugmentation(turned, 32, 12, 7, 3, r);
    const internal::Augmentation b = internal::DrawAugmentation(mirrored, 32, 12, 7, 3, r);
    EXPECT_FALSE(a.mirror);
    EXPECT_EQ(a.rotation, b.rotation);
    EXPECT_EQ(a.time_mask_start, b.time_mask_start);
    count += b.mirror ? 1 : 0;
  }
  EXPECT_NEAR(static_cast<double>(count), 200.0, 40.0);
  FeatureSet f = MakeFeatures(1, 3);
  internal::ModalitySet use;
  use.audio = true;
  const std::vector<float> fill(f.channels, 0.0f);
  const std::vector<internal::Augmentation> one{{.rotation = 1, .mirror = true}};
  const torch::Tensor x = internal::AssembleBatch(f, {0}, use, f.frames, &one, fill).mel;
  const torch::Tensor plain = internal::AssembleBatch(f, {0}, use, f.frames, nullptr, fill).mel;
  for (int64_t c = 0; c < 6; ++c) {
    const int64_t read = c / 3 * 3 + (6 - c % 3 - 1) % 3;  // disc -p - 1 of the same ring
    EXPECT_TRUE(torch::equal(x[0][c], plain[0][read])) << c;
  }
  const torch::Tensor t = internal::AssembleTargets(f, {0}, &one);
  const double theta = std::atan2(t[0][2].item<float>(), t[0][1].item<float>());
  EXPECT_NEAR(
      std::remainder(theta + f.theta_rad[0] + 2.0 * std::numbers::pi / 3.0, 2.0 * std::numbers::pi),
      0.0, 1e-5);
  // an answer seen through the symmetry maps back to the strike's own theta
  EXPECT_NEAR(std::remainder(internal::UnturnedTheta(theta, one[0]) - f.theta_rad[0],
                             2.0 * std::numbers::pi),
              0.0, 1e-5);
}

// model.arrival_picks: a step of constant amplitude at sample t0 smoothed over 31 samples
// rises linearly from t0 - 15 to t0 + 15, so the energy reaches fraction f of its peak at
// t0 - 16 + 31 f, whatever the channel's amplitude (the last fraction, 1, is the peak, which a
// plateau leaves to rounding).
TEST(ArrivalPicksTest, EachChannelIsPickedOnItsOwnRiseToTheSubSample) {
  const int64_t onsets[6] = {300, 310, 327, 400, 301, 500};
  torch::Tensor x = torch::zeros({2, 6, 1, 882});
  for (int64_t c = 0; c < 6; ++c) {
    x[0][c][0].narrow(0, onsets[c], 882 - onsets[c]).fill_(0.01 * (c + 1));
    x[1][c][0].narrow(0, onsets[c], 882 - onsets[c]).fill_(-3.0 + c);  // c = 3: silent
  }
  const torch::Tensor picks = internal::ArrivalPicksOf(x);  // (2, 6, 4)
  ASSERT_EQ(picks.sizes(), (std::vector<int64_t>{2, 6, 4}));
  for (int64_t c = 0; c < 6; ++c) {
    for (int64_t k = 0; k < 3; ++k) {
      const double expected = onsets[c] - 16.0 + 31.0 * internal::kArrivalFractions[k];
      EXPECT_NEAR(picks[0][c][k].item<float>(), expected, 2e-3) << c << " " << k;
      if (c != 3) {
        EXPECT_NEAR(picks[1][c][k].item<float>(), expected, 2e-3) << c << " " << k;
      }
    }
  }
  // a silent channel picks its first sample rather than anything non-finite
  EXPECT_TRUE(torch::isfinite(picks).all().item<bool>());
}

// The arrival token reads times relative to the channels' mean: a whole record later by 37
// samples and each channel at its own gain is the same token; one channel later is not.
TEST(ArrivalPicksTest, TheTokenIgnoresTheRecordsTimeAndGainButNotOneChannelsDelay) {
  torch::manual_seed(5);
  ModelConfig config;
  config.width = 16;
  config.heads = 2;
  internal::NetworkShapes shapes;
  shapes.mels = 1;
  internal::ArrivalEncoder encoder(config, shapes);
  encoder->eval();
  // a decaying 3 kHz burst per channel, onsets 20 samples apart
  auto burst = [](int64_t shift, int64_t late_channel) {
    torch::Tensor x = torch::zeros({1, 6, 1, 882});
    for (int64_t c = 0; c < 6; ++c) {
      const int64_t t0 = 200 + 20 * c + shift + (c == late_channel ? 9 : 0);
      const torch::Tensor t = torch::arange(0, 882 - t0, torch::kFloat) / 44100.0;
      x[0][c][0].narrow(0, t0, 882 - t0).copy_(torch::sin(2 * 3.14159265 * 3000.0 * t) *
                                               torch::exp(-t / 0.004) * (0.5 + c));
    }
    return x;
  };
  const torch::Tensor base = encoder->forward(burst(0, -1));
  const torch::Tensor gains = torch::tensor({1.0f, 0.1f, 7.0f, 2.0f, 0.3f, 1.5f}).view({1, 6, 1, 1});
  const torch::Tensor moved = encoder->forward(burst(37, -1) * gains);
  EXPECT_LT((base - moved).abs().max().item<float>(), 1e-4);
  const torch::Tensor late = encoder->forward(burst(0, 4));
  EXPECT_GT((base - late).abs().max().item<float>(), 1e-2);
}

// Unlabelled adaptation: the per-mic input statistics become the target's own, the labels are
// not read (a target without them adapts to the same weights), the source stays as it was, and
// out_dir in use, an empty target or features of other shapes are refused before anything is
// written.
TEST_F(TrainingTest, AdaptRefitsStatisticsOnTheTargetWithoutReadingItsLabels) {
  const std::string run = Dir("run");
  Train(MakeFeatures(8, 5), MakeFeatures(4, 6), TinyModel(), TinyTraining(1), kRadius, 1, run,
        false, false);
  FeatureSet target = MakeFeatures(kMinFitRecords, 11);
  for (int64_t i = 0; i < target.size(); ++i) {  // channel 0 louder and offset on the target
    float* c0 = target.mel.data() + i * target.channels * target.mels * target.frames;
    for (int64_t k = 0; k < target.mels * target.frames; ++k) c0[k] = 3.0f * c0[k] + 2.0f;
  }
  const AdaptReport report = AdaptToUnlabelled(run, target, Dir("adapted"), AdaptOptions{});
  EXPECT_EQ(report.members, 1);
  EXPECT_EQ(report.records, kMinFitRecords);
  EXPECT_EQ(report.batch_norm_layers, 4 + 4);  // compact CNN and proprioception encoder
  std::vector<int64_t> all(kMinFitRecords);
  std::iota(all.begin(), all.end(), 0);
  const std::vector<float> mean = internal::ComputeMelStats(target, all).mean;
  internal::LoadedRun adapted = internal::LoadRun(Dir("adapted"));
  EXPECT_EQ(adapted.network->MelMean(), mean);
  EXPECT_NE(internal::LoadRun(run).network->MelMean(), mean);
  nlohmann::json j;
  std::ifstream(fs::path(Dir("adapted")) / "model.json") >> j;
  EXPECT_EQ(j["adapted"]["labels"], "not read");
  EXPECT_EQ(j["adapted"]["records"], kMinFitRecords);
  // the same strikes without labels: the same statistics, buffer for buffer
  FeatureSet unlabelled = target;
  std::fill(unlabelled.z_m.begin(), unlabelled.z_m.end(), std::nan(""));
  std::fill(unlabelled.theta_rad.begin(), unlabelled.theta_rad.end(), std::nan(""));
  AdaptToUnlabelled(run, unlabelled, Dir("unlabelled"), AdaptOptions{});
  internal::LoadedRun blind = internal::LoadRun(Dir("unlabelled"));
  const auto a = adapted.network->named_buffers(), b = blind.network->named_buffers();
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_TRUE(torch::equal(a[k].value(), b[k].value())) << a[k].key();
  }
  // refusals, and nothing written for them
  auto config_error = [&](const std::string& out, const FeatureSet& f) -> std::string {
    try {
      AdaptToUnlabelled(run, f, out, AdaptOptions{});
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "no ConfigError";
  };
  EXPECT_THAT(config_error(Dir("adapted"), target), HasSubstr("not empty"));
  EXPECT_THAT(config_error(Dir("empty_target"), FeatureSet{}), HasSubstr("holds 0 strike(s)"));
  // statistics of fewer strikes than any fit rests on are refused
  EXPECT_THAT(config_error(Dir("few"), MakeFeatures(kMinFitRecords - 1, 12)),
              HasSubstr("holds 29 strike(s); re-estimating the input and BatchNorm statistics "
                        "needs at least 30"));
  FeatureSet other = MakeFeatures(kMinFitRecords, 9);
  other.mels = 10;
  other.mel.resize(kMinFitRecords * other.channels * other.mels * other.frames);
  try {
    AdaptToUnlabelled(run, other, Dir("other"), AdaptOptions{});
    ADD_FAILURE() << "expected SchemaError";
  } catch (const SchemaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("mels"));
  }
  EXPECT_FALSE(fs::exists(Dir("other")));
  EXPECT_FALSE(fs::exists(Dir("empty_target")));
  EXPECT_FALSE(fs::exists(Dir("few")));
}

namespace {

// `f` with channel c of every strike holding what channel read(c) held (a ring turn or mirror)
FeatureSet ReadingChannels(const FeatureSet& f, const std::function<int64_t(int64_t)>& read) {
  FeatureSet out = f;
  const int64_t plane = f.mels * f.frames;
  for (int64_t i = 0; i < f.size(); ++i) {
    for (int64_t c = 0; c < f.channels; ++c) {
      std::copy_n(f.mel.data() + (i * f.channels + read(c)) * plane, plane,
                  out.mel.data() + (i * f.channels + c) * plane);
    }
  }
  return out;
}

// The largest gap between a localizer's answers to `f` and to `g`: heights in cm, and g's theta
// against expected(f's theta) in rad.
double LargestMiss(const Localizer& localizer, const FeatureSet& f, const FeatureSet& g,
                   const std::function<double(double)>& expected) {
  const std::vector<Prediction> a = localizer.Predict(f), b = localizer.Predict(g);
  double miss = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    miss = std::max(miss, std::abs(a[i].z_m - b[i].z_m) * 100.0);
    miss = std::max(miss, std::abs(std::remainder(b[i].theta_rad - expected(a[i].theta_rad),
                                                  2.0 * std::numbers::pi)));
  }
  return miss;
}

}  // namespace

// model.turn_average: a strike with every ring turned one disc on (channel p reads disc p - 1)
// is answered 120 degrees on at the same height, for any weights (the three turns of one are the
// three turns of the other); the network alone is not so. A model reading GCC-PHAT refuses.
TEST_F(TrainingTest, TurnAveragingAnswersATurnedStrikeTurned) {
  ModelConfig model = TinyModel();
  model.modalities = {"audio"};
  model.turn_average = true;
  const std::string run = Dir("run");
  Train(MakeFeatures(8, 5), MakeFeatures(4, 6), model, TinyTraining(1), kRadius, 1, run, false,
        false);
  const FeatureSet f = MakeFeatures(5, 21);
  const FeatureSet turned =
      ReadingChannels(f, [](int64_t c) { return c / 3 * 3 + (c % 3 + 2) % 3; });
  auto largest_miss = [&](const Localizer& localizer) {
    return LargestMiss(localizer, f, turned,
                       [](double theta) { return theta + 2.0 * std::numbers::pi / 3.0; });
  };
  EXPECT_LT(largest_miss(Localizer(run)), 1e-4);
  // the same weights answering each strike once
  nlohmann::json j;
  std::ifstream(fs::path(run) / "model.json") >> j;
  j["model"]["turn_average"] = false;
  std::ofstream(fs::path(run) / "model.json") << j.dump();
  EXPECT_GT(largest_miss(Localizer(run)), 1e-2);
  EXPECT_LT(largest_miss(Localizer(run, {.turn_average = true})), 1e-4);
  // GCC-PHAT does not turn with the audio
  const std::string gcc_run = Dir("gcc_run");
  Train(MakeFeatures(8, 5), MakeFeatures(4, 6), TinyModel(), TinyTraining(1), kRadius, 1,
        gcc_run, false, false);
  try {
    Localizer(gcc_run, {.turn_average = true}).Predict(f);
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("model.modalities = [audio]"));
  }
}

// model.mirror_average: a strike with discs 1 and 2 of every ring swapped is answered at -theta
// and the same height, for any weights (its six images are the strike's six images); turn
// averaging alone is not so. Asked without turn averaging, the localizer refuses.
TEST_F(TrainingTest, MirrorAveragingAnswersAMirroredStrikeMirrored) {
  ModelConfig model = TinyModel();
  model.modalities = {"audio"};
  model.turn_average = true;
  const std::string run = Dir("run");
  Train(MakeFeatures(8, 5), MakeFeatures(4, 6), model, TinyTraining(1), kRadius, 1, run, false,
        false);
  const FeatureSet f = MakeFeatures(5, 21);
  const FeatureSet mirrored =
      ReadingChannels(f, [](int64_t c) { return c / 3 * 3 + (3 - c % 3) % 3; });
  auto largest_miss = [&](const Localizer& localizer) {
    return LargestMiss(localizer, f, mirrored, [](double theta) { return -theta; });
  };
  EXPECT_GT(largest_miss(Localizer(run)), 1e-2);
  EXPECT_LT(largest_miss(Localizer(run, {.mirror_average = true})), 1e-4);
  // the run's own key does it too
  nlohmann::json j;
  std::ifstream(fs::path(run) / "model.json") >> j;
  j["model"]["mirror_average"] = true;
  std::ofstream(fs::path(run) / "model.json") << j.dump();
  EXPECT_LT(largest_miss(Localizer(run)), 1e-4);
  // mirror images are taken of each turn
  j["model"]["turn_average"] = false;
  j["model"]["mirror_average"] = false;
  std::ofstream(fs::path(run) / "model.json") << j.dump();
  try {
    Localizer(run, {.mirror_average = true}).Predict(f);
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("turn averaging"));
  }
}

TEST_F(TrainingTest, ArrivalPicksOfALogMelImageIsAConfigError) {
  ModelConfig model = TinyModel();
  model.arrival_picks = ArrivalPicks::kToken;
  ExpectTrainRefuses(MakeFeatures(4, 5), model, TinyTraining(1), Dir("run"),
                     "model.arrival_picks", "waveform");
}

TEST_F(TrainingTest, RotateRingsWithGccIsAConfigError) {
  TrainConfig config = TinyTraining(1);
  config.rotate_rings = true;
  ExpectTrainRefuses(MakeFeatures(4, 5), TinyModel(), config, Dir("run"), "train.rotate_rings",
                     "modalities");
}

TEST_F(TrainingTest, PolarityFlipOfALogMelImageIsAConfigError) {
  TrainConfig config = TinyTraining(1);
  config.polarity_flip = true;
  // log-mel, 128-sample hop
  ExpectTrainRefuses(MakeFeatures(4, 5), TinyModel(), config, Dir("run"), "train.polarity_flip",
                     "waveform");
}

TEST_F(TrainingTest, TimeStretchOfALogMelImageIsAConfigError) {
  TrainConfig config = TinyTraining(1);
  config.time_stretch = 0.1;
  // log-mel, 128-sample hop
  ExpectTrainRefuses(MakeFeatures(4, 5), TinyModel(), config, Dir("run"), "train.time_stretch",
                     "waveform");
}

TEST(Conv1dEncoderTest, OutputDoesNotDependOnTheRecordsLevel) {
  ModelConfig model = TinyModel();
  model.audio_encoder = AudioEncoderKind::kConv1d;
  internal::NetworkShapes shapes;
  shapes.channels = 6;
  shapes.mels = 1;
  shapes.crop_frames = 200;
  torch::manual_seed(3);
  internal::AudioEncoder encoder(model, shapes);
  encoder->eval();
  torch::NoGradGuard no_grad;
  // (B, C, 1, T) waveforms; record 1 is record 0 at 40 dB more, record 2 at another shape
  const torch::Tensor x = torch::randn({1, 6, 1, 200});
  const torch::Tensor batch = torch::cat({x, 100.0 * x, torch::randn({1, 6, 1, 200})});
  const torch::Tensor out = encoder->forward(batch);
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{3, model.width}));
  EXPECT_TRUE(torch::allclose(out[0], out[1], 1e-4, 1e-5));
  // but it does depend on the record: the relative levels and timing of the channels
  EXPECT_GT((out[0] - out[2]).abs().max().item<float>(), 1e-3f);
}

TEST_F(TrainingTest, ModalitySubsetsTrainAndBuildOnlyTheirEncoders) {
  FeatureSet train = MakeFeatures(8, 5);
  FeatureSet val = MakeFeatures(4, 6);
  // Audio only: GCC and proprio arrays may be absent.
  {
    FeatureSet t = train, v = val;
    t.gcc.clear();
    t.proprio.clear();
    v.gcc.clear();
    v.proprio.clear();
    ModelConfig model = TinyModel();
    model.modalities = {"audio"};
    const Metrics m = Train(t, v, model, TinyTraining(1), kRadius, 1, Dir("audio"), false, false);
    EXPECT_TRUE(std::isfinite(m.med_cm));
    const auto counts = Localizer(Dir("audio")).ParameterCounts();
    EXPECT_EQ(counts.size(), 2u);
    EXPECT_TRUE(counts.count("audio_encoder"));
    EXPECT_EQ(counts, CountParameters(model, t));
  }
  // Proprio only.
  {
    FeatureSet t = train, v = val;
    t.mel.clear();
    t.gcc.clear();
    v.mel.clear();
    v.gcc.clear();
    ModelConfig model = TinyModel();
    model.modalities = {"proprio"};
    const Metrics m = Train(t, v, model, TinyTraining(1), kRadius, 1, Dir("proprio"), false, false);
    EXPECT_TRUE(std::isfinite(m.med_cm));
    const auto counts = Localizer(Dir("proprio")).ParameterCounts();
    EXPECT_EQ(counts.size(), 2u);
    EXPECT_TRUE(counts.count("proprio_encoder"));
    EXPECT_EQ(counts, CountParameters(model, t));
  }
  // Missing arrays of a selected modality are a SchemaError naming the array.
  {
    FeatureSet t = train;
    t.gcc.clear();
    try {
      Train(t, val, TinyModel(), TinyTraining(1), kRadius, 1, Dir("bad"), false, false);
      FAIL() << "expected SchemaError";
    } catch (const SchemaError& e) {
      EXPECT_THAT(e.what(), HasSubstr("gcc"));
    }
  }
}

nlohmann::json ReadModelJson(const std::string& run_dir) {
  nlohmann::json j;
  std::ifstream(fs::path(run_dir) / "model.json") >> j;
  return j;
}

void WriteModelJson(const std::string& run_dir, const nlohmann::json& j) {
  std::ofstream(fs::path(run_dir) / "model.json") << j.dump(2);
}

TEST_F(TrainingTest, UncertaintyIsFiniteAndCalibratedOnValidation) {
  const FeatureSet train = MakeFeatures(32, 21);
  const FeatureSet val = MakeFeatures(kMinFitRecords, 22);  // enough strikes to fit the scales
  const std::string run = Dir("uncertainty");
  const Metrics m = Train(train, val, TinyModel(), TinyTraining(12), kRadius, 5, run, false, false);

  // Every prediction carries a finite, positive distribution.
  const Localizer localizer(run);
  ASSERT_TRUE(localizer.has_uncertainty());
  const std::vector<Prediction> predictions = localizer.Predict(val);
  for (const Prediction& p : predictions) {
    EXPECT_TRUE(std::isfinite(p.z_std_m) && p.z_std_m > 0.0) << p.z_std_m;
    EXPECT_TRUE(std::isfinite(p.theta_kappa) && p.theta_kappa > 0.0) << p.theta_kappa;
  }
  // Calibrated on this split, the 90 % intervals hold most of it (uncalibrated, the tiny model's
  // intervals hold anything from none to all).
  std::cout << "validation coverage z " << m.z_coverage_50 << " / " << m.z_coverage_90 << ", theta "
            << m.theta_coverage_50 << " / " << m.theta_coverage_90 << ", NLL " << m.nll << "\n";
  EXPECT_GE(m.z_coverage_90, 0.7);
  EXPECT_LE(m.z_coverage_90, 1.0);
  EXPECT_GE(m.theta_coverage_90, 0.7);
  EXPECT_LE(m.theta_coverage_90, 1.0);
  EXPECT_GE(m.z_coverage_50, 0.2);
  EXPECT_LE(m.z_coverage_50, 0.8);
  // model.json holds the scales the Localizer applies, and the calibration did not make the
  // validation NLL worse (it minimizes it).
  const nlohmann::json j = ReadModelJson(run);
  ASSERT_TRUE(j.contains("uncertainty")) << j.dump(2);
  EXPECT_EQ(j["uncertainty"]["method"], "scales minimizing the mean NLL of the validation split");
  const double z_scale = j["uncertainty"]["z_std_scale"].get<double>();
  const double kappa_scale = j["uncertainty"]["kappa_scale"].get<double>();
  std::cout << "scales: sigma_z x " << z_scale << ", kappa x " << kappa_scale << "; uncalibrated "
            << j["uncertainty"]["uncalibrated_val_metrics"].dump() << "\n";
  EXPECT_EQ(localizer.calibration().z_std_scale, z_scale);
  EXPECT_EQ(localizer.calibration().kappa_scale, kappa_scale);
  EXPECT_LE(m.nll, j["uncertainty"]["uncalibrated_val_metrics"]["nll"].get<double>() + 1e-9);
  EXPECT_EQ(j["val_metrics"]["z_coverage_90"].get<double>(), m.z_coverage_90);
  // The loaded model reproduces the returned figures.
  const Metrics again = ComputeMetrics(predictions, val, kRadius);
  EXPECT_EQ(again.z_coverage_90, m.z_coverage_90);
  EXPECT_EQ(again.theta_coverage_50, m.theta_coverage_50);
  EXPECT_NEAR(again.nll, m.nll, 1e-9);
  // metrics.jsonl logs the uncertainty loss and the (uncalibrated) validation coverage.
  const auto lines = ReadMetricsLines(run);
  ASSERT_EQ(lines.size(), 12u);
  EXPECT_TRUE(std::isfinite(lines.back()["train_nll"].get<double>()));
  EXPECT_TRUE(lines.back()["val"]["theta_coverage_90"].is_number());
  EXPECT_LT(lines.back()["train_nll"].get<double>(), lines.front()["train_nll"].get<double>());

  // A broken calibration (stds 100 times too small, kappas at the largest scale a file may
  // hold, 1e4) fails the bounds above: the Localizer applies what model.json says.
  nlohmann::json broken = j;
  broken["uncertainty"]["z_std_scale"] = z_scale / 100.0;
  broken["uncertainty"]["kappa_scale"] = UncertaintyCalibration::kMaxScale;
  WriteModelJson(run, broken);
  const Metrics bad = ComputeMetrics(Localizer(run).Predict(val), val, kRadius);
  EXPECT_LT(bad.z_coverage_90, 0.6);
  EXPECT_LT(bad.theta_coverage_90, 0.6);
  EXPECT_GT(bad.nll, m.nll);
}

// Scales are fitted on as many validation strikes as calibrate needs, or not at all: a fresh run
// keeps 1 and 1, a fine-tune its pretrained ones, and model.json says which.
TEST_F(TrainingTest, TooFewValidationStrikesKeepTheScalesAndModelJsonSaysSo) {
  const FeatureSet train = MakeFeatures(16, 41), few = MakeFeatures(kMinFitRecords - 1, 42);
  Train(train, few, TinyModel(), TinyTraining(1), kRadius, 3, Dir("fresh"), false, false);
  nlohmann::json j = ReadModelJson(Dir("fresh"));
  EXPECT_EQ(j["uncertainty"]["z_std_scale"], 1.0);
  EXPECT_EQ(j["uncertainty"]["kappa_scale"], 1.0);
  EXPECT_THAT(j["uncertainty"]["method"].get<std::string>(),
              HasSubstr("not fitted: 29 validation strikes with a predictive distribution, fewer "
                        "than the 30 a fit needs; scales 1 kept"));
  // the scales a calibrate gave it carry over into a fine-tune on as few strikes
  j["uncertainty"]["z_std_scale"] = 2.5;
  j["uncertainty"]["kappa_scale"] = 0.25;
  WriteModelJson(Dir("fresh"), j);
  Train(train, few, TinyModel(), TinyTraining(1), kRadius, 3, Dir("tuned"), false, false,
        FineTune{Dir("fresh"), FineTune::Freeze::kNone, false});
  const nlohmann::json tuned = ReadModelJson(Dir("tuned"));
  EXPECT_EQ(tuned["uncertainty"]["z_std_scale"], 2.5);
  EXPECT_EQ(tuned["uncertainty"]["kappa_scale"], 0.25);
  EXPECT_THAT(tuned["uncertainty"]["method"].get<std::string>(),
              HasSubstr("the pretrained scales of " + Dir("fresh") + "/model.json kept"));
  EXPECT_EQ(Localizer(Dir("tuned")).calibration().z_std_scale, 2.5);
}

TEST_F(TrainingTest, UncertaintyHeadLeavesPointsUnchangedAndOldModelFilesLoad) {
  const FeatureSet train = MakeFeatures(16, 31);
  const FeatureSet val = MakeFeatures(kMinFitRecords, 32);
  ModelConfig model = TinyModel();
  model.dropout = 0.1;  // dropout draws must not depend on the head either
  const TrainConfig with_head = TinyTraining(3);
  TrainConfig point_only = with_head;
  point_only.uncertainty_weight = 0.0;
  const std::string with_run = Dir("with"), point_run = Dir("point");
  Train(train, val, model, with_head, kRadius, 9, with_run, false, false);
  const Metrics point_metrics =
      Train(train, val, model, point_only, kRadius, 9, point_run, false, false);

  // The uncertainty loss never reaches the point estimate: identical to the paper's network.
  const Localizer a(with_run), b(point_run);
  EXPECT_TRUE(a.has_uncertainty());
  EXPECT_FALSE(b.has_uncertainty());
  const std::vector<Prediction> pa = a.Predict(val), pb = b.Predict(val);
  ASSERT_EQ(pa.size(), pb.size());
  for (size_t i = 0; i < pa.size(); ++i) {
    EXPECT_EQ(pa[i].z_m, pb[i].z_m) << i;
    EXPECT_EQ(pa[i].theta_rad, pb[i].theta_rad) << i;
    EXPECT_TRUE(pa[i].has_uncertainty());
    EXPECT_FALSE(pb[i].has_uncertainty());
  }
  const auto lines_a = ReadMetricsLines(with_run), lines_b = ReadMetricsLines(point_run);
  for (size_t e = 0; e < lines_a.size(); ++e) {
    EXPECT_EQ(lines_a[e]["train_loss"], lines_b[e]["train_loss"]) << e;
  }
  // Without the head (as before it existed): no "uncertainty" entry, null coverage.
  EXPECT_TRUE(std::isnan(point_metrics.z_coverage_90));
  const nlohmann::json point_json = ReadModelJson(point_run);
  EXPECT_FALSE(point_json.contains("uncertainty"));
  EXPECT_TRUE(point_json["val_metrics"]["nll"].is_null());
  EXPECT_EQ(b.calibration().z_std_scale, 1.0);
  EXPECT_FALSE(lines_b.back().contains("train_nll"));
  // Its checkpoint resumes only as a run without the head.
  TrainConfig longer = with_head;
  longer.epochs = 4;
  EXPECT_THROW(Train(train, val, model, longer, kRadius, 9, point_run, true, false), SchemaError);

  // A model.json from before calibration existed (no "uncertainty"): scales 1, so the
  // predictions are the calibrated ones divided by the stored scales.
  nlohmann::json j = ReadModelJson(with_run);
  const UncertaintyCalibration scales{j["uncertainty"]["z_std_scale"].get<double>(),
                                      j["uncertainty"]["kappa_scale"].get<double>()};
  EXPECT_NE(scales.z_std_scale, 1.0);
  j.erase("uncertainty");
  WriteModelJson(with_run, j);
  const Localizer old(with_run);
  EXPECT_TRUE(old.has_uncertainty());
  EXPECT_EQ(old.calibration().z_std_scale, 1.0);
  EXPECT_EQ(old.calibration().kappa_scale, 1.0);
  const std::vector<Prediction> raw = old.Predict(val);
  for (size_t i = 0; i < raw.size(); ++i) {
    EXPECT_EQ(raw[i].z_m, pa[i].z_m);
    EXPECT_NEAR(raw[i].z_std_m * scales.z_std_scale, pa[i].z_std_m, 1e-12 * pa[i].z_std_m);
    EXPECT_NEAR(raw[i].theta_kappa * scales.kappa_scale, pa[i].theta_kappa,
                1e-12 * pa[i].theta_kappa);
  }
  // A malformed calibration is refused, naming the key.
  j["uncertainty"] = {{"z_std_scale", -1.0}, {"kappa_scale", 1.0}};
  WriteModelJson(with_run, j);
  try {
    Localizer bad(with_run);
    FAIL() << "expected SchemaError";
  } catch (const SchemaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("uncertainty.z_std_scale"));
  }
}

TEST_F(TrainingTest, ResNetAndConv1dEncodersTrainOneEpoch) {
  const FeatureSet train = MakeFeatures(4, 5);
  const FeatureSet val = MakeFeatures(2, 6);
  for (const AudioEncoderKind encoder :
       {AudioEncoderKind::kResnet18, AudioEncoderKind::kResnet50, AudioEncoderKind::kConv1d}) {
    ModelConfig model = TinyModel();
    model.audio_encoder = encoder;
    model.modalities = {"audio"};
    TrainConfig config = TinyTraining(1);
    config.batch_size = 4;
    config.threads = 0;
    const std::string name(NameOf(encoder));
    const Metrics m = Train(train, val, model, config, kRadius, 1, Dir(name), false, false);
    EXPECT_TRUE(std::isfinite(m.med_cm)) << name;
  }
}

// Every parameter and buffer of a run's model.pt, by name.
std::map<std::string, torch::Tensor> RunWeights(const std::string& run, const FeatureSet& shapes,
                                                const ModelConfig& model) {
  internal::Network network(model, internal::ShapesOf(shapes, model), /*uncertainty_head=*/true);
  torch::serialize::InputArchive archive;
  archive.load_from(run + "/model.pt");
  internal::LoadModuleChecked(*network, archive, run);
  std::map<std::string, torch::Tensor> weights;
  for (const auto& p : network->named_parameters()) weights[p.key()] = p.value().clone();
  for (const auto& b : network->named_buffers()) weights[b.key()] = b.value().clone();
  return weights;
}

// Names of the weights that a fine-tune changed.
std::vector<std::string> Changed(const std::map<std::string, torch::Tensor>& before,
                                 const std::map<std::string, torch::Tensor>& after) {
  std::vector<std::string> changed;
  for (const auto& [name, tensor] : before) {
    if (!torch::equal(tensor, after.at(name))) changed.push_back(name);
  }
  return changed;
}

TEST_F(TrainingTest, FineTuneTrainsOnlyWhatIsNotFrozen) {
  const FeatureSet train = MakeFeatures(32, 41), val = MakeFeatures(16, 42);
  Train(train, val, TinyModel(), TinyTraining(2), kRadius, 3, Dir("pre"), false, false);
  const auto pre = RunWeights(Dir("pre"), train, TinyModel());
  // a target whose mel levels differ, so refitted statistics differ from the pretrained ones
  FeatureSet target = MakeFeatures(24, 43);
  for (float& v : target.mel) v = 2.0f * v + 1.0f;
  const FeatureSet target_val = MakeFeatures(12, 44);

  auto tune = [&](const std::string& name, FineTune::Freeze freeze, bool refit) {
    Train(target, target_val, TinyModel(), TinyTraining(2), kRadius, 5, Dir(name), false, false,
          FineTune{Dir("pre"), freeze, refit});
    return Changed(pre, RunWeights(Dir(name), train, TinyModel()));
  };
  auto starts = [](const std::string& name, const std::string& prefix) {
    return name.rfind(prefix, 0) == 0;
  };
  // encoders frozen: their weights and BatchNorm statistics stay, the rest learns
  const std::vector<std::string> encoders = tune("enc", FineTune::Freeze::kEncoders, false);
  ASSERT_FALSE(encoders.empty());
  for (const std::string& name : encoders) {
    EXPECT_FALSE(starts(name, "audio_encoder") || starts(name, "gcc_encoder") ||
                 starts(name, "proprio_encoder") || name == "mel_mean" || name == "mel_std")
        << name;
  }
  EXPECT_TRUE(std::count_if(encoders.begin(), encoders.end(),
                            [&](const std::string& n) { return starts(n, "head."); }) > 0);
  // only the heads learn
  const std::vector<std::string> heads = tune("head", FineTune::Freeze::kAllButHead, false);
  ASSERT_FALSE(heads.empty());
  for (const std::string& name : heads) {
    EXPECT_TRUE(starts(name, "head.") || starts(name, "uncertainty_head.")) << name;
  }
  // nothing frozen, statistics refitted on the target: every part moves, mel_mean included
  const std::vector<std::string> all = tune("all", FineTune::Freeze::kNone, true);
  for (const char* part : {"audio_encoder", "block0", "mel_mean", "cls_token"}) {
    EXPECT_TRUE(std::count_if(all.begin(), all.end(),
                              [&](const std::string& n) { return starts(n, part); }) > 0)
        << part;
  }
}

TEST_F(TrainingTest, EnsembleTrainsItsMembersAndPredictsTheirMixture) {
  const FeatureSet train = MakeFeatures(16, 5);
  const FeatureSet val = MakeFeatures(kMinFitRecords, 6);
  TrainConfig config = TinyTraining(2);
  config.ensemble_members = 3;
  const std::string run = Dir("ensemble");
  const Metrics m = TrainEnsemble(train, val, TinyModel(), config, kRadius, 7, run, false, false);
  // member 0 is the single run of the same seed; the others differ
  TrainConfig single_config = config;
  single_config.ensemble_members = 1;
  TrainEnsemble(train, val, TinyModel(), single_config, kRadius, 7, Dir("single"), false, false);
  EXPECT_EQ(EnsembleMembers(Dir("single")).size(), 0u);
  const Localizer member0(run + "/member0"), member1(run + "/member1"), member2(run + "/member2"),
      single(Dir("single"));
  const std::vector<Prediction> p0 = member0.Predict(val), p1 = member1.Predict(val),
                                p2 = member2.Predict(val), ps = single.Predict(val);
  EXPECT_EQ(p0[0].z_m, ps[0].z_m);
  EXPECT_NE(p0[0].z_m, p1[0].z_m);
  // the directory is one model: the members' mixture, strike by strike
  const Localizer ensemble(run);
  EXPECT_EQ(ensemble.members(), 3);
  ASSERT_EQ(EnsembleMembers(run).size(), 3u);
  const std::vector<Prediction> pe = ensemble.Predict(val);
  // its own calibration was fitted on the validation set: refitting there changes nothing
  const UncertaintyCalibration refit = FitUncertaintyCalibration(pe, val);
  EXPECT_NEAR(refit.z_std_scale, 1.0, 1e-3);
  EXPECT_NEAR(refit.kappa_scale, 1.0, 1e-3);
  EXPECT_NE(ensemble.calibration().z_std_scale, 1.0);
  for (size_t i = 0; i < pe.size(); ++i) {
    const Prediction expected =
        ApplyCalibration(CombinePredictions({p0[i], p1[i], p2[i]}), ensemble.calibration());
    EXPECT_DOUBLE_EQ(pe[i].z_m, expected.z_m) << i;
    EXPECT_DOUBLE_EQ(pe[i].theta_rad, expected.theta_rad) << i;
    EXPECT_DOUBLE_EQ(pe[i].z_std_m, expected.z_std_m) << i;
  }
  EXPECT_DOUBLE_EQ(m.med_cm, ComputeMetrics(pe, val, kRadius).med_cm);
  // three members hold three times the weights
  for (const auto& [part, n] : ensemble.ParameterCounts()) {
    EXPECT_EQ(n, 3 * single.ParameterCounts().at(part)) << part;
  }
  // a fine-tune keeps the member count: member k from member k, or refused naming the key
  FineTune tune;
  tune.init_from = run;
  TrainEnsemble(train, val, TinyModel(), config, kRadius, 7, Dir("tuned"), false, false, tune);
  EXPECT_EQ(Localizer(Dir("tuned")).members(), 3);
  try {
    TrainEnsemble(train, val, TinyModel(), single_config, kRadius, 7, Dir("bad"), false, false,
                  tune);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("train.ensemble_members"));
  }
  // a damaged ensemble.json names the file
  std::ofstream(run + "/ensemble.json")
      << R"({"members": ["member0"], "uncertainty": {"z_std_scale": -1, "kappa_scale": 1}})";
  EXPECT_THROW(Localizer{run}, SchemaError);
  std::ofstream(run + "/ensemble.json") << R"({"members": ["../elsewhere"]})";
  try {
    Localizer broken(run);
    FAIL() << "expected SchemaError";
  } catch (const SchemaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("ensemble.json"));
  }
}

// FineTune::Calibration::kKeepPretrained (--tune auto's folds and final run): the pretrained
// scales stay although the validation split could fit them, in a run and in an ensemble.
TEST_F(TrainingTest, FineTuneCanKeepThePretrainedCalibration) {
  const FeatureSet train = MakeFeatures(32, 61), val = MakeFeatures(32, 62);
  auto scales = [](const std::string& file) {
    const nlohmann::json u = nlohmann::json::parse(sonicboom::testing::ReadBytes(file))["uncertainty"];
    return std::make_pair(u["z_std_scale"].get<double>(), u["kappa_scale"].get<double>());
  };
  TrainConfig config = TinyTraining(1);
  for (const int64_t members : {1, 2}) {
    config.ensemble_members = members;
    const std::string pre = Dir(fmt::format("pre{}", members));
    const std::string file = members == 1 ? "/model.json" : "/ensemble.json";
    TrainEnsemble(train, val, TinyModel(), config, kRadius, 3, pre, false, false);
    ASSERT_NE(scales(pre + file).first, 1.0);  // fitted on 32 strikes
    FineTune tune;
    tune.init_from = pre;
    tune.calibration = FineTune::Calibration::kKeepPretrained;
    const std::string tuned = Dir(fmt::format("tuned{}", members));
    TrainEnsemble(MakeFeatures(24, 63), MakeFeatures(32, 64), TinyModel(), config, kRadius, 5,
                  tuned, false, false, tune);
    EXPECT_EQ(scales(tuned + file), scales(pre + file)) << members;
    EXPECT_THAT(sonicboom::testing::ReadBytes(tuned + file), HasSubstr("keeps its calibration"));
  }
}

TEST_F(TrainingTest, FineTuneRefusesAMissingOrMismatchedPretrainedRun) {
  const FeatureSet train = MakeFeatures(16, 51), val = MakeFeatures(8, 52);
  EXPECT_THAT(sonicboom::testing::ThrownMessage<IoError>([&] {
                Train(train, val, TinyModel(), TinyTraining(1), kRadius, 1, Dir("a"), false, false,
                      FineTune{Dir("none"), FineTune::Freeze::kNone, false});
              }),
              HasSubstr("none/model.pt: missing"));
  Train(train, val, TinyModel(), TinyTraining(1), kRadius, 1, Dir("pre"), false, false);
  ModelConfig wider = TinyModel();
  wider.width = 48;
  EXPECT_THAT(sonicboom::testing::ThrownMessage<SchemaError>([&] {
                Train(train, val, wider, TinyTraining(1), kRadius, 1, Dir("b"), false, false,
                      FineTune{Dir("pre"), FineTune::Freeze::kNone, false});
              }),
              HasSubstr("pre/model.pt: tensor"));
  // the freeze choices by name, as --freeze takes them
  EXPECT_EQ(EnumNameList<FineTune::Freeze>(), "none, encoders, all-but-head");
  EXPECT_FALSE(EnumFromName<FineTune::Freeze>("all").has_value());
}

TEST_F(TrainingTest, KeepBestSavesTheEpochWithTheLowestValidationLoss) {
  const FeatureSet train = MakeFeatures(24, 61), val = MakeFeatures(12, 62);
  TrainConfig config = TinyTraining(6);
  config.keep_best = true;
  config.learning_rate = 2e-2;  // a rate that makes the validation loss jump about
  Train(train, val, TinyModel(), config, kRadius, 9, Dir("best"), false, false);
  // best.json names the minimum of metrics.jsonl's validation losses
  double lowest = std::numeric_limits<double>::infinity();
  int64_t lowest_epoch = 0;
  for (const nlohmann::json& line : ReadMetricsLines(Dir("best"))) {
    if (line["val_loss"].get<double>() < lowest) {
      lowest = line["val_loss"].get<double>();
      lowest_epoch = line["epoch"].get<int64_t>();
    }
  }
  std::ifstream in(fs::path(Dir("best")) / "best.json");
  const nlohmann::json best = nlohmann::json::parse(in);
  EXPECT_EQ(best["epoch"].get<int64_t>(), lowest_epoch);
  EXPECT_LT(lowest_epoch, 6) << "this check needs a best epoch before the last";
  EXPECT_DOUBLE_EQ(best["val_loss"].get<double>(), lowest);
  // the model is that epoch's network: a run of that many epochs ends there (training is
  // deterministic)
  TrainConfig shorter = config;
  shorter.keep_best = false;
  shorter.epochs = lowest_epoch;
  Train(train, val, TinyModel(), shorter, kRadius, 9, Dir("shorter"), false, false);
  const auto at_best = RunWeights(Dir("shorter"), train, TinyModel());
  EXPECT_TRUE(Changed(at_best, RunWeights(Dir("best"), train, TinyModel())).empty());
  // the finished run keeps no best.pt beside it (it is model.pt), and its checkpoint the last
  // epoch's weights, which a resume continues from
  EXPECT_FALSE(fs::exists(fs::path(Dir("best")) / "best.pt"));
  internal::Network last(TinyModel(), internal::ShapesOf(train, TinyModel()), true);
  torch::serialize::InputArchive checkpoint, weights;
  checkpoint.load_from(Dir("best") + "/checkpoint.pt");
  ASSERT_TRUE(checkpoint.try_read("model", weights));
  internal::LoadModuleChecked(*last, weights, "checkpoint.pt");
  std::map<std::string, torch::Tensor> at_last;
  for (const auto& p : last->named_parameters()) at_last[p.key()] = p.value();
  EXPECT_FALSE(Changed(at_last, RunWeights(Dir("best"), train, TinyModel())).empty());
  // trained one epoch further (hardly moving), the model stays the best epoch's unless the new
  // one is better
  TrainConfig longer = config;
  longer.epochs = 7;
  longer.learning_rate = 1e-9;
  Train(train, val, TinyModel(), longer, kRadius, 9, Dir("best"), true, false);
  std::ifstream again(fs::path(Dir("best")) / "best.json");
  if (nlohmann::json::parse(again)["epoch"].get<int64_t>() == lowest_epoch) {
    EXPECT_TRUE(Changed(at_best, RunWeights(Dir("best"), train, TinyModel())).empty());
  }
}

}  // namespace
}  // namespace sonicboom::learning
