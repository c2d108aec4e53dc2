// The generated MuJoCo Panda against the DH forward kinematics, and the model's limits and masses.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <numbers>
#include <string>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/franka_mjcf.h"
#include "sonicboom/sim/mujoco_scene.h"

namespace sonicboom::sim {
namespace {

JointVector HomeJoints() {
  JointVector q;
  q << 1.2614, -0.8973, -0.0474, -2.3464, -0.0790, 1.4341, -1.7109;
  return q;
}

// gravitational potential energy (J) of the links (Gaz et al. 2019 masses and centres of mass,
// link frames) and of a 1400 kg/m^3 PVC tube, through the DH chain
double PotentialEnergyJ(const JointVector& q, const TubeConfig& tube) {
  const std::array<double, 7> mass_kg = {4.970684, 0.646926, 3.228604, 3.587895,
                                         1.225946, 1.666555, 0.735522};
  const std::array<Eigen::Vector3d, 7> com_m = {Eigen::Vector3d(0.003875, 0.002081, -0.04762),
                                                Eigen::Vector3d(-0.003141, -0.02872, 0.003495),
                                                Eigen::Vector3d(0.027518, 0.039252, -0.066502),
                                                Eigen::Vector3d(-0.05317, 0.104419, 0.027454),
                                                Eigen::Vector3d(-0.011953, 0.041065, -0.038437),
                                                Eigen::Vector3d(0.060149, -0.014117, -0.010517),
                                                Eigen::Vector3d(0.010517, -0.004252, 0.061597)};
  constexpr double kG = 9.81;
  double energy_j = 0.0;
  for (int k = 0; k < kPandaJoints; ++k) {
    energy_j += mass_kg[k] * kG * (PandaLinkPose(q, k + 1) * com_m[k]).z();
  }
  const double r_in_m = tube.outer_radius_m - tube.wall_thickness_m;
  const double tube_mass_kg = 1400.0 * std::numbers::pi *
                              (tube.outer_radius_m * tube.outer_radius_m - r_in_m * r_in_m) *
                              tube.length_m;
  energy_j += tube_mass_kg * kG *
              PandaForwardKinematics(q, tube.center_from_flange_m).tube.translation().z();
  return energy_j;
}

JointVector PotentialGradient(const JointVector& q, const TubeConfig& tube) {
  constexpr double kStepRad = 1e-6;
  JointVector gradient;
  for (int i = 0; i < kPandaJoints; ++i) {
    JointVector plus = q, minus = q;
    plus[i] += kStepRad;
    minus[i] -= kStepRad;
    gradient[i] = (PotentialEnergyJ(plus, tube) - PotentialEnergyJ(minus, tube)) / (2 * kStepRad);
  }
  return gradient;
}

// one compiled default model shared by the tests of this file
const PandaScene& DefaultScene() {
  static const PandaScene scene(PandaMjcf(TubeConfig{}));
  return scene;
}

TEST(MujocoFkTest, SitesMatchDhForwardKinematics) {
  const TubeConfig tube;
  const PandaScene& scene = DefaultScene();
  ASSERT_EQ(scene.nq(), kPandaJoints);
  Rng rng(20240611);
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  double max_position_error_m = 0.0, max_rotation_error = 0.0;
  for (int trial = 0; trial < 500; ++trial) {
    JointVector q;
    for (int i = 0; i < kPandaJoints; ++i) q[i] = rng.Uniform(lo[i], hi[i]);
    const PandaPoses dh = PandaForwardKinematics(q, tube.center_from_flange_m);
    const PandaPoses mj = scene.SitePoses(q);
    // positions (m) and rotation matrices (element-wise) of both frames
    const std::array<std::pair<const Eigen::Isometry3d*, const Eigen::Isometry3d*>, 2> frames = {
        {{&dh.flange, &mj.flange}, {&dh.tube, &mj.tube}}};
    for (const auto& [ref, got] : frames) {
      max_position_error_m =
          std::max(max_position_error_m, (ref->translation() - got->translation()).norm());
      max_rotation_error =
          std::max(max_rotation_error, (ref->linear() - got->linear()).cwiseAbs().maxCoeff());
    }
  }
  std::cout << "max FK discrepancy over 500 configurations: position " << max_position_error_m
            << " m, rotation matrix element " << max_rotation_error << "\n";
  EXPECT_LT(max_position_error_m, 1e-6);
  EXPECT_LT(max_rotation_error, 1e-6);
}

TEST(MujocoFkTest, TubeSiteFollowsTheConfiguredOffset) {
  // a different offset moves the tube site, not the flange
  TubeConfig tube;
  tube.center_from_flange_m = 0.2;
  const PandaScene scene(PandaMjcf(tube));
  const JointVector q = HomeJoints();
  const PandaPoses dh = PandaForwardKinematics(q, 0.2);
  const PandaPoses mj = scene.SitePoses(q);
  EXPECT_LT((dh.tube.translation() - mj.tube.translation()).norm(), 1e-9);
  EXPECT_LT((dh.flange.translation() - mj.flange.translation()).norm(), 1e-9);
  EXPECT_NEAR((mj.tube.translation() - mj.flange.translation()).norm(), 0.2, 1e-9);
}

TEST(MujocoFkTest, MalformedMjcfThrowsConfigErrorWithMujocosMessage) {
  try {
    PandaScene scene("<mujoco><worldbody><body>");
    FAIL() << "a truncated MJCF compiled";
  } catch (const ConfigError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("MuJoCo could not load"), std::string::npos) << message;
    // MuJoCo's own parser text, which names the line
    EXPECT_NE(message.find("XML parse error"), std::string::npos) << message;
    EXPECT_NE(message.find("Line number=1"), std::string::npos) << message;
  }
}

TEST(MujocoFkTest, ModelWithoutPandaJointsThrowsConfigError) {
  const std::string no_panda =
      "<mujoco><worldbody><body><geom size=\"0.1\"/></body></worldbody></mujoco>";
  EXPECT_THROW(PandaScene{no_panda}, ConfigError);
}

TEST(MujocoFkTest, SevenHingesWithThePublishedLimits) {
  const PandaScene& scene = DefaultScene();
  const std::vector<MujocoJointInfo> joints = scene.Joints();
  const std::vector<std::pair<double, double>> ranges = scene.JointRanges();
  ASSERT_EQ(joints.size(), 7u);
  ASSERT_EQ(ranges.size(), 7u);
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int i = 0; i < kPandaJoints; ++i) {
    EXPECT_EQ(joints[i].name, "panda_joint" + std::to_string(i + 1));
    EXPECT_TRUE(joints[i].is_hinge) << i;
    EXPECT_TRUE(joints[i].is_limited) << i;
    EXPECT_DOUBLE_EQ(ranges[i].first, lo[i]) << i;
    EXPECT_DOUBLE_EQ(ranges[i].second, hi[i]) << i;
  }
}

