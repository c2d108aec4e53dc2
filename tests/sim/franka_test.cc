// Panda forward kinematics against the closed-form modified-DH matrix and known poses;
// the tube Jacobian against finite differences and the inverse kinematics against the FK.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>

#include "sonicboom/core/rng.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::sim {
namespace {

// Craig's link matrix written out element by element (independent of the Eigen composition)
Eigen::Matrix4d CraigMatrix(double a, double d, double alpha, double theta) {
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha),
               sa = std::sin(alpha);
  Eigen::Matrix4d t;
  t << ct, -st, 0, a, st * ca, ct * ca, -sa, -d * sa, st * sa, ct * sa, ca, d * ca, 0, 0, 0, 1;
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

JointVector HomeJoints() {
  JointVector q;
  q << 1.2614, -0.8973, -0.0474, -2.3464, -0.0790, 1.4341, -1.7109;
  return q;
}

JointVector RandomJoints(Rng& rng) {
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  JointVector q;
  for (int i = 0; i < kPandaJoints; ++i) q[i] = rng.Uniform(lo[i], hi[i]);
  return q;
}

bool WithinLimits(const JointVector& q) {
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  return q.allFinite() && (q.array() >= lo.array()).all() && (q.array() <= hi.array()).all();
}

// the IK's reported errors must be the ones of the FK at the returned joints
void ExpectErrorsMatchFk(const IkResult& ik, const Eigen::Isometry3d& target, double offset_m) {
  const Eigen::Isometry3d tube = PandaForwardKinematics(ik.q, offset_m).tube;
  EXPECT_NEAR((tube.translation() - target.translation()).norm(), ik.position_error_m, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(tube.linear().transpose() * target.linear()).angle(),
              ik.rotation_error_rad, 1e-9);
}

TEST(FrankaTest, TubeJacobianMatchesFiniteDifferences) {
  constexpr double kOffsetM = 0.155, kStepRad = 1e-6;
  Rng rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const JointVector q = trial == 0 ? HomeJoints() : RandomJoints(rng);
    const Eigen::Matrix<double, 6, kPandaJoints> jacobian = PandaTubeJacobian(q, kOffsetM);
    for (int i = 0; i < kPandaJoints; ++i) {
      JointVector plus = q, minus = q;
      plus[i] += kStepRad;
      minus[i] -= kStepRad;
      const Eigen::Isometry3d tp = PandaForwardKinematics(plus, kOffsetM).tube;
      const Eigen::Isometry3d tm = PandaForwardKinematics(minus, kOffsetM).tube;
      const Eigen::Vector3d linear = (tp.translation() - tm.translation()) / (2 * kStepRad);
      // angular velocity: rotation vector of R(q + h) R(q - h)^T over 2h, base frame
      const Eigen::AngleAxisd delta(tp.linear() * tm.linear().transpose());
      const Eigen::Vector3d angular = delta.angle() * delta.axis() / (2 * kStepRad);
      EXPECT_LT((jacobian.col(i).head<3>() - linear).norm(), 1e-6) << trial << " joint " << i;
      EXPECT_LT((jacobian.col(i).tail<3>() - angular).norm(), 1e-6) << trial << " joint " << i;
    }
  }
}

TEST(FrankaTest, InverseKinematicsRecoversRandomReachablePoses) {
  constexpr double kOffsetM = 0.155;
  constexpr int kCases = 200;
  Rng rng(2024);
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  int converged = 0;
  double total_s = 0.0;
  for (int trial = 0; trial < kCases; ++trial) {
    const JointVector q_true = RandomJoints(rng);
    const Eigen::Isometry3d target = PandaForwardKinematics(q_true, kOffsetM).tube;
    JointVector seed;
    for (int i = 0; i < kPandaJoints; ++i) {
      seed[i] = std::clamp(q_true[i] + rng.Uniform(-0.2, 0.2), lo[i], hi[i]);
    }
    const auto start = std::chrono::steady_clock::now();
    const IkResult ik = PandaInverseKinematics(target, seed, kOffsetM);
    total_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(WithinLimits(ik.q)) << "trial " << trial;
    EXPECT_LE(ik.iterations, 200);
    ExpectErrorsMatchFk(ik, target, kOffsetM);
    if (ik.converged) {
      ++converged;
      EXPECT_LT(ik.position_error_m, 1e-5);
      EXPECT_LT(ik.rotation_error_rad, 1e-4);
    }
  }
  std::cout << "[ info     ] IK random reachable poses: " << converged << "/" << kCases
            << " converged, " << 1e6 * total_s / kCases << " us per solve\n";
  EXPECT_GE(converged, 190);  // >= 95 %
}

