// The baselines: kNN recovery, weighting and circular means, the constant predictor, error paths.
#include "sonicboom/core/constants.h"
#include "sonicboom/learning/baselines.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "sonicboom/core/errors.h"

namespace sonicboom::learning {
namespace {

using sonicboom::kPi;

// A small random feature set (2 channels, 4 mels, 40 frames, 3 GCC pairs of 21 lags) with
// positive power mels and labels spread over the region.
FeatureSet RandomSet(int64_t n, uint32_t seed) {
  FeatureSet f;
  f.channels = 2;
  f.mels = 4;
  f.frames = 40;
  f.gcc_pairs = 3;
  f.gcc_lags = 21;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> power(1e-6f, 1.0f), unit(-1.0f, 1.0f);
  std::uniform_real_distribution<double> z(-0.1, 0.1), theta(-kPi, kPi);
  f.mel.resize(n * f.channels * f.mels * f.frames);
  for (float& v : f.mel) v = power(rng);
  f.gcc.resize(n * f.gcc_pairs * f.gcc_lags);
  for (float& v : f.gcc) v = unit(rng);
  for (int64_t i = 0; i < n; ++i) {
    f.z_m.push_back(z(rng));
    f.theta_rad.push_back(theta(rng));
  }
  return f;
}

KnnConfig SmallConfig(int64_t k) {
  KnnConfig c;
  c.k = k;
  c.crop_frames = 20;
  c.pooled_frames = 5;
  c.threads = 1;
  return c;
}

TEST(KnnTest, OneNeighbourRecoversTrainingRowsExactly) {
  const FeatureSet train = RandomSet(30, 1);
  for (const int64_t gcc_lags : {int64_t{0}, int64_t{4}}) {
    KnnConfig config = SmallConfig(1);
    config.gcc_lags = gcc_lags;
    const KnnBaseline knn(train, config);
    EXPECT_EQ(knn.size(), 30);
    EXPECT_EQ(knn.dimensions(), 2 * 4 * 5 + (gcc_lags > 0 ? 3 * 9 : 0));
    const std::vector<Prediction> p = knn.Predict(train);
    ASSERT_EQ(p.size(), 30u);
    for (int64_t i = 0; i < 30; ++i) {
      EXPECT_DOUBLE_EQ(p[i].z_m, train.z_m[i]) << i;
      EXPECT_NEAR(p[i].theta_rad, train.theta_rad[i], 1e-12) << i;
    }
    // metrics of an exact recovery are zero
    const Metrics m = ComputeMetrics(p, train, 0.05355);
    EXPECT_NEAR(m.med_cm, 0.0, 1e-9);
  }
}

TEST(KnnTest, CircularMeanAcrossTheSeam) {
  // three exact matches with angles around +-pi: their mean lies at pi, not near 0
  FeatureSet train = RandomSet(10, 2);
  const int64_t row = train.channels * train.mels * train.frames;
  for (int r : {1, 2}) std::copy_n(train.mel.begin(), row, train.mel.begin() + r * row);
  train.theta_rad[0] = kPi - 0.1;
  train.theta_rad[1] = -kPi + 0.1;
  train.theta_rad[2] = kPi - 0.05;
  train.z_m[0] = 0.01;
  train.z_m[1] = 0.02;
  train.z_m[2] = 0.06;
  const KnnBaseline knn(train, SmallConfig(3));
  const Prediction p = knn.Predict(train.SelectRows({0})).front();
  const double expected =
      std::atan2(std::sin(kPi - 0.1) + std::sin(-kPi + 0.1) + std::sin(kPi - 0.05),
                 std::cos(kPi - 0.1) + std::cos(-kPi + 0.1) + std::cos(kPi - 0.05));
  EXPECT_NEAR(p.theta_rad, expected, 1e-9);
  EXPECT_GT(std::abs(p.theta_rad), kPi - 0.05);
  EXPECT_NEAR(p.z_m, 0.03, 1e-12);  // equal weights for exact matches
  // the helper itself: opposite unit weights around the seam, and a vanishing resultant
  EXPECT_NEAR(std::abs(CircularMean({kPi - 0.2, -kPi + 0.2}, {1.0, 1.0}, 0.0)), kPi, 1e-12);
  EXPECT_EQ(CircularMean({0.5, 0.5 - kPi}, {1.0, 1.0}, 0.25), 0.25);
}

TEST(KnnTest, DistanceWeightingFavoursTheNearer) {
  // a test row between two training rows, three times nearer the first
  FeatureSet train = RandomSet(2, 3);
  const int64_t row = train.channels * train.mels * train.frames;
  FeatureSet test = train.SelectRows({0});
  for (int64_t i = 0; i < row; ++i) {
    const double a = std::log10(train.mel[i] + 1e-10), b = std::log10(train.mel[row + i] + 1e-10);
    test.mel[i] = static_cast<float>(std::pow(10.0, 0.75 * a + 0.25 * b) - 1e-10);
  }
  train.z_m = {0.0, 0.08};
  train.theta_rad = {0.0, 0.0};
  // standardized, the test row lies a quarter of the way from row 0 to row 1: weights 3 : 1
  const Prediction p = KnnBaseline(train, SmallConfig(2)).Predict(test).front();
  EXPECT_NEAR(p.z_m, 0.02, 1e-4);
  KnnConfig uniform = SmallConfig(2);
  uniform.distance_weighted = false;
  EXPECT_NEAR(KnnBaseline(train, uniform).Predict(test).front().z_m, 0.04, 1e-12);
}

TEST(KnnTest, DeterministicAcrossThreads) {
  const FeatureSet train = RandomSet(200, 4), test = RandomSet(150, 5);
  KnnConfig one = SmallConfig(5), many = SmallConfig(5);
  many.threads = 0;
  const std::vector<Prediction> a = KnnBaseline(train, one).Predict(test);
  const std::vector<Prediction> b = KnnBaseline(train, many).Predict(test);
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].z_m, b[i].z_m);
    EXPECT_EQ(a[i].theta_rad, b[i].theta_rad);
  }
}

