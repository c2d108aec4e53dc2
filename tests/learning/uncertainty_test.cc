// The predictive distribution: von Mises and Gaussian intervals against independent
// computations, coverage and NLL in ComputeMetrics on synthetic predictions with known errors,
// and the post-hoc calibration recovering a known mis-scaling.

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>
#include <vector>

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include "common/test_util.h"
#include "internal/uncertainty.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/learning/conformal.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

using sonicboom::kPi;

// P(|x| <= h) for a von Mises variable of concentration kappa around 0, from the Fourier series
// of the density (h + 2 sum_n I_n(kappa) / I0(kappa) sin(n h) / n) / pi: an independent check
// of the grid integration, valid where std::cyl_bessel_i does not overflow.
double FourierCentralProbability(double kappa, double h) {
  const double i0 = std::cyl_bessel_i(0.0, kappa);
  double sum = h;
  for (int n = 1; n < 400; ++n) {
    const double term = 2.0 * std::cyl_bessel_i(double(n), kappa) / i0 * std::sin(n * h) / n;
    sum += term;
    if (n > kappa + 40 && std::abs(term) < 1e-17) break;
  }
  return sum / kPi;
}

TEST(UncertaintyMathTest, GaussianHalfWidthsAreTheNormalQuantiles) {
  EXPECT_NEAR(GaussianIntervalHalfWidth(0.5), 0.6744897501960817, 1e-12);
  EXPECT_NEAR(GaussianIntervalHalfWidth(0.68268949213708585), 1.0, 1e-12);
  EXPECT_NEAR(GaussianIntervalHalfWidth(0.9), 1.6448536269514722, 1e-12);
  EXPECT_NEAR(GaussianIntervalHalfWidth(0.95), 1.959963984540054, 1e-12);
  EXPECT_NEAR(GaussianIntervalHalfWidth(0.999), 3.2905267314918945, 1e-10);
}

TEST(UncertaintyMathTest, VonMisesIntervalOfAFlatDensityIsThatFractionOfTheCircle) {
  for (double kappa : {0.0, 1e-12, 1e-9}) {
    EXPECT_NEAR(VonMisesIntervalHalfWidth(kappa, 0.9), 0.9 * kPi, 1e-7) << kappa;
    EXPECT_NEAR(VonMisesIntervalHalfWidth(kappa, 0.5), 0.5 * kPi, 1e-7) << kappa;
  }
  // a weak concentration already narrows the interval, but not by much
  const double weak = VonMisesIntervalHalfWidth(0.05, 0.9);
  EXPECT_LT(weak, 0.9 * kPi);
  EXPECT_GT(weak, 0.85 * kPi);
}

TEST(UncertaintyMathTest, VonMisesIntervalOfAConcentratedDensityIsNormal) {
  // kappa -> infinity: the density tends to a normal of variance 1 / kappa
  for (double kappa : {1e4, 1e6, 1e9}) {
    for (double p : {0.5, 0.9}) {
      const double normal = GaussianIntervalHalfWidth(p) / std::sqrt(kappa);
      EXPECT_NEAR(VonMisesIntervalHalfWidth(kappa, p) / normal, 1.0, 1e-3) << kappa << " " << p;
    }
  }
  EXPECT_EQ(VonMisesIntervalHalfWidth(std::numeric_limits<double>::infinity(), 0.9), 0.0);
}

TEST(UncertaintyMathTest, VonMisesIntervalHoldsItsProbability) {
  double previous = kPi;
  for (double kappa : {0.3, 1.0, 2.0, 5.0, 20.0, 80.0, 300.0}) {
    for (double p : {0.5, 0.9, 0.99}) {
      const double h = VonMisesIntervalHalfWidth(kappa, p);
      EXPECT_NEAR(FourierCentralProbability(kappa, h), p, 1e-10) << kappa << " " << p;
      EXPECT_NEAR(VonMisesCentralProbability(kappa, h), p, 1e-12) << kappa << " " << p;
    }
    for (double h : {0.01, 0.3, 1.0, 2.5, 3.1}) {
      EXPECT_NEAR(VonMisesCentralProbability(kappa, h), FourierCentralProbability(kappa, h), 1e-10)
          << kappa << " " << h;
    }
    // narrower as the concentration grows
    const double h90 = VonMisesIntervalHalfWidth(kappa, 0.9);
    EXPECT_LT(h90, previous) << kappa;
    previous = h90;
  }
}

