#pragma once
/// The parts of StrikeRollout (rollout.h) that its set-up (rollout.cc) and its simulation
/// (rollout_simulate.cc) share: the compiled scene of one object geometry, the plan of one strike,
/// and the stepping constants. Private to the sim module (includes mujoco.h).

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "internal/mujoco_util.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/mujoco_scene.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/scene.h"

namespace sonicboom::sim {
namespace internal {

// An episode ends after this many steps without contact: under friction MuJoCo's soft contact
// between the pressed tube and an object flickers off for single steps (with friction 0 it does
// not), which would otherwise count as bounces
constexpr int64_t kReleaseSteps = 2;
// Free flight (no object pair can touch) steps k timesteps at once, k <= kMaxFreeStepMultiple,
// with omega_max k dt <= kFreeStepOmegaDt for the stiffest joint's natural frequency
// omega_max = max_i sqrt(K_i / M_ii) (explicit impedance torques stay well inside stability)
constexpr int kMaxFreeStepMultiple = 4;
constexpr double kFreeStepOmegaDt = 0.75;
// A steady press (no episode opened or closed for kSteadyPressS) steps
// rollout.press_step_multiple timesteps at once (at most the free-flight multiple, for the arm)
constexpr double kSteadyPressS = 0.05;
// a step skips collision detection when every object pair is this much farther apart than it
// can close in one step, m
constexpr double kCollisionSkipSlackM = 0.001;

/// Surface distance lower bound of two capsule or cylinder geoms at their poses in d: their axis
/// segments' distance less both radii (a cylinder lies inside the capsule of its radius), m.
double GeomGapLowerBound(const mjModel* m, const mjData* d, int g1, int g2);

/// Modal mass (kg) of an object segment's fundamental mode seen at object-frame point p: the
/// segment as a beam clamped at its base end (both ends for a both-ends-clamped rod or cross).
double SegmentModalMassKg(const ObjectConfig& object, const ObjectSegment& seg,
                          const Eigen::Vector3d& p_object);

}  // namespace internal

// One compiled scene: the Panda, the tube and one object geometry, with indices into it.
struct StrikeRollout::Variant {
  int object{0};
  int64_t variant{0};
  std::string name;         // recorded with every contact
  ObjectGeometry geometry;  // object frame
  std::unique_ptr<PandaScene> scene;
  std::array<int, kPandaJoints> qpos{};      // qpos index of panda_joint1..7
  std::array<int, kPandaJoints> dof{};       // dof index of panda_joint1..7
  std::array<int, kPandaJoints> actuator{};  // panda_motor1..7
  int tube_geom{-1};
  int object_mocap{-1};  // index into mjData's mocap arrays
  int flange_body{-1};   // body carrying the tube
  int tube_site{-1};
  std::vector<int> segment_of_geom;  // (ngeom) object segment of a geom, -1 otherwise
  // The scene with contacts disabled, stepped instead where no object pair can touch: its steps
  // equal the full model's whenever collision detection would find no contact. Twin k - 1 steps
  // k timesteps at once (free flight needs only the arm's own time scale, see Simulate).
  std::vector<internal::ModelPtr> contact_free;
  // The scene with the tube-object pairs only, stepped where the arm cannot touch the object:
  // its steps equal the full model's whenever no arm pair would find a contact.
  internal::ModelPtr tube_only;
  // The full and tube-only scenes stepping press_multiple timesteps at once, for a steady press
  internal::ModelPtr press, press_tube_only;
  int press_multiple{1};
  std::vector<std::array<int, 2>> tube_pairs;  // geoms of the tube-object pairs
  std::vector<std::array<int, 2>> arm_pairs;   // geoms of the arm-object pairs
  double reach_m{0.0};  // bound on any geom point's distance to any joint axis
};

// What one rollout does: start, goal and timing of the joint path, gains, object pose, target.
struct StrikeRollout::Plan {
  JointVector q_start{JointVector::Zero()};      // rad
  JointVector q_goal{JointVector::Zero()};       // rad
  double t_start_s{0.0};                         // path start, audio clock
  double duration_s{1.0};                        // path duration
  std::array<double, kPandaJoints> stiffness{};  // N m / rad
  Eigen::Isometry3d object_pose{Eigen::Isometry3d::Identity()};
  std::string motion;
  double target_z_m{0.0};
  double target_theta_rad{0.0};
  double target_time_s{0.0};
  bool timed{false};  // start earlier by the swept joint's lag D/K
  int swept_joint{0};
  double s_contact{0.0};  // path fraction (normalised time) at the target
  std::string invalid_reason;
};

}  // namespace sonicboom::sim
