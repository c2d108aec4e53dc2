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

/// Geometric Jacobian of the tube frame (6 x 7, base frame): rows 0-2 map joint rates (rad/s)
/// to the linear velocity of the tube-frame origin (m/s), rows 3-5 to the angular velocity of
/// the tube frame (rad/s). Built from the joint axes z_i and origins o_i of the DH chain:
/// column i = [z_i x (p_tube - o_i); z_i]. tube_center_from_flange_m is in m.
Eigen::Matrix<double, 6, kPandaJoints> PandaTubeJacobian(const JointVector& q,
                                                         double tube_center_from_flange_m);

/// Result of an inverse-kinematics solve.
struct IkResult {
  bool converged{false};
  JointVector q{JointVector::Zero()};  // rad, within the joint limits
  double position_error_m{0.0};        // |p_tube(q) - p_target| at the end, m
  double rotation_error_rad{0.0};      // angle of R(q)^T R_target at the end, rad
  int iterations{0};                   // iterations used (accepted and rejected steps)
};

/// Joint angles (rad) that put the tube frame at `target` (base frame, m), starting from
/// q_seed (rad; clamped into the limits, non-finite entries replaced by the limits' midpoint):
/// Levenberg-Marquardt damped least squares on the 6-D pose error (position in m, rotation as
/// the base-frame rotation vector in rad) with the geometric Jacobian of the DH chain, adaptive
/// damping (a step is accepted only if it lowers the error), a per-iteration step limit, joint
/// limits enforced by clamping (joints pushed onto a limit leave the step's active set), and a
/// null-space pull towards q_seed. Converged means position error < tol_m (m) and rotation
/// error < tol_rad (rad). Deterministic; never throws: an unreachable or non-finite target
/// gives converged = false with the best q found (finite, within the limits).
IkResult PandaInverseKinematics(const Eigen::Isometry3d& target, const JointVector& q_seed,
                                double tube_center_from_flange_m, double tol_m = 1e-5,
                                double tol_rad = 1e-4, int max_iterations = 200);

}  // namespace sonicboom::sim