TEST(UncertaintyMathTest, BesselFunctionsAndCircularStd) {
  for (double k : {0.0, 0.1, 1.0, 5.0, 50.0, 99.9, 100.1, 300.0, 700.0}) {
    EXPECT_NEAR(LogBesselI0(k), std::log(std::cyl_bessel_i(0.0, k)), 1e-12 * std::max(1.0, k)) << k;
    EXPECT_NEAR(internal::VonMisesMeanResultant(k),
                k == 0.0 ? 0.0 : std::cyl_bessel_i(1.0, k) / std::cyl_bessel_i(0.0, k), 1e-13)
        << k;
  }
  // beyond double range of I0 itself: log I0(k) ~ k - log(2 pi k) / 2 + 1 / (8k)
  const double big = 1e6;
  EXPECT_NEAR(LogBesselI0(big), big - 0.5 * std::log(2.0 * kPi * big) + 1.0 / (8.0 * big), 1e-6);
  // circular std: sqrt(-2 ln A); about 1 / sqrt(kappa) when concentrated, unbounded when flat
  const double a1 = std::cyl_bessel_i(1.0, 1.0) / std::cyl_bessel_i(0.0, 1.0);
  EXPECT_NEAR(VonMisesCircularStd(1.0), std::sqrt(-2.0 * std::log(a1)), 1e-12);
  EXPECT_NEAR(VonMisesCircularStd(1e6) * 1e3, 1.0, 1e-5);
  EXPECT_GT(VonMisesCircularStd(1e-6), 5.0);
  EXPECT_TRUE(std::isinf(VonMisesCircularStd(0.0)));
}

// A draw from VonMises(0, kappa) (Best and Fisher 1979).
double SampleVonMises(Rng* rng, double kappa) {
  const double tau = 1.0 + std::sqrt(1.0 + 4.0 * kappa * kappa);
  const double rho = (tau - std::sqrt(2.0 * tau)) / (2.0 * kappa);
  const double r = (1.0 + rho * rho) / (2.0 * rho);
  while (true) {
    const double z = std::cos(kPi * rng->Uniform());
    const double f = (1.0 + r * z) / (r + z);
    const double c = kappa * (r - f);
    const double u2 = rng->Uniform();
    if (c * (2.0 - c) - u2 > 0.0 || std::log(c / u2) + 1.0 - c >= 0.0) {
      return (rng->Uniform() < 0.5 ? -1.0 : 1.0) * std::acos(std::clamp(f, -1.0, 1.0));
    }
  }
}

// Labels and predictions whose errors follow the predicted distribution exactly: per record a
// std of z between 2 mm and 3 cm and a concentration between 0.5 and 200.
struct Synthetic {
  std::vector<Prediction> predictions;
  FeatureSet truth;
};
Synthetic MakeSynthetic(int64_t n, uint64_t seed) {
  Synthetic s;
  Rng rng(seed);
  for (int64_t i = 0; i < n; ++i) {
    Prediction p;
    p.z_m = rng.Uniform(-0.1, 0.1);
    p.theta_rad = rng.Uniform(-kPi, kPi);
    p.z_std_m = std::exp(rng.Uniform(std::log(0.002), std::log(0.03)));
    p.theta_kappa = std::exp(rng.Uniform(std::log(0.5), std::log(200.0)));
    s.truth.z_m.push_back(p.z_m + rng.Normal(0.0, p.z_std_m));
    s.truth.theta_rad.push_back(
        std::remainder(p.theta_rad + SampleVonMises(&rng, p.theta_kappa), 2.0 * kPi));
    s.predictions.push_back(p);
  }
  return s;
}

std::vector<Prediction> Scaled(std::vector<Prediction> predictions, double z_factor,
                               double kappa_factor) {
  for (Prediction& p : predictions) {
    p.z_std_m *= z_factor;
    p.theta_kappa *= kappa_factor;
  }
  return predictions;
}

TEST(EnsembleCombinationTest, KappaForResultantInvertsTheMeanResultant) {
  for (const double kappa : {1e-3, 0.5, 2.0, 30.0, 900.0, 5e4}) {
    const double r = internal::VonMisesMeanResultant(kappa);
    EXPECT_NEAR(VonMisesKappaForResultant(r) / kappa, 1.0, 1e-6) << kappa;
  }
  EXPECT_EQ(VonMisesKappaForResultant(0.0), 0.0);
}