TEST(KnnTest, ConstantPredictorIsTheMeanAndCircularMean) {
  const Prediction p = ConstantPrediction({0.01, 0.03, std::nan("")}, {3.0, -3.0, 0.0});
  EXPECT_NEAR(p.z_m, 0.02, 1e-12);
  EXPECT_NEAR(std::abs(p.theta_rad), kPi, 1e-12);
  EXPECT_THROW(ConstantPrediction({}, {}), SchemaError);
  EXPECT_THROW(ConstantPrediction({0.1}, {0.1, 0.2}), SchemaError);
}

TEST(KnnErrorTest, EmptyTrainingSetAndShapeMismatch) {
  // no rows, or only unlabelled ones
  EXPECT_THROW(KnnBaseline(RandomSet(0, 6), SmallConfig(1)), SchemaError);
  FeatureSet unlabelled = RandomSet(3, 6);
  for (double& z : unlabelled.z_m) z = std::nan("");
  EXPECT_THROW(KnnBaseline(unlabelled, SmallConfig(1)), SchemaError);
  // arrays that do not hold the declared shapes
  FeatureSet short_mel = RandomSet(4, 7);
  short_mel.mel.pop_back();
  EXPECT_THROW(KnnBaseline(short_mel, SmallConfig(1)), SchemaError);
  // a crop longer than the frames, GCC lags beyond the stored ones
  KnnConfig long_crop = SmallConfig(1);
  long_crop.crop_frames = 41;
  EXPECT_THROW(KnnBaseline(RandomSet(4, 7), long_crop), SchemaError);
  KnnConfig wide_gcc = SmallConfig(1);
  wide_gcc.gcc_lags = 11;
  EXPECT_THROW(KnnBaseline(RandomSet(4, 7), wide_gcc), SchemaError);
  // test features of other shapes
  const KnnBaseline knn(RandomSet(8, 8), SmallConfig(3));
  FeatureSet other = RandomSet(2, 9);
  other.mels = 5;
  other.mel.resize(2 * other.channels * other.mels * other.frames, 0.5f);
  EXPECT_THROW(knn.Predict(other), SchemaError);
  // bad config values name their key
  KnnConfig bad = SmallConfig(0);
  try {
    KnnBaseline(RandomSet(4, 7), bad);
    FAIL() << "k = 0 accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("knn.k"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sonicboom::learning
