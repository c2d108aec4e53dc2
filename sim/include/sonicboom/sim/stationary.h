#pragma once
/// Stationary robot, hand-held striker (scene.mode stationary; the paper's human-strike test):
/// the arm holds the home pose (strike.home_joints_rad) and is not integrated; a free striker
/// (scene.objects of kind striker: a wooden rod, an aluminium rod or a PVC pipe) hits a commanded
/// point on the tube at a random speed. Only the striker's six degrees of freedom are simulated,
/// against the tube as a fixed body.
///
/// The commanded point: z uniform in the contact region, snapped to scene.stationary.z_grid_m
/// (the paper marked the tube every 2 cm), theta uniform. The striker crosses the tube at 90
/// degrees, tangent to the surface there, its free tip tip_margin_m beyond the point; it moves
/// towards the tube along a direction up to approach_spread_deg off the inward normal, at the
/// drawn speed, and reaches the surface at the drawn onset. The hand holding its grip end is a
/// spring (hand_stiffness_n_m, hand_damping_ratio, and the matching rotational spring) to a hand
/// target that moves on at that speed until it is follow_through_m inside the surface, then
/// stops: the striker bounces, or stays pressed.
///
/// Contacts are recorded as in rollout.h; the effective mass is the striker's (rigid body, at the
/// contact point) in series with the held arm's at the tube point. Proprioception: the held pose
/// at zero velocity.

#include <cstdint>
#include <memory>
#include <vector>

#include "sonicboom/core/tube.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {

/// Immutable model: one compiled striker scene per striker object; Run is const and
/// thread-safe.
class HandStrikeRollout {
 public:
  /// Throws ConfigError on an invalid config, or where scene.mode is not stationary.
  HandStrikeRollout(const TubeConfig& tube, const AudioConfig& audio, const StrikeConfig& strike,
                    const SceneConfig& scene, const RolloutConfig& rollout);
  ~HandStrikeRollout();
  HandStrikeRollout(const HandStrikeRollout&) = delete;
  HandStrikeRollout& operator=(const HandStrikeRollout&) = delete;

  /// One hand strike from its sample seed (deterministic); never throws (see StrikeRollout::Run).
  RolloutResult Run(uint64_t sample_index, uint64_t sample_seed) const;
  double timestep_s() const { return timestep_s_; }

 private:
  struct Striker;
  TubeConfig tube_;
  AudioConfig audio_;
  StrikeConfig strike_;
  SceneConfig scene_;
  RolloutConfig config_;
  double timestep_s_{0.0};
  JointVector q_home_{JointVector::Zero()};                     // held pose, rad
  Eigen::Isometry3d tube_pose_{Eigen::Isometry3d::Identity()};  // held tube frame, base frame
  Eigen::Matrix<float, 1, 10> held_row_;                        // its proprioception row
  std::vector<std::unique_ptr<Striker>> strikers_;              // [object]
  std::unique_ptr<class PandaScene> arm_;                       // for the arm's effective mass
};

}  // namespace sonicboom::sim