TEST(EnsembleCombinationTest, MixtureMomentsByHand) {
  Prediction a{0.02, 0.3, 0.004, 50.0};
  // identical members: the member itself
  const Prediction same = CombinePredictions({a, a, a});
  EXPECT_NEAR(same.z_m, a.z_m, 1e-15);
  EXPECT_NEAR(same.theta_rad, a.theta_rad, 1e-12);
  EXPECT_NEAR(same.z_std_m, a.z_std_m, 1e-15);
  EXPECT_NEAR(same.theta_kappa / a.theta_kappa, 1.0, 1e-6);
  // two members: mean z, mixture variance = mean variance + variance of the means
  Prediction b{0.04, 0.5, 0.003, 50.0};
  const Prediction two = CombinePredictions({a, b});
  EXPECT_NEAR(two.z_m, 0.03, 1e-15);
  EXPECT_NEAR(two.z_std_m, std::sqrt(0.5 * (0.004 * 0.004 + 0.003 * 0.003) + 0.01 * 0.01), 1e-15);
  // equal concentrations: the bisector, with the resultant shortened by cos(0.1)
  EXPECT_NEAR(two.theta_rad, 0.4, 1e-12);
  EXPECT_NEAR(internal::VonMisesMeanResultant(two.theta_kappa),
              internal::VonMisesMeanResultant(50.0) * std::cos(0.1), 1e-9);
  EXPECT_LT(two.theta_kappa, 50.0);
  // across the +-pi seam the direction wraps, it is not the arithmetic mean
  const Prediction seam = CombinePredictions({Prediction{0.0, 3.1, 0.01, 20.0},
                                              Prediction{0.0, -3.1, 0.01, 20.0}});
  EXPECT_NEAR(std::abs(seam.theta_rad), std::numbers::pi, 1e-12);
  // opposite directions: no preferred angle, a (nearly) flat distribution
  const Prediction flat = CombinePredictions({Prediction{0.0, 0.0, 0.01, 20.0},
                                              Prediction{0.0, std::numbers::pi, 0.01, 20.0}});
  EXPECT_TRUE(flat.has_uncertainty());
  EXPECT_LT(flat.theta_kappa, 1e-6);
  // members without a distribution: circular mean of the points, no distribution
  const Prediction points = CombinePredictions({Prediction{0.0, 0.2, NAN, NAN}, Prediction{0.02, 0.4, NAN, NAN}});
  EXPECT_NEAR(points.theta_rad, 0.3, 1e-12);
  EXPECT_NEAR(points.z_m, 0.01, 1e-15);
  EXPECT_FALSE(points.has_uncertainty());
}

TEST(UncertaintyMetricsTest, CoverageOfTheTrueDistributionIsNominal) {
  const int64_t n = 4000;
  const Synthetic s = MakeSynthetic(n, 17);
  const Metrics m = ComputeMetrics(s.predictions, s.truth, 0.05);
  ASSERT_EQ(m.n, n);
  // four standard errors of a binomial fraction: 0.032 at 0.5, 0.019 at 0.9
  EXPECT_NEAR(m.z_coverage_50, 0.5, 4.0 * std::sqrt(0.25 / n));
  EXPECT_NEAR(m.z_coverage_90, 0.9, 4.0 * std::sqrt(0.09 / n));
  EXPECT_NEAR(m.theta_coverage_50, 0.5, 4.0 * std::sqrt(0.25 / n));
  EXPECT_NEAR(m.theta_coverage_90, 0.9, 4.0 * std::sqrt(0.09 / n));
  EXPECT_TRUE(std::isfinite(m.nll));
  std::cout << "true distribution: z " << m.z_coverage_50 << " / " << m.z_coverage_90 << ", theta "
            << m.theta_coverage_50 << " / " << m.theta_coverage_90 << "\n";

  // Stds three times too small, kappas nine times too large: the intervals hold far less.
  // (A normal within 1.645 / 3 std: 0.42.)
  const Metrics narrow = ComputeMetrics(Scaled(s.predictions, 1.0 / 3.0, 9.0), s.truth, 0.05);
  EXPECT_LT(narrow.z_coverage_90, 0.6);
  EXPECT_NEAR(narrow.z_coverage_90, 0.416, 0.04);
  EXPECT_LT(narrow.z_coverage_50, 0.3);
  EXPECT_LT(narrow.theta_coverage_90, 0.7);
  EXPECT_LT(narrow.theta_coverage_50, 0.3);
  EXPECT_GT(narrow.nll, m.nll + 1.0);
  std::cout << "too narrow: z " << narrow.z_coverage_50 << " / " << narrow.z_coverage_90
            << ", theta " << narrow.theta_coverage_50 << " / " << narrow.theta_coverage_90
            << ", NLL " << narrow.nll << " against " << m.nll << "\n";
  // Too wide: everything inside, and a worse likelihood too.
  const Metrics wide = ComputeMetrics(Scaled(s.predictions, 5.0, 1.0 / 25.0), s.truth, 0.05);
  EXPECT_GT(wide.z_coverage_90, 0.99);
  EXPECT_GT(wide.z_coverage_50, 0.85);
  EXPECT_GT(wide.theta_coverage_50, 0.8);
  EXPECT_GT(wide.nll, m.nll + 0.5);
}

