// The training-free arrival locator: picks on synthetic wavefronts, the fit recovers point and
// speed, channel gains do not move it, bad settings are refused naming the field.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "../common/test_util.h"
#include "sonicboom/acoustics/arrival.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;
constexpr double kFs = 44100.0;

TdoaGeometry Geometry() {
  return MakeTdoaGeometry(TubeConfig{}, MaterialConfig{}, MicArrayConfig{}, ShellConfig{});
}

// a record of low noise with, on channel k, a 6 kHz burst arriving at onset + d_k / c (the
// burst's first half-cycle at full size), scaled by gain[k]
Eigen::MatrixXf Wavefront(const TdoaGeometry& g, double z, double theta, double speed,
                          int64_t onset, const std::vector<double>& gain) {
  Eigen::MatrixXf x = Eigen::MatrixXf::Zero(6, 44100);
  uint32_t state = 12345;
  for (int k = 0; k < 6; ++k) {
    for (int64_t t = 0; t < x.cols(); ++t) {
      state = state * 1664525u + 1013904223u;
      x(k, t) = 1e-5f * (static_cast<float>(state >> 8) / 16777216.0f - 0.5f);
    }
    const double d = SurfacePathLength(g, z, theta, g.mic_z_m[k], g.mic_theta_rad[k]);
    const double t0 = onset / kFs + d / speed;
    for (int64_t t = static_cast<int64_t>(t0 * kFs); t < x.cols(); ++t) {
      const double u = t / kFs - t0;
      if (u < 0) continue;
      if (u > 0.003) break;
      x(k, t) +=
          static_cast<float>(gain[k] * 0.1 * std::sin(2 * kPi * 6000 * u) * std::exp(-u / 0.001));
    }
  }
  return x;
}

double SurfaceError(double z1, double t1, double z2, double t2, double r) {
  return std::hypot(z1 - z2, 2 * r * std::sin(0.5 * std::remainder(t1 - t2, 2 * kPi)));
}

TEST(ArrivalLocatorTest, RecoversPointAndSpeedOfAWavefront) {
  const TdoaGeometry g = Geometry();
  const ArrivalLocator locator(g, ArrivalConfig{}, kFs);
  const int64_t onset = 20000;
  for (const auto& [z, theta] :
       {std::pair{0.05, 0.4}, std::pair{-0.08, 2.5}, std::pair{0.0, -1.9}}) {
    SCOPED_TRACE(std::to_string(z) + ", " + std::to_string(theta));
    // channel gains 10x apart: the per-channel threshold keeps the picks
    const Eigen::MatrixXf x = Wavefront(g, z, theta, 600.0, onset, {1, 0.1, 2, 0.5, 1, 3});
    const ArrivalEstimate e = locator.Locate(x, onset);
    EXPECT_LT(SurfaceError(e.z_m, e.theta_rad, z, theta, g.radius_m), 0.01);
    EXPECT_NEAR(e.speed_m_s, 600.0, 120.0);
    EXPECT_LT(e.residual_s, 5.0 / kFs);
  }
}

TEST(ArrivalLocatorTest, BadSettingsAndRecordsAreRefused) {
  ArrivalConfig c;
  c.min_speed_m_s = 4000;
  const std::string m =
      testing::ThrownMessage<ConfigError>([&] { ArrivalLocator(Geometry(), c, kFs); });
  EXPECT_NE(m.find("arrival.min_speed_m_s"), std::string::npos) << m;
  c = {};
  c.highpass_hz = 30000;
  EXPECT_THROW(ArrivalLocator(Geometry(), c, kFs), ConfigError);
  const ArrivalLocator locator(Geometry(), ArrivalConfig{}, kFs);
  EXPECT_THROW(locator.PickArrivals(Eigen::MatrixXf::Zero(4, 1000), 500), Error);
}

}  // namespace
}  // namespace sonicboom::acoustics
