// How the fidelity ladder scores a rung (experiments/internal/fidelity_metrics.h): timing of known
// delays, the comparison low-pass, rank-matched frequencies.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <numbers>

#include "internal/fidelity_metrics.h"
#include "sonicboom/core/constants.h"

namespace sonicboom::experiments {
namespace {

using sonicboom::kPi;
constexpr double kFs = 44100.0;
// the bursts' first 300 samples, shifts within +-1 ms (44 samples)
constexpr WavefrontWindow kWavefront{.samples = 300, .max_lag_s = 0.001};

// (6 x 400) a decaying 2 kHz burst starting at sample 50 + delay[c] on channel c
Eigen::MatrixXd Bursts(const Eigen::VectorXd& delay_samples) {
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(6, 400);
  for (int c = 0; c < 6; ++c) {
    for (int k = 0; k < 400; ++k) {
      const double t = (k - 50.0 - delay_samples[c]) / kFs;
      if (t > 0) y(c, k) = std::sin(2 * kPi * 2000 * t) * std::exp(-t / 2e-3);
    }
  }
  return y;
}

TEST(FidelityMetricsTest, TimingErrorsOfAKnownDelay) {
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(6);
  Eigen::VectorXd late = none;
  late[2] = 3.0;  // channel 2 three samples late: 5 of the 15 pairs are off by 3 samples
  const TimingError e = TimingErrorUs(Bursts(late), Bursts(none), kFs, kWavefront);
  const double sample_us = 1e6 / kFs;
  EXPECT_NEAR(e.arrival_us, 3.0 / 6.0 * sample_us, 0.05 * sample_us);
  EXPECT_NEAR(e.delay_us, 3.0 * 5.0 / 15.0 * sample_us, 0.05 * sample_us);
  EXPECT_NEAR(e.delay_max_us, 3.0 * sample_us, 0.05 * sample_us);
  // the same delay on every channel moves the arrivals, not the inter-channel delays
  const TimingError common =
      TimingErrorUs(Bursts(Eigen::VectorXd::Constant(6, 2.0)), Bursts(none), kFs, kWavefront);
  EXPECT_NEAR(common.arrival_us, 2.0 * sample_us, 0.05 * sample_us);
  EXPECT_LT(common.delay_us, 0.01 * sample_us);
  EXPECT_DOUBLE_EQ(RelativeError(Bursts(none), Bursts(none)), 0.0);
}

TEST(FidelityMetricsTest, AlignedShiftsFindFractionalDelaysAndIgnoreTheLevel) {
  // channel c delayed by 0.37 c samples and scaled: the shifts find the delays between samples
  Eigen::VectorXd delay(6);
  for (int c = 0; c < 6; ++c) delay[c] = 0.37 * c;
  Eigen::MatrixXd y = Bursts(delay);
  y.row(3) *= 0.2;  // a weaker channel (another model's share of the direct wave) times the same
  const Eigen::VectorXd shift = AlignedShifts(y, Bursts(Eigen::VectorXd::Zero(6)), kFs, kWavefront);
  for (int c = 0; c < 6; ++c) EXPECT_NEAR(shift[c] * kFs, delay[c], 0.05) << c;
  // the pairs' errors are the differences of the shifts: channel 5 against channel 0
  const TimingError e = TimingErrorUs(y, Bursts(Eigen::VectorXd::Zero(6)), kFs, kWavefront);
  ASSERT_EQ(e.aligned_delay_errors_us.size(), 15u);
  EXPECT_NEAR(e.aligned_delay_errors_us[4], 1.85 / kFs * 1e6, 0.05 / kFs * 1e6);
  // a channel that leads has a negative shift; a shift never leaves the search bound
  const Eigen::VectorXd lead = AlignedShifts(
      Bursts(Eigen::VectorXd::Zero(6)), Bursts(Eigen::VectorXd::Constant(6, 4.5)), kFs, kWavefront);
  EXPECT_NEAR(lead[0] * kFs, -4.5, 0.05);
  const Eigen::VectorXd far = AlignedShifts(Bursts(Eigen::VectorXd::Constant(6, 90.0)),
                                            Bursts(Eigen::VectorXd::Zero(6)), kFs, kWavefront);
  EXPECT_LE(far.cwiseAbs().maxCoeff(), kWavefront.max_lag_s + 1e-12);
}

TEST(FidelityMetricsTest, MediansShowWhatOneHoppedChannelHides) {
  // one channel 20 samples (454 us) late, as when the threshold lands on a later wave packet:
  // the mean over pairs is 151 us, the median 0; every channel's and pair's error is kept
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(6);
  Eigen::VectorXd hop = none;
  hop[4] = 20.0;
  const TimingError e = TimingErrorUs(Bursts(hop), Bursts(none), kFs, kWavefront);
  const double sample_us = 1e6 / kFs;
  ASSERT_EQ(e.arrival_errors_us.size(), 6u);
  ASSERT_EQ(e.delay_errors_us.size(), 15u);
  EXPECT_NEAR(e.arrival_errors_us[4], 20.0 * sample_us, 0.05 * sample_us);
  EXPECT_NEAR(e.delay_us, 20.0 * 5.0 / 15.0 * sample_us, 0.05 * sample_us);
  EXPECT_LT(Median(e.delay_errors_us), 0.05 * sample_us);
  EXPECT_LT(Median(e.arrival_errors_us), 0.05 * sample_us);
  // the median of an even count is the mean of the middle two; of nothing, NaN
  EXPECT_DOUBLE_EQ(Median({4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_DOUBLE_EQ(Median({5.0, 1.0, 3.0}), 3.0);
  EXPECT_TRUE(std::isnan(Median({})));
}

TEST(FidelityMetricsTest, LowPassKeepsThePassBandAndStopsTheStopBand) {
  Eigen::MatrixXd y(2, 2000);
  for (int k = 0; k < 2000; ++k) {
    y(0, k) = std::sin(2 * kPi * 1000 * k / kFs);
    y(1, k) = std::sin(2 * kPi * 18000 * k / kFs);
  }
  const Eigen::MatrixXd out = LowPass(y, 15000.0, kFs);
  // away from the record's ends (the kernel is 101 taps)
  const Eigen::MatrixXd mid = out.middleCols(200, 1600), in = y.middleCols(200, 1600);
  EXPECT_LT((mid.row(0) - in.row(0)).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_LT(mid.row(1).cwiseAbs().maxCoeff(), 1e-3);
  // zero phase: the kept sine is not shifted
  EXPECT_NEAR(out(0, 1000), y(0, 1000), 1e-3);
}

TEST(FidelityMetricsTest, FrequenciesMatchByRankBelowTheLimit) {
  Eigen::VectorXd rung(3), reference(4);
  rung << 100.0, 200.0, 300.0;
  reference << 101.0, 200.0, 330.0, 20000.0;
  const FrequencyError e = RankedFrequencyError(rung, reference, 10000.0);
  EXPECT_EQ(e.modes, 3);
  EXPECT_EQ(e.reference_modes, 3);
  EXPECT_NEAR(e.median_pct, 100.0 * (1.0 - 100.0 / 101.0), 1e-9);
  EXPECT_NEAR(e.max_pct, 100.0 * (1.0 - 300.0 / 330.0), 1e-9);
}

}  // namespace
}  // namespace sonicboom::experiments