TEST(UncertaintyMetricsTest, NllOfOneRecordByHand) {
  // dz = 1.5 cm with std 2 cm; theta error 0.3 rad with kappa 4
  Prediction p{0.0, 0.0, 0.02, 4.0};
  FeatureSet truth;
  truth.z_m = {0.015};
  truth.theta_rad = {0.3};
  const Metrics m = ComputeMetrics({p}, truth, 0.05);
  const double z_nll = std::log(2.0) + 0.5 * std::log(2.0 * kPi) + 0.5 * 0.75 * 0.75;
  const double theta_nll = -4.0 * std::cos(0.3) + std::log(2.0 * kPi * std::cyl_bessel_i(0.0, 4.0));
  EXPECT_NEAR(m.nll, z_nll + theta_nll, 1e-12);
  EXPECT_EQ(m.z_coverage_50, 0.0);  // 1.5 cm > 0.674 * 2 cm
  EXPECT_EQ(m.z_coverage_90, 1.0);
  EXPECT_EQ(m.theta_coverage_90, 1.0);
}

TEST(UncertaintyMetricsTest, PredictionsWithoutUncertaintyHaveNoCoverage) {
  const Synthetic s = MakeSynthetic(10, 3);
  std::vector<Prediction> points;
  for (const Prediction& p : s.predictions) points.push_back({p.z_m, p.theta_rad});
  const Metrics m = ComputeMetrics(points, s.truth, 0.05);
  EXPECT_EQ(m.n, 10);
  EXPECT_TRUE(std::isfinite(m.med_cm));
  EXPECT_TRUE(std::isnan(m.z_coverage_90));
  EXPECT_TRUE(std::isnan(m.theta_coverage_50));
  EXPECT_TRUE(std::isnan(m.nll));
  // one record without a distribution is enough to withhold the figures
  std::vector<Prediction> mixed = s.predictions;
  mixed[4] = points[4];
  EXPECT_TRUE(std::isnan(ComputeMetrics(mixed, s.truth, 0.05).z_coverage_90));
  EXPECT_FALSE(points[0].has_uncertainty());
  EXPECT_TRUE(s.predictions[0].has_uncertainty());
}