TEST(MujocoFkTest, MotorsHaveThePublishedTorqueLimits) {
  const std::array<double, 7> limits_nm = {87, 87, 87, 87, 12, 12, 12};
  const std::vector<std::pair<double, double>> ranges = DefaultScene().ControlRanges();
  ASSERT_EQ(ranges.size(), 7u);
  for (int i = 0; i < kPandaJoints; ++i) {
    EXPECT_DOUBLE_EQ(ranges[i].first, -limits_nm[i]) << i;
    EXPECT_DOUBLE_EQ(ranges[i].second, limits_nm[i]) << i;
  }
}

TEST(MujocoFkTest, TimestepIsWrittenAndValidated) {
  PandaMjcfOptions options;
  options.timestep_s = 0.0005;
  EXPECT_DOUBLE_EQ(PandaScene(PandaMjcf(TubeConfig{}, options)).timestep_s(), 0.0005);
  EXPECT_DOUBLE_EQ(DefaultScene().timestep_s(), 0.001);
  options.timestep_s = 0.0;
  EXPECT_THROW(PandaMjcf(TubeConfig{}, options), ConfigError);
}

TEST(MujocoFkTest, GravityCompensationAtHome) {
  const PandaScene& scene = DefaultScene();
  // Gaz et al. link masses sum to 16.06 kg; the model adds the ~0.42 kg PVC tube
  const double published_sum_kg =
      4.970684 + 0.646926 + 3.228604 + 3.587895 + 1.225946 + 1.666555 + 0.735522;
  EXPECT_NEAR(PandaLinkMassSumKg(), published_sum_kg, 1e-9);
  EXPECT_NEAR(scene.TotalMass(), published_sum_kg, 0.1 * published_sum_kg);
  EXPECT_GT(scene.TotalMass(), published_sum_kg);  // the tube has mass

  const JointVector q = HomeJoints();
  const JointVector tau_nm = scene.GravityTorques(q);
  std::cout << "gravity torques at home (N m): " << tau_nm.transpose() << "\n";
  // holding torque = gradient of the potential energy, from the DH chain and the published
  // centres of mass, by central differences
  const JointVector tau_ref_nm = PotentialGradient(q, TubeConfig{});
  for (int i = 0; i < kPandaJoints; ++i) EXPECT_NEAR(tau_nm[i], tau_ref_nm[i], 1e-4) << i;
  // joint 1 turns about the vertical: gravity exerts no torque on it
  EXPECT_NEAR(tau_nm[0], 0.0, 1e-9);
  // the elbow carries the forearm: several N m; every joint within its motor's limit
  EXPECT_GT(std::abs(tau_nm[3]), 5.0);
  const std::array<double, 7> limits_nm = {87, 87, 87, 87, 12, 12, 12};
  for (int i = 0; i < kPandaJoints; ++i) EXPECT_LT(std::abs(tau_nm[i]), limits_nm[i]) << i;
}

