// The analytic TDOA locator: wave speeds, surface paths, location of synthetic dispersive
// strikes, the gain of dispersion, the speed fit, error paths.
#include "sonicboom/acoustics/tdoa.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <unsupported/Eigen/FFT>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;
constexpr double kFs = 44100.0;
constexpr int64_t kOnset = 2000;

TdoaGeometry DefaultGeometry(bool seamed) {
  ShellConfig shell;
  shell.ideal = !seamed;
  return MakeTdoaGeometry(TubeConfig{}, MaterialConfig{}, MicArrayConfig{}, shell);
}

// Six channels of a unit impulse at (z, theta) at sample kOnset, each travelling its surface path
// as Kirchhoff flexural waves (phase k(f) L, k = w / c_phase), band-limited to 0.5-20 kHz with
// cosine edges; every speed times speed_factor.
Eigen::MatrixXf DispersiveStrike(const TdoaGeometry& g, double z, double theta,
                                 double speed_factor = 1.0) {
  constexpr int64_t kLength = 8192;
  const int64_t bins = kLength / 2 + 1;
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  Eigen::MatrixXf record(static_cast<int64_t>(g.mic_z_m.size()), kLength);
  std::vector<std::complex<double>> spectrum(static_cast<size_t>(bins));
  std::vector<double> signal(static_cast<size_t>(kLength));
  for (size_t m = 0; m < g.mic_z_m.size(); ++m) {
    const double path = SurfacePathLength(g, z, theta, g.mic_z_m[m], g.mic_theta_rad[m]);
    for (int64_t k = 0; k < bins; ++k) {
      const double f = k * kFs / kLength;
      double a = 0.0;
      if (f > 300.0 && f < 21000.0) {
        a = 1.0;
        if (f < 500.0) a = 0.5 - 0.5 * std::cos(kPi * (f - 300.0) / 200.0);
        if (f > 20000.0) a = 0.5 + 0.5 * std::cos(kPi * (f - 20000.0) / 1000.0);
      }
      const double omega = 2.0 * kPi * f;
      const double c =
          f > 0.0 ? speed_factor * FlexuralPhaseVelocity(f, g.material, g.wall_thickness_m) : 1.0;
      const double phase = omega * kOnset / kFs + (f > 0.0 ? omega / c * path : 0.0);
      spectrum[k] = a * std::polar(1.0, -phase);
    }
    fft.inv(signal.data(), spectrum.data(), kLength);
    for (int64_t t = 0; t < kLength; ++t)
      record(static_cast<int64_t>(m), t) = static_cast<float>(signal[t]);
  }
  return record;
}

double SurfaceError(double z1, double t1, double z2, double t2) {
  const double r = 0.05355;
  return std::sqrt(std::pow(r * (std::cos(t1) - std::cos(t2)), 2) +
                   std::pow(r * (std::sin(t1) - std::sin(t2)), 2) + std::pow(z1 - z2, 2));
}

TEST(TdoaTest, FlexuralSpeedsMatchThePlateTable) {
  // docs/physics.md, "Flexural waves": c_phase 93.6 m/s at 1 kHz, 295.9 at 10 kHz; c_group twice
  const MaterialConfig pvc;
  EXPECT_NEAR(FlexuralPhaseVelocity(1000.0, pvc, 0.00305), 93.6, 0.1);
  EXPECT_NEAR(FlexuralPhaseVelocity(10000.0, pvc, 0.00305), 295.9, 0.2);
  EXPECT_NEAR(FlexuralGroupVelocity(20000.0, pvc, 0.00305), 836.9, 0.5);
}