// Coverage calibration: on Gaussian errors it finds the same mis-scaling as the likelihood; on
// heavy-tailed ones (a tenth of the strikes ten times further off, as off-distribution strikes
// are) the likelihood's rms scale is pulled by the far misses and over-covers, while the coverage
// fit holds 90 % on the strikes it was fitted on and on fresh ones of the same family.
TEST(UncertaintyCalibrationTest, CoverageFitHoldsTheLevelWhereTheLikelihoodDoesNot) {
  const Synthetic s = MakeSynthetic(3000, 31);
  const std::vector<Prediction> wrong = Scaled(s.predictions, 1.0 / 3.0, 4.0);
  const UncertaintyCalibration c = FitCoverageCalibration(wrong, s.truth);
  EXPECT_NEAR(c.z_std_scale, 3.0, 0.2);
  EXPECT_NEAR(c.kappa_scale, 0.25, 0.03);
  // heavy tails: every tenth record's error x10, a fresh set of the same family beside it
  const auto heavy = [](Synthetic set) {
    for (size_t i = 0; i < set.predictions.size(); i += 10) {
      const Prediction& p = set.predictions[i];
      set.truth.z_m[i] = p.z_m + 10.0 * (set.truth.z_m[i] - p.z_m);
      set.truth.theta_rad[i] = std::remainder(
          p.theta_rad + 10.0 * std::remainder(set.truth.theta_rad[i] - p.theta_rad, 2 * kPi),
          2 * kPi);
    }
    return set;
  };
  const Synthetic fit_set = heavy(MakeSynthetic(3000, 32)), fresh = heavy(MakeSynthetic(3000, 33));
  const auto coverage = [](const std::vector<Prediction>& predictions, const Synthetic& set,
                           const UncertaintyCalibration& scales) {
    std::vector<Prediction> scaled;
    for (const Prediction& p : predictions) scaled.push_back(ApplyCalibration(p, scales));
    return ComputeMetrics(scaled, set.truth, 0.05);
  };
  const UncertaintyCalibration by_coverage = FitCoverageCalibration(fit_set.predictions,
                                                                    fit_set.truth);
  const UncertaintyCalibration by_likelihood = FitUncertaintyCalibration(fit_set.predictions,
                                                                         fit_set.truth);
  const Metrics on_fit = coverage(fit_set.predictions, fit_set, by_coverage);
  const Metrics on_fresh = coverage(fresh.predictions, fresh, by_coverage);
  EXPECT_GE(on_fit.z_coverage_90, 0.9);
  EXPECT_LT(on_fit.z_coverage_90, 0.905);
  EXPECT_GE(on_fit.theta_coverage_90, 0.9);
  EXPECT_LT(on_fit.theta_coverage_90, 0.905);
  EXPECT_NEAR(on_fresh.z_coverage_90, 0.9, 0.02);
  EXPECT_NEAR(on_fresh.theta_coverage_90, 0.9, 0.02);
  EXPECT_GT(coverage(fresh.predictions, fresh, by_likelihood).z_coverage_90, 0.93);
  // nothing usable leaves the scales alone; mismatched counts are refused
  FeatureSet one;
  one.z_m = {0.0};
  one.theta_rad = {0.0};
  const UncertaintyCalibration none = FitCoverageCalibration({Prediction{}}, one);
  EXPECT_EQ(none.z_std_scale, 1.0);
  EXPECT_EQ(none.kappa_scale, 1.0);
  EXPECT_THROW(FitCoverageCalibration({}, one), SchemaError);
}

TEST(UncertaintyCalibrationTest, RecoversAKnownMisScaling) {
  const Synthetic s = MakeSynthetic(3000, 29);
  // The model claims stds three times too small and kappas four times too large.
  const std::vector<Prediction> wrong = Scaled(s.predictions, 1.0 / 3.0, 4.0);
  const UncertaintyCalibration c = FitUncertaintyCalibration(wrong, s.truth);
  std::cout << "fitted scales " << c.z_std_scale << " (true 3), " << c.kappa_scale
            << " (true 0.25)\n";
  EXPECT_NEAR(c.z_std_scale, 3.0, 0.1);
  EXPECT_NEAR(c.kappa_scale, 0.25, 0.015);
  // Applied, the coverage is nominal again and the NLL is back to that of the truth.
  std::vector<Prediction> fixed;
  for (const Prediction& p : wrong) fixed.push_back(ApplyCalibration(p, c));
  const Metrics before = ComputeMetrics(wrong, s.truth, 0.05);
  const Metrics after = ComputeMetrics(fixed, s.truth, 0.05);
  const Metrics truth = ComputeMetrics(s.predictions, s.truth, 0.05);
  EXPECT_LT(before.z_coverage_90, 0.6);
  EXPECT_NEAR(after.z_coverage_90, 0.9, 0.025);
  EXPECT_NEAR(after.theta_coverage_90, 0.9, 0.025);
  EXPECT_NEAR(after.z_coverage_50, 0.5, 0.04);
  EXPECT_NEAR(after.theta_coverage_50, 0.5, 0.04);
  EXPECT_LT(after.nll, before.nll);
  EXPECT_NEAR(after.nll, truth.nll, 0.01);
  // The fit minimizes the NLL: nudging either scale makes it worse.
  for (double factor : {0.95, 1.05}) {
    std::vector<Prediction> z_off, kappa_off;
    for (const Prediction& p : fixed) {
      z_off.push_back(ApplyCalibration(p, {factor, 1.0}));
      kappa_off.push_back(ApplyCalibration(p, {1.0, factor}));
    }
    EXPECT_GT(ComputeMetrics(z_off, s.truth, 0.05).nll, after.nll) << factor;
    EXPECT_GT(ComputeMetrics(kappa_off, s.truth, 0.05).nll, after.nll) << factor;
  }
}

