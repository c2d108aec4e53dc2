// Which answers of a pretrained run become pseudo-labels (experiments/internal/pseudo_labels.h):
// the surest fraction by predictive spread, their labels the answers, and the refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "internal/pseudo_labels.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {
namespace {

constexpr double kRadiusM = 0.05355;

learning::Prediction Answer(double z_m, double theta_rad, double z_std_m, double kappa) {
  return {.z_m = z_m, .theta_rad = theta_rad, .z_std_m = z_std_m, .theta_kappa = kappa};
}

TEST(PseudoLabelsTest, SpreadIsTheSurfaceStandardDeviation) {
  // z_std 3 mm, theta's circular std sqrt(-2 ln(I1/I0)) ~ 1/sqrt(kappa) for large kappa: at
  // kappa 1e6, 1 mrad, 0.0536 mm along the surface
  const double spread = PredictiveSpreadCm(Answer(0, 0, 0.003, 1e6), kRadiusM);
  EXPECT_NEAR(spread, 100.0 * std::hypot(0.003, kRadiusM * 1e-3), 1e-6);
  // a wide angle dominates: kappa 1 is a circular std of about 1.4 rad
  EXPECT_GT(PredictiveSpreadCm(Answer(0, 0, 0.003, 1.0), kRadiusM), 5.0);
  EXPECT_TRUE(std::isnan(PredictiveSpreadCm(learning::Prediction{}, kRadiusM)));
}

TEST(PseudoLabelsTest, KeepsTheSurestFractionInSetOrder) {
  // spreads by row: 5, 1, 4, 2, 3 mm (angle nearly certain)
  const std::vector<learning::Prediction> p = {
      Answer(0.00, 0.1, 0.005, 1e8), Answer(0.01, 0.2, 0.001, 1e8), Answer(0.02, 0.3, 0.004, 1e8),
      Answer(0.03, 0.4, 0.002, 1e8), Answer(0.04, 0.5, 0.003, 1e8)};
  PseudoLabelSelection s = SelectPseudoLabels(p, 0.4, kRadiusM);
  EXPECT_EQ(s.rows, (std::vector<int64_t>{1, 3}));
  EXPECT_NEAR(s.spread_limit_cm, 0.2, 1e-3);
  // ceil(0.5 * 5) = 3 records; a tiny fraction still keeps one
  EXPECT_EQ(SelectPseudoLabels(p, 0.5, kRadiusM).rows, (std::vector<int64_t>{1, 3, 4}));
  EXPECT_EQ(SelectPseudoLabels(p, 1e-6, kRadiusM).rows, (std::vector<int64_t>{1}));
  // all of them, without a ranking (so without needing a distribution)
  std::vector<learning::Prediction> bare(3);
  s = SelectPseudoLabels(bare, 1.0, kRadiusM);
  EXPECT_EQ(s.rows, (std::vector<int64_t>{0, 1, 2}));
  EXPECT_TRUE(std::isnan(s.spread_limit_cm));
}

TEST(PseudoLabelsTest, TheKeptRowsCarryTheAnswersAsLabels) {
  learning::FeatureSet f;
  f.mel = {1, 2, 3};  // (3 x 1 x 1 x 1): one value per record
  f.channels = f.mels = f.frames = 1;
  f.z_m = {0.1, 0.2, 0.3};
  f.theta_rad = {1.0, 2.0, 3.0};
  const std::vector<learning::Prediction> p = {
      Answer(-0.1, -1, 0.01, 10), Answer(-0.2, -2, 0.01, 10), Answer(-0.3, -3, 0.01, 10)};
  const learning::FeatureSet out = WithPseudoLabels(f, p, {0, 2});
  EXPECT_EQ(out.mel, (std::vector<float>{1, 3}));
  EXPECT_EQ(out.z_m, (std::vector<double>{-0.1, -0.3}));
  EXPECT_EQ(out.theta_rad, (std::vector<double>{-1, -3}));
}

TEST(PseudoLabelsTest, RefusesFractionsOutsideTheUnitIntervalAndRankingWithoutSpread) {
  const std::vector<learning::Prediction> p = {Answer(0, 0, 0.01, 10), learning::Prediction{}};
  for (double bad : {0.0, -0.5, 1.5, std::nan("")}) {
    try {
      SelectPseudoLabels(p, bad, kRadiusM);
      ADD_FAILURE() << bad << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("--pseudo-labels"), std::string::npos) << e.what();
    }
  }
  try {
    SelectPseudoLabels(p, 0.5, kRadiusM);
    ADD_FAILURE() << "ranked answers without a distribution";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("strike 1 no predictive distribution"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(SelectPseudoLabels({}, 1.0, kRadiusM), ConfigError);
}

}  // namespace
}  // namespace sonicboom::experiments