TEST(TdoaTest, SurfacePathsOnClosedAndSeamedTubes) {
  const TdoaGeometry closed = DefaultGeometry(false);
  const double r = closed.radius_m;
  // closed tube: the shorter helix, across theta = +-pi
  EXPECT_NEAR(SurfacePathLength(closed, 0.0, 3.0, 0.03, -3.0),
              std::hypot(0.03, r * (2 * kPi - 6.0)), 1e-12);
  // seamed tube (cuts at 90 and 270 deg, bolts at z = -0.1, 0, 0.1): inside a half, straight
  const TdoaGeometry seamed = DefaultGeometry(true);
  const double deg = kPi / 180.0;
  EXPECT_NEAR(SurfacePathLength(seamed, 0.02, 10 * deg, -0.01, 60 * deg),
              std::hypot(0.03, r * 50 * deg), 1e-12);
  // across the cut at 90 deg only through a bolt: from z = 0.05 the bolts at 0 and 0.1 tie
  EXPECT_NEAR(SurfacePathLength(seamed, 0.05, 80 * deg, 0.05, 100 * deg),
              2.0 * std::hypot(0.05, r * 10 * deg), 1e-12);
  // at a bolt's height the path runs straight through it
  EXPECT_NEAR(SurfacePathLength(seamed, 0.1, 80 * deg, 0.1, 100 * deg), r * 20 * deg, 1e-12);
  // symmetric
  EXPECT_NEAR(SurfacePathLength(seamed, 0.07, -30 * deg, -0.05, 200 * deg),
              SurfacePathLength(seamed, -0.05, 200 * deg, 0.07, -30 * deg), 1e-12);
}

TEST(TdoaTest, LocatesSyntheticDispersiveStrikes) {
  // a strike made by the dispersive model is located within a few mm and degrees, seamed and
  // closed tube alike
  for (const bool seamed : {true, false}) {
    const TdoaGeometry g = DefaultGeometry(seamed);
    const TdoaLocator locator(g, TdoaConfig{}, kFs);
    for (const auto& [z, theta] :
         {std::pair{0.043, 0.7}, std::pair{-0.081, -2.9}, std::pair{0.005, 3.1}}) {
      const TdoaEstimate e = locator.Locate(DispersiveStrike(g, z, theta), kOnset);
      SCOPED_TRACE(::testing::Message() << "seamed " << seamed << " z " << z << " theta " << theta);
      EXPECT_NEAR(e.z_m, z, 0.003);
      EXPECT_LT(std::abs(std::remainder(e.theta_rad - theta, 2 * kPi)) * 180 / kPi, 3.0);
      EXPECT_GT(e.score, 0.0);
    }
  }
}

TEST(TdoaTest, DispersionBeatsOneSpeed) {
  // dispersive input, octave bands 1-8 kHz: one speed for every band is far worse at its
  // analytic value (the group velocity at 2.8 kHz) and still worse at the best speed of a scan
  // (a fitted scale); measured 14.7 mm and 2.9 mm against 1.6 mm
  const TdoaGeometry g = DefaultGeometry(true);
  TdoaConfig per_band;
  per_band.band_edges_hz = {1000.0, 2000.0, 4000.0, 8000.0};
  TdoaConfig flat = per_band;
  flat.dispersive = false;
  const TdoaLocator dispersive(g, per_band, kFs);
  const TdoaLocator single(g, flat, kFs);
  const std::vector<std::pair<double, double>> strikes{
      {0.043, 0.7}, {-0.081, -2.9}, {0.06, 2.0}, {-0.02, -1.2}};
  const std::vector<double> scales{0.8, 0.9, 1.0, 1.1, 1.25, 1.4, 1.6};
  double err_dispersive = 0.0;
  std::vector<double> err_single(scales.size(), 0.0);
  for (const auto& [z, theta] : strikes) {
    const Eigen::MatrixXf record = DispersiveStrike(g, z, theta);
    const TdoaEstimate e = dispersive.Locate(record, kOnset);
    err_dispersive += SurfaceError(e.z_m, e.theta_rad, z, theta) / strikes.size();
    const TdoaCorrelations c = single.Correlate(record, kOnset);
    for (size_t s = 0; s < scales.size(); ++s) {
      const TdoaEstimate f = single.Locate(c, scales[s]);
      err_single[s] += SurfaceError(f.z_m, f.theta_rad, z, theta) / strikes.size();
    }
  }
  const double analytic_single = err_single[2];
  const double best_single = *std::min_element(err_single.begin(), err_single.end());
  EXPECT_LT(err_dispersive, 0.0025);
  EXPECT_GT(analytic_single, 4.0 * err_dispersive)
      << analytic_single << " m against " << err_dispersive << " m";
  EXPECT_GT(best_single, 1.3 * err_dispersive)
      << best_single << " m against " << err_dispersive << " m";
}