TEST(FrankaTest, InverseKinematicsIsDeterministic) {
  const Eigen::Isometry3d target = PandaForwardKinematics(HomeJoints(), 0.155).tube;
  JointVector seed = HomeJoints();
  seed.array() += 0.15;
  const IkResult a = PandaInverseKinematics(target, seed, 0.155);
  const IkResult b = PandaInverseKinematics(target, seed, 0.155);
  EXPECT_TRUE(a.converged);
  EXPECT_EQ(a.q, b.q);
  EXPECT_EQ(a.iterations, b.iterations);
}

TEST(FrankaTest, InverseKinematicsReportsUnreachableTargets) {
  constexpr double kOffsetM = 0.155;
  // 2 m from the base: beyond the Panda's ~0.855 m reach plus the tube
  Eigen::Isometry3d target = PandaForwardKinematics(HomeJoints(), kOffsetM).tube;
  target.translation() = Eigen::Vector3d(2.0, 0.0, 0.333);
  IkResult ik;
  EXPECT_NO_THROW(ik = PandaInverseKinematics(target, HomeJoints(), kOffsetM));
  EXPECT_FALSE(ik.converged);
  EXPECT_TRUE(WithinLimits(ik.q));
  EXPECT_TRUE(std::isfinite(ik.position_error_m));
  EXPECT_GT(ik.position_error_m, 0.5);
  EXPECT_LE(ik.iterations, 200);
  ExpectErrorsMatchFk(ik, target, kOffsetM);
  // a non-finite target or seed does not throw either
  Eigen::Isometry3d bad = target;
  bad.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NO_THROW(ik = PandaInverseKinematics(bad, HomeJoints(), kOffsetM));
  EXPECT_FALSE(ik.converged);
  EXPECT_TRUE(WithinLimits(ik.q));
  JointVector bad_seed = HomeJoints();
  bad_seed[2] = std::numeric_limits<double>::infinity();
  EXPECT_NO_THROW(ik = PandaInverseKinematics(target, bad_seed, kOffsetM));
  EXPECT_TRUE(WithinLimits(ik.q));
}

// guided sampling: the tube centre on the recording plane z = 0.315 m, in the home orientation
TEST(FrankaTest, InverseKinematicsReachesTheRecordingGridFromHome) {
  const double offset_m = TubeConfig{}.center_from_flange_m;
  const Eigen::Isometry3d home = PandaForwardKinematics(HomeJoints(), offset_m).tube;
  constexpr int kNx = 9, kNy = 8;
  int converged = 0;
  double total_s = 0.0;
  for (int ix = 0; ix < kNx; ++ix) {
    for (int iy = 0; iy < kNy; ++iy) {
      Eigen::Isometry3d target = home;
      target.translation() =
          Eigen::Vector3d(-0.22 + 0.44 * ix / (kNx - 1), 0.20 + 0.35 * iy / (kNy - 1), 0.315);
      const auto start = std::chrono::steady_clock::now();
      const IkResult ik = PandaInverseKinematics(target, HomeJoints(), offset_m);
      total_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      EXPECT_TRUE(WithinLimits(ik.q));
      ExpectErrorsMatchFk(ik, target, offset_m);
      if (ik.converged) {
        ++converged;
      } else {
        std::cout << "[ info     ] IK not converged at " << target.translation().transpose() << ": "
                  << ik.position_error_m << " m, " << ik.rotation_error_rad << " rad\n";
      }
    }
  }
  std::cout << "[ info     ] IK recording grid from home: " << converged << "/" << kNx * kNy
            << " converged, " << 1e6 * total_s / (kNx * kNy) << " us per solve\n";
  EXPECT_GE(converged, kNx * kNy * 9 / 10);
}

}  // namespace
}  // namespace sonicboom::sim
