#pragma once
/// Franka Emika Panda kinematics from its published Craig-convention (modified) DH parameters,
/// and the SonicBoom tube mounted on the flange (tube axis = flange z, centre offset along it).

#include <Eigen/Geometry>
#include <array>

namespace sonicboom::sim {

inline constexpr int kPandaJoints = 7;
using JointVector = Eigen::Matrix<double, kPandaJoints, 1>;  // rad

/// One Craig (modified) DH row: T = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(q_i) TransZ(d_i).
struct DhRow {
  double a_m;        // a_{i-1}
  double d_m;        // d_i
  double alpha_rad;  // alpha_{i-1}
};
/// The Panda's published DH rows: joints 1-7, then the fixed flange row (q = 0).
const std::array<DhRow, kPandaJoints + 1>& PandaDhRows();

/// Published joint position limits, rad.
JointVector PandaLowerLimits();
JointVector PandaUpperLimits();

/// Poses in the robot base frame.
struct PandaPoses {
  Eigen::Isometry3d flange{Eigen::Isometry3d::Identity()};
  Eigen::Isometry3d tube{Eigen::Isometry3d::Identity()};  // tube frame: centre, axis = +z
};

/// Forward kinematics: joint angles (rad) -> flange and tube-centre poses.
PandaPoses PandaForwardKinematics(const JointVector& q, double tube_center_from_flange_m);

/// Joint i's frame (i = 1..7) and the flange (i = 8), for tests against other implementations.
Eigen::Isometry3d PandaLinkPose(const JointVector& q, int frame);

}  // namespace sonicboom::sim
