// --tune auto's rule on synthetic fold results (no training): a tuned candidate replaces the
// pretrained weights only when the folds say it is better beyond their spread; fold assignment.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/test_util.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/learning/fine_tune.h"

namespace sonicboom::learning {
namespace {

using ::testing::HasSubstr;

const std::vector<double> kPretrained = {1.0, 1.1, 0.9, 1.0, 1.2};

// The pretrained folds shifted by `d` fold by fold.
std::vector<double> Shifted(const std::vector<double>& d) {
  std::vector<double> v = kPretrained;
  for (size_t f = 0; f < v.size(); ++f) v[f] += d[f];
  return v;
}

TEST(FineTuneSelectionTest, AWorseTunedCandidateKeepsThePretrainedWeights) {
  const FineTuneChoice c =
      SelectFineTune({kPretrained, Shifted({0.3, 0.1, 0.2, 0.4, 0.3})}, {}, {"pre", "tuned"});
  EXPECT_EQ(c.chosen, 0);
  EXPECT_EQ(c.folds_better[1], 0);
  EXPECT_GT(c.t_statistic[1], 0.0);
  EXPECT_THAT(c.why, HasSubstr("pretrained weights kept"));
  EXPECT_THAT(c.why, HasSubstr("best tuned"));
}

TEST(FineTuneSelectionTest, ATunedCandidateWithinTheNoiseKeepsThePretrainedWeights) {
  // lower on average, and on 3 of 5 folds, but by less than its spread
  FineTuneChoice c = SelectFineTune({kPretrained, Shifted({-0.2, 0.15, -0.1, 0.1, -0.1})});
  EXPECT_EQ(c.chosen, 0);
  EXPECT_LT(c.mean_med_cm[1], c.mean_med_cm[0]);
  EXPECT_EQ(c.folds_better[1], 3);
  // lower on 4 of 5 folds by 0.14 cm on average, t = -1.91 (needs < -2.132): not at 5 %, but at 10 %
  const std::vector<std::vector<double>> folds = {kPretrained,
                                                  Shifted({-0.3, -0.2, 0.1, -0.25, -0.05})};
  c = SelectFineTune(folds);
  EXPECT_EQ(c.chosen, 0);
  EXPECT_NEAR(c.t_statistic[1], -1.914, 1e-3);
  EXPECT_DOUBLE_EQ(c.t_critical, 2.132);
  EXPECT_EQ(SelectFineTune(folds, {.alpha = 0.10}).chosen, 1);
}

TEST(FineTuneSelectionTest, AClearlyBetterCandidateIsChosenAndTheBestOfSeveral) {
  const std::vector<double> better = Shifted({-0.5, -0.6, -0.4, -0.55, -0.45});
  const std::vector<double> best = Shifted({-0.7, -0.8, -0.6, -0.7, -0.75});
  FineTuneChoice c = SelectFineTune({kPretrained, better}, {}, {"pre", "none lr 3e-4"});
  EXPECT_EQ(c.chosen, 1);
  EXPECT_EQ(c.folds_better[1], 5);
  EXPECT_THAT(c.why, HasSubstr("none lr 3e-4: held-out MED 0.540 cm against 1.040 cm"));
  c = SelectFineTune({kPretrained, better, best});
  EXPECT_EQ(c.chosen, 2);
  // a worse candidate listed first changes nothing; one lower by the same amount on every fold
  // has no spread and passes
  EXPECT_EQ(SelectFineTune({kPretrained, Shifted({1, 1, 1, 1, 1}), better}).chosen, 2);
  c = SelectFineTune({kPretrained, Shifted({-0.1, -0.1, -0.1, -0.1, -0.1})});
  EXPECT_EQ(c.chosen, 1);
  EXPECT_LT(c.t_statistic[1], -1e3);
  // the same MED on every fold: no difference, kept
  EXPECT_EQ(SelectFineTune({kPretrained, kPretrained}).chosen, 0);
  EXPECT_EQ(SelectFineTune({kPretrained}).chosen, 0);
}

TEST(FineTuneSelectionTest, RefusesFoldsItCannotJudge) {
  using sonicboom::testing::ThrownMessage;
  EXPECT_THAT(ThrownMessage<ConfigError>([] { SelectFineTune({{1.0}, {0.5}}); }),
              HasSubstr("1 folds"));
  EXPECT_THAT(ThrownMessage<ConfigError>([] { SelectFineTune({{1.0, 1.0}, {0.5}}); }),
              HasSubstr("unequal folds"));
  EXPECT_THAT(ThrownMessage<ConfigError>([] { SelectFineTune({kPretrained}, {.alpha = 0.2}); }),
              HasSubstr("alpha = 0.2"));
}

TEST(FineTuneFoldsTest, EveryRowOnceInFoldsOfEqualSizeWhateverTheRowOrder) {
  std::vector<uint64_t> indices;
  for (uint64_t i = 0; i < 23; ++i) indices.push_back(1000 + 7 * i);
  const std::vector<int64_t> folds = AssignFolds(indices, 5, 3);
  std::vector<int64_t> sizes(5, 0);
  for (const int64_t f : folds) ++sizes.at(static_cast<size_t>(f));
  EXPECT_EQ(*std::min_element(sizes.begin(), sizes.end()), 4);
  EXPECT_EQ(*std::max_element(sizes.begin(), sizes.end()), 5);
  // the same strike lands in the same fold in any order; another seed deals them otherwise
  std::vector<uint64_t> reversed(indices.rbegin(), indices.rend());
  const std::vector<int64_t> folds_reversed = AssignFolds(reversed, 5, 3);
  for (size_t r = 0; r < indices.size(); ++r) {
    EXPECT_EQ(folds[r], folds_reversed[indices.size() - 1 - r]);
  }
  EXPECT_NE(AssignFolds(indices, 5, 4), folds);
  // as many folds as strikes: one each
  std::vector<int64_t> sorted = AssignFolds({5, 6, 7, 8, 9}, 5, 3);
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, (std::vector<int64_t>{0, 1, 2, 3, 4}));
}

}  // namespace
}  // namespace sonicboom::learning
