#pragma once
/// A compiled MuJoCo model of the Panda (see franka_mjcf.h) behind a small RAII wrapper, so that
/// no other file needs mujoco.h. The model is immutable after construction; every query works on
/// its own mjData, so a const PandaScene may be shared between threads.
/// The first PandaScene installs process-wide MuJoCo hooks where none are set: mju_user_warning
/// logs a warning; mju_user_error logs and aborts, since MuJoCo requires that it never returns and
/// an exception must not unwind through MuJoCo's C frames.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sonicboom/sim/franka.h"

// MuJoCo's model type, declared here so that this header needs no mujoco.h
struct mjModel_;

namespace sonicboom::sim {

/// One joint of the compiled model.
struct MujocoJointInfo {
  std::string name;
  bool is_hinge{false};
  bool is_limited{false};
  double lower_rad{0.0};
  double upper_rad{0.0};
};

/// Compiled Panda model. The MJCF must name hinges panda_joint1..7 and sites "flange" and
/// "tube_center"; PandaMjcf() output does.
class PandaScene {
 public:
  /// Compiles `mjcf_xml` (from memory, through a MuJoCo virtual file system). Throws ConfigError
  /// carrying MuJoCo's message (which names the line) when the model does not parse or compile,
  /// or lacks the joints and sites above.
  explicit PandaScene(const std::string& mjcf_xml);
  ~PandaScene();
  PandaScene(const PandaScene&) = delete;
  PandaScene& operator=(const PandaScene&) = delete;

  /// Number of generalized coordinates.
  int nq() const;
  /// Simulation timestep of the model, s.
  double timestep_s() const;
  /// Sum of all body masses, kg.
  double TotalMass() const;

  /// Every joint, in model order.
  std::vector<MujocoJointInfo> Joints() const;
  /// (lower, upper) position range of every joint, model order, rad.
  std::vector<std::pair<double, double>> JointRanges() const;
  /// (lower, upper) control range of every actuator, model order (N m for the Panda's motors).
  std::vector<std::pair<double, double>> ControlRanges() const;

  /// Poses of the "flange" and "tube_center" sites in the base frame for joint angles q (rad),
  /// through mj_kinematics.
  PandaPoses SitePoses(const JointVector& q) const;
  /// Joint torques that hold the arm still against gravity at q (rad), N m: MuJoCo's bias force
  /// at zero velocity.
  JointVector GravityTorques(const JointVector& q) const;
  /// Effective mass (kg) the arm at rest at q (rad) shows at a point of the flange body (tube)
  /// along a unit direction (both base frame): 1 / (n^T J M^-1 J^T n).
  double FlangeEffectiveMassKg(const JointVector& q, const Eigen::Vector3d& point_m,
                               const Eigen::Vector3d& normal) const;
  /// Number of contacts MuJoCo's collision detection finds at q (rad), at rest.
  int ContactCount(const JointVector& q) const;

  /// The compiled model, for sim .cc files that include mujoco.h and simulate on their own mjData.
  /// Read-only: the model stays immutable and shared.
  const mjModel_* model() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::sim