TEST(TdoaTest, SpeedFitRecoversAScaledMaterial) {
  // strikes whose waves run 25 % faster than the plate model: the fitted scale finds it
  const TdoaGeometry g = DefaultGeometry(true);
  const TdoaLocator locator(g, TdoaConfig{}, kFs);
  std::vector<TdoaCorrelations> strikes;
  std::vector<double> z{0.03, -0.07, 0.08}, theta{0.4, -2.2, 2.6};
  for (size_t i = 0; i < z.size(); ++i) {
    strikes.push_back(locator.Correlate(DispersiveStrike(g, z[i], theta[i], 1.25), kOnset));
  }
  double med = 0.0;
  const double scale = FitSpeedScale(locator, strikes, z, theta, 0.05355, 0.7, 1.6, 1, &med);
  EXPECT_NEAR(scale, 1.25, 0.06);
  EXPECT_LT(med, 0.004);
}

TEST(TdoaTest, PredictedLagSignFollowsGccPhat) {
  // a contact next to mic 0 reaches it first: pair (0, 3) has a negative lag (mic 0 earlier)
  const TdoaLocator locator(DefaultGeometry(true), TdoaConfig{}, kFs);
  EXPECT_LT(locator.PredictedLag(-0.1, 0.0, 2, 0), 0.0);  // pair 2 = (0, 3)
  // lower bands are slower: the same path difference is a longer lag
  EXPECT_GT(std::abs(locator.PredictedLag(-0.1, 0.0, 2, 0)),
            std::abs(locator.PredictedLag(-0.1, 0.0, 2, 3)));
  EXPECT_LT(locator.BandSpeed(0), locator.BandSpeed(3));
}

TEST(TdoaErrorTest, BadConfigAndInput) {
  const TdoaGeometry g = DefaultGeometry(true);
  TdoaConfig bad;
  bad.band_edges_hz = {2000.0, 1000.0};
  EXPECT_THROW(TdoaLocator(g, bad, kFs), ConfigError);
  bad = TdoaConfig{};
  bad.band_edges_hz = {8000.0, 30000.0};  // above Nyquist
  EXPECT_THROW(TdoaLocator(g, bad, kFs), ConfigError);
  bad = TdoaConfig{};
  bad.band_weights = {1.0};  // one weight for four bands
  EXPECT_THROW(TdoaLocator(g, bad, kFs), ConfigError);
  TdoaGeometry no_bolts = g;
  no_bolts.bolt_z_m.clear();
  EXPECT_THROW(TdoaLocator(no_bolts, TdoaConfig{}, kFs), ConfigError);
  TdoaGeometry one_mic = g;
  one_mic.mic_z_m.resize(1);
  one_mic.mic_theta_rad.resize(1);
  EXPECT_THROW(TdoaLocator(one_mic, TdoaConfig{}, kFs), ConfigError);

  const TdoaLocator locator(g, TdoaConfig{}, kFs);
  EXPECT_THROW(locator.Correlate(Eigen::MatrixXf::Zero(2, 4000), 2000), Error);
  const TdoaCorrelations c = locator.Correlate(Eigen::MatrixXf::Zero(6, 4000), 2000);
  EXPECT_THROW(locator.Locate(c, 0.1), ConfigError);  // below min_speed_scale
  EXPECT_THROW(FitSpeedScale(locator, {}, {}, {}, 0.05, 0.5, 2.0, 1), Error);
  // silence: a finite estimate inside the region, zero score
  const TdoaEstimate e = locator.Locate(c, 1.0);
  EXPECT_GE(e.z_m, g.z_min_m);
  EXPECT_LE(e.z_m, g.z_max_m);
  EXPECT_EQ(e.score, 0.0);
}

}  // namespace
}  // namespace sonicboom::acoustics