TEST(UncertaintyCalibrationTest, DegenerateInputs) {
  // nothing usable: scales 1
  FeatureSet truth;
  truth.z_m = {0.0};
  truth.theta_rad = {0.0};
  const UncertaintyCalibration none = FitUncertaintyCalibration({{0.0, 0.0}}, truth);
  EXPECT_EQ(none.z_std_scale, 1.0);
  EXPECT_EQ(none.kappa_scale, 1.0);
  // angle errors of pi everywhere: the best kappa is the smallest allowed
  truth.theta_rad = {kPi};
  const UncertaintyCalibration flat = FitUncertaintyCalibration({{0.0, 0.0, 0.01, 5.0}}, truth);
  EXPECT_LE(flat.kappa_scale, 1e-4 * 1.0001);
  EXPECT_EQ(flat.z_std_scale, 1e-4);  // a perfect height: clamped at the smallest scale
  // a count mismatch is an error
  EXPECT_THROW(FitUncertaintyCalibration({}, truth), SchemaError);
  // a prediction without uncertainty is left alone by ApplyCalibration
  const Prediction point = ApplyCalibration({0.1, 0.2}, {2.0, 3.0});
  EXPECT_TRUE(std::isnan(point.z_std_m));
}

TEST(UncertaintyCalibrationTest, RecalibrateMultipliesTheStoredScalesOfAnEnsemble) {
  testing::TempDir dir;
  const std::string file = dir / "ensemble.json";
  WriteTextAtomic(file, R"({"members": ["member0", "member1"],
                           "uncertainty": {"z_std_scale": 0.5, "kappa_scale": 2.0}})");
  // predictions already carrying the stored scales, three times too sure in z, four in theta
  const Synthetic s = MakeSynthetic(3000, 31);
  const std::vector<Prediction> sure = Scaled(s.predictions, 1.0 / 3.0, 4.0);
  const Recalibration r = Recalibrate(dir.path().string(), sure, s.truth, "beyond.h5");
  EXPECT_EQ(r.before.z_std_scale, 0.5);
  EXPECT_EQ(r.before.kappa_scale, 2.0);
  EXPECT_NEAR(r.relative.z_std_scale, 3.0, 0.1);
  EXPECT_NEAR(r.relative.kappa_scale, 0.25, 0.015);
  EXPECT_DOUBLE_EQ(r.after.z_std_scale, 0.5 * r.relative.z_std_scale);
  EXPECT_DOUBLE_EQ(r.after.kappa_scale, 2.0 * r.relative.kappa_scale);
  // stored: the members untouched, the new scales read back, where they came from
  const UncertaintyCalibration read = EnsembleCalibration(dir.path().string());
  EXPECT_DOUBLE_EQ(read.z_std_scale, r.after.z_std_scale);
  EXPECT_DOUBLE_EQ(read.kappa_scale, r.after.kappa_scale);
  EXPECT_EQ(EnsembleMembers(dir.path().string()).size(), 2u);
  const nlohmann::json j = nlohmann::json::parse(ReadText(file));
  EXPECT_EQ(j["uncertainty"]["calibrated_on"], "beyond.h5");
  EXPECT_EQ(j["uncertainty"]["records"], 3000);
}

TEST(UncertaintyCalibrationTest, RecalibrateRefusesWhatItCannotFitAndStartsFromScalesOne) {
  testing::TempDir dir;
  const std::string file = dir / "ensemble.json";
  const Synthetic s = MakeSynthetic(40, 37);
  const std::string run = dir.path().string();
  WriteTextAtomic(file, R"({"members": ["member0"],
                           "uncertainty": {"z_std_scale": 1.0, "kappa_scale": 1.0}})");
  // predictions and labels differ in number
  std::vector<Prediction> fewer(s.predictions.begin(), s.predictions.end() - 1);
  EXPECT_THROW(Recalibrate(run, fewer, s.truth, "x.h5"), SchemaError);
  // point estimates only, or no label: nothing to fit
  std::vector<Prediction> points;
  for (const Prediction& p : s.predictions) points.push_back({p.z_m, p.theta_rad});
  EXPECT_THROW(Recalibrate(run, points, s.truth, "x.h5"), SchemaError);
  FeatureSet unlabelled = s.truth;
  for (double& z : unlabelled.z_m) z = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(Recalibrate(run, s.predictions, unlabelled, "x.h5"), SchemaError);
  // and a refused fit leaves the file as it was
  EXPECT_EQ(nlohmann::json::parse(ReadText(file))["uncertainty"].size(), 2u);
  // a file from before calibration existed holds scales 1: the fit becomes the stored scales
  WriteTextAtomic(file, R"({"members": ["member0"]})");
  const Recalibration r = Recalibrate(run, s.predictions, s.truth, "x.h5");
  EXPECT_EQ(r.before.z_std_scale, 1.0);
  EXPECT_EQ(r.after.z_std_scale, r.relative.z_std_scale);
  EXPECT_EQ(EnsembleCalibration(run).kappa_scale, r.relative.kappa_scale);
}

