// Kinematic strikes: labels on the surface, determinism, proprioception consistency.
#include <gtest/gtest.h>

#include <cmath>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {
namespace {

TEST(StrikeTest, LabelsOnSurfaceInsideRegionWithApproachSpeed) {
  const TubeConfig tube;
  const StrikeModel model(StrikeConfig{}, SceneConfig{}, tube, AudioConfig{});
  int valid = 0;
  double theta_min = 10, theta_max = -10;
  for (uint64_t i = 0; i < 500; ++i) {
    const StrikeEvents ev = model.Generate(SampleSeed(5, i));
    if (!ev.valid) continue;
    ++valid;
    const ContactLabel& l = ev.label;
    EXPECT_NEAR(std::hypot(l.point_m.x(), l.point_m.y()), tube.outer_radius_m, 1e-12);
    EXPECT_GE(l.z_m, tube.contact_z_min_m);
    EXPECT_LE(l.z_m, tube.contact_z_max_m);
    EXPECT_GT(l.theta_rad, -M_PI);
    EXPECT_LE(l.theta_rad, M_PI);
    EXPECT_NEAR(l.normal.norm(), 1.0, 1e-12);
    // the reference motion: a few cm/s to a few dm/s at the tube
    EXPECT_GT(ev.contact.normal_speed_m_s, 0.01);
    EXPECT_LT(ev.contact.normal_speed_m_s, 0.5);
    theta_min = std::min(theta_min, l.theta_rad);
    theta_max = std::max(theta_max, l.theta_rad);
  }
  EXPECT_EQ(valid, 500);
  // both sweep directions together cover the whole circle
  EXPECT_LT(theta_min, -3.0);
  EXPECT_GT(theta_max, 3.0);
}

TEST(StrikeTest, SameSeedSameStrike) {
  const StrikeModel model(StrikeConfig{}, SceneConfig{}, TubeConfig{}, AudioConfig{});
  const StrikeEvents a = model.Generate(SampleSeed(9, 17)), b = model.Generate(SampleSeed(9, 17));
  const StrikeEvents c = model.Generate(SampleSeed(9, 18));
  EXPECT_EQ(a.label.z_m, b.label.z_m);
  EXPECT_EQ(a.label.theta_rad, b.label.theta_rad);
  EXPECT_TRUE(a.proprio.isApprox(b.proprio, 0.0f));
  EXPECT_NE(a.label.z_m, c.label.z_m);
}

TEST(StrikeTest, ProprioceptionIsConsistent) {
  StrikeConfig config;
  const StrikeModel model(config, SceneConfig{}, TubeConfig{}, AudioConfig{});
  const StrikeEvents ev = model.Generate(SampleSeed(3, 0));
  ASSERT_EQ(ev.proprio.rows(), config.proprio_rows);
  ASSERT_EQ(ev.proprio.cols(), kProprioFeatures);
  const double dt = 1.0 / config.proprio_rate_hz;
  for (int k = 0; k + 1 < ev.proprio.rows(); ++k) {
    // unit quaternion
    EXPECT_NEAR(ev.proprio.row(k).segment<4>(3).norm(), 1.0, 1e-5);
    // velocity agrees with the position difference to first order
    const Eigen::Vector3f dp = (ev.proprio.row(k + 1).head<3>() - ev.proprio.row(k).head<3>()) / dt;
    const Eigen::Vector3f v =
        0.5f * (ev.proprio.row(k).tail<3>() + ev.proprio.row(k + 1).tail<3>());
    EXPECT_LT((dp - v).norm(), 0.01 + 0.05 * v.norm()) << "row " << k;
  }
  // the tube moves before the contact at ~0.5 s
  EXPECT_GT(ev.proprio.row(40).tail<3>().norm(), 1e-3);
}

TEST(StrikeTest, RejectsBadConfig) {
  StrikeConfig config;
  config.home_joints_rad[3] = 0.5;  // joint 4 must stay negative
  try {
    StrikeModel model(config, SceneConfig{}, TubeConfig{}, AudioConfig{});
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("strike.home_joints_rad[3]"), std::string::npos);
  }
  config = StrikeConfig{};
  config.sweep_min_deg = 20;
  EXPECT_THROW(StrikeModel(config, SceneConfig{}, TubeConfig{}, AudioConfig{}), ConfigError);
}

}  // namespace
}  // namespace sonicboom::sim
