// Deterministic random numbers and tube surface geometry.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <set>

#include "sonicboom/core/rng.h"
#include "sonicboom/core/tube.h"

namespace sonicboom {
namespace {

TEST(RngTest, SameSeedSameStreamDifferentStreamsDiffer) {
  Rng a(SampleSeed(7, 3), Stream::kStrike), b(SampleSeed(7, 3), Stream::kStrike);
  Rng c(SampleSeed(7, 3), Stream::kNoise);
  int equal_ac = 0;
  for (int i = 0; i < 100; ++i) {
    const uint64_t x = a.NextU64();
    EXPECT_EQ(x, b.NextU64());
    equal_ac += x == c.NextU64();
  }
  EXPECT_EQ(equal_ac, 0);
}

TEST(RngTest, SampleSeedsAreDistinct) {
  std::set<uint64_t> seeds;
  for (uint64_t i = 0; i < 10000; ++i) seeds.insert(SampleSeed(1, i));
  for (uint64_t s = 0; s < 100; ++s) seeds.insert(SampleSeed(s + 2, 0));
  EXPECT_EQ(seeds.size(), 10100u);
}

TEST(RngTest, UniformAndNormalMoments) {
  Rng rng(42);
  const int n = 200000;
  double su = 0, sn = 0, sn2 = 0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.Uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    su += u;
    const double g = rng.Normal();
    sn += g;
    sn2 += g * g;
  }
  EXPECT_NEAR(su / n, 0.5, 0.005);
  EXPECT_NEAR(sn / n, 0.0, 0.01);
  EXPECT_NEAR(sn2 / n, 1.0, 0.02);
  for (int i = 0; i < 1000; ++i) EXPECT_LT(rng.UniformInt(7), 7u);
}

TEST(TubeTest, WrapAngleIntoHalfOpenInterval) {
  const double pi = std::numbers::pi;
  EXPECT_DOUBLE_EQ(WrapAngle(pi), pi);
  EXPECT_DOUBLE_EQ(WrapAngle(-pi), pi);
  EXPECT_NEAR(WrapAngle(3 * pi / 2), -pi / 2, 1e-12);
  EXPECT_NEAR(WrapAngle(-7.0), -7.0 + 2 * pi, 1e-12);
}

TEST(TubeTest, SurfacePointsLieOnTheOuterSurface) {
  TubeConfig tube;
  for (double theta : {-3.0, -1.0, 0.0, 0.5, 3.14}) {
    const Eigen::Vector3d p = SurfacePoint(tube, 0.05, theta);
    EXPECT_NEAR(std::hypot(p.x(), p.y()), tube.outer_radius_m, 1e-15);
    EXPECT_NEAR(SurfaceNormal(theta).dot(p), tube.outer_radius_m, 1e-15);
  }
  // opposite sides at the same height: one diameter apart
  EXPECT_NEAR(SurfaceDistance(tube, 0.0, 0.0, 0.0, std::numbers::pi), 2 * tube.outer_radius_m,
              1e-12);
  EXPECT_NEAR(SurfaceDistance(tube, -0.1, 1.0, 0.1, 1.0), 0.2, 1e-12);
}

}  // namespace
}  // namespace sonicboom

namespace sonicboom {
namespace {

TEST(RngTest, NoiseSampleHasUnitVarianceAndBoundedTails) {
  Rng rng(7);
  const int n = 400000;
  double s = 0, s2 = 0, s4 = 0, peak = 0;
  for (int i = 0; i < n; ++i) {
    const double x = rng.NoiseSample();
    s += x;
    s2 += x * x;
    s4 += x * x * x * x;
    peak = std::max(peak, std::abs(x));
  }
  EXPECT_NEAR(s / n, 0.0, 0.01);
  EXPECT_NEAR(s2 / n, 1.0, 0.01);
  // Irwin-Hall(4) kurtosis is 3 - 1.2 / 4 = 2.7
  EXPECT_NEAR(s4 / n, 2.7, 0.05);
  EXPECT_LE(peak, std::sqrt(12.0) + 1e-9);
}

}  // namespace
}  // namespace sonicboom