// A training's calibration has calibrate's minimum: below it the given scales stay, said so.
TEST(UncertaintyCalibrationTest, FitOrKeepCalibrationFitsOnlyOnTheMinimumOfStrikes) {
  const Synthetic s = MakeSynthetic(kMinFitRecords, 47);
  const std::vector<Prediction> wrong = Scaled(s.predictions, 1.0 / 3.0, 4.0);
  const CalibrationFit fit = FitOrKeepCalibration(wrong, s.truth, {2.0, 0.5}, "the pretrained");
  EXPECT_TRUE(fit.fitted);
  EXPECT_EQ(fit.records, kMinFitRecords);
  EXPECT_EQ(fit.scales.z_std_scale, FitUncertaintyCalibration(wrong, s.truth).z_std_scale);
  // one record fewer (or a label unknown): the kept scales, and the method says why
  FeatureSet one_unknown = s.truth;
  one_unknown.z_m[3] = std::numeric_limits<double>::quiet_NaN();
  const CalibrationFit kept =
      FitOrKeepCalibration(wrong, one_unknown, {2.0, 0.5}, "the pretrained scales of RUN");
  EXPECT_FALSE(kept.fitted);
  EXPECT_EQ(kept.records, kMinFitRecords - 1);
  EXPECT_EQ(kept.scales.z_std_scale, 2.0);
  EXPECT_EQ(kept.scales.kappa_scale, 0.5);
  EXPECT_EQ(kept.method,
            "not fitted: 29 validation strikes with a predictive distribution, fewer than the 30 "
            "a fit needs; the pretrained scales of RUN kept");
}

TEST(UncertaintyCalibrationTest, RecalibrateNeedsThirtyRecordsAndKeepsItsScalesBounded) {
  testing::TempDir dir;
  const std::string file = dir / "ensemble.json";
  const std::string run = dir.path().string();
  WriteTextAtomic(file, R"({"members": ["member0"]})");
  // one strike (it was accepted) and 29 are refused, naming the minimum
  const Synthetic few = MakeSynthetic(29, 41);
  try {
    Recalibrate(run, few.predictions, few.truth, "x.h5");
    ADD_FAILURE() << "29 records accepted";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("needs at least 30"), std::string::npos) << e.what();
  }
  // refits on strikes whose angle the predictions do not know push kappa down, one factor per
  // refit: the stored scale stops at the bound (it reached 1e-32)
  Synthetic s = MakeSynthetic(60, 43);
  for (double& theta : s.truth.theta_rad) theta = std::remainder(theta + 2.0, 2.0 * kPi);
  double kappa = 1.0;
  for (int refit = 0; refit < 12; ++refit) {
    const std::vector<Prediction> calibrated =
        Scaled(s.predictions, EnsembleCalibration(run).z_std_scale, kappa);
    kappa = Recalibrate(run, calibrated, s.truth, "x.h5").after.kappa_scale;
    EXPECT_GE(kappa, UncertaintyCalibration::kMinScale);
  }
  EXPECT_EQ(kappa, UncertaintyCalibration::kMinScale);
  // a stored scale out of bounds (a hand-edited 1e308) is refused by every reader
  WriteTextAtomic(file, R"({"members": ["member0"],
                           "uncertainty": {"z_std_scale": 1.0, "kappa_scale": 1e308}})");
  try {
    EnsembleCalibration(run);
    ADD_FAILURE() << "kappa_scale 1e308 accepted";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("uncertainty.kappa_scale"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace sonicboom::learning
