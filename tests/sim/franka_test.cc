// Panda forward kinematics against the closed-form modified-DH matrix and known poses.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "sonicboom/core/rng.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::sim {
namespace {

// Craig's link matrix written out element by element (independent of the Eigen composition)
Eigen::Matrix4d CraigMatrix(double a, double d, double alpha, double theta) {
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  Eigen::Matrix4d t;
  t << ct, -st, 0, a,
      st * ca, ct * ca, -sa, -d * sa,
      st * sa, ct * sa, ca, d * ca,
      0, 0, 0, 1;
  return t;
}

Eigen::Matrix4d ReferenceFlange(const JointVector& q) {
  const double pi = std::numbers::pi;
  const double a[8] = {0, 0, 0, 0.0825, -0.0825, 0, 0.088, 0};
  const double d[8] = {0.333, 0, 0.316, 0, 0.384, 0, 0, 0.107};
  const double alpha[8] = {0, -pi / 2, pi / 2, pi / 2, -pi / 2, pi / 2, pi / 2, 0};
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  for (int i = 0; i < 8; ++i) t = t * CraigMatrix(a[i], d[i], alpha[i], i < 7 ? q[i] : 0.0);
  return t;
}

TEST(FrankaTest, ZeroConfigurationFlangePose) {
  // all joints zero: flange 0.088 m forward, 0.926 m up, pointing down
  const PandaPoses poses = PandaForwardKinematics(JointVector::Zero(), 0.155);
  EXPECT_NEAR(poses.flange.translation().x(), 0.088, 1e-12);
  EXPECT_NEAR(poses.flange.translation().y(), 0.0, 1e-12);
  EXPECT_NEAR(poses.flange.translation().z(), 0.926, 1e-12);
  EXPECT_NEAR(poses.flange.linear()(2, 2), -1.0, 1e-12);
  // tube centre 0.155 m further along the flange z axis (downwards here)
  EXPECT_NEAR(poses.tube.translation().z(), 0.926 - 0.155, 1e-12);
  EXPECT_TRUE(poses.tube.linear().isApprox(poses.flange.linear()));
}

TEST(FrankaTest, MatchesCraigMatricesOnRandomConfigurations) {
  Rng rng(123);
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int trial = 0; trial < 200; ++trial) {
    JointVector q;
    for (int i = 0; i < kPandaJoints; ++i) q[i] = rng.Uniform(lo[i], hi[i]);
    const Eigen::Matrix4d ref = ReferenceFlange(q);
    const PandaPoses poses = PandaForwardKinematics(q, 0.155);
    EXPECT_LT((poses.flange.matrix() - ref).cwiseAbs().maxCoeff(), 1e-12);
    const Eigen::Vector3d tube_ref = ref.block<3, 1>(0, 3) + 0.155 * ref.block<3, 1>(0, 2);
    EXPECT_LT((poses.tube.translation() - tube_ref).norm(), 1e-12);
  }
}

TEST(FrankaTest, LimitsAreOrdered) {
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int i = 0; i < kPandaJoints; ++i) EXPECT_LT(lo[i], hi[i]);
}

}  // namespace
}  // namespace sonicboom::sim