TEST(MujocoFkTest, ObjectContactsOnlyPairsEachObjectGeomWithTheTubeAndEveryCapsule) {
  PandaMjcfOptions options;
  // a rod and a cross (two segments)
  ObjectConfig cross;
  cross.kind = ObjectKind::kCross;
  options.objects.resize(2);
  options.objects[0].segments = BuildObjectGeometry(ObjectConfig{}, 0).segments;
  options.objects[1].segments = BuildObjectGeometry(cross, 0).segments;
  options.object_contacts_only = true;
  const std::string xml = PandaMjcf(TubeConfig{}, options);
  EXPECT_NE(xml.find("collision=\"predefined\""), std::string::npos);
  // 3 object geoms x (tube + 11 capsules)
  size_t pairs = 0;
  for (size_t at = xml.find("<pair "); at != std::string::npos; at = xml.find("<pair ", at + 1)) {
    ++pairs;
  }
  EXPECT_EQ(pairs, 36u);
  EXPECT_NE(xml.find("<pair geom1=\"tube\" geom2=\"object1_1\""), std::string::npos);
  EXPECT_NE(xml.find("<pair geom1=\"panda_link7_collision0\" geom2=\"object0_0\""),
            std::string::npos);
  // it compiles, and the parked rods touch nothing
  const PandaScene scene(xml);
  EXPECT_EQ(scene.ContactCount(HomeJoints()), 0);
  // the default model detects all contacts dynamically
  EXPECT_EQ(PandaMjcf(TubeConfig{}).find("<pair "), std::string::npos);
}

TEST(MujocoFkTest, NoContactsAtHome) {
  EXPECT_EQ(DefaultScene().ContactCount(HomeJoints()), 0);
}

}  // namespace
}  // namespace sonicboom::sim
