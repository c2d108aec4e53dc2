#pragma once
/// Dynamic strikes in MuJoCo with the arm (scene.mode strike and guided, scene.h). A joint-space
/// impedance controller drives the arm along a minimum-jerk joint path; the tube meets a fixed
/// object (a mocap body of cylinders: a rod, a cross or a branch structure); every tube contact
/// (touch, release, impulse, approach speed, effective mass) comes from MuJoCo.
///
/// Mode strike (docs/reference.md, "The reference strike motion", and its variants). The strike is
/// drawn by DrawStrike (strike.h), the same draws as the kinematic engine. At the kinematic
/// contact configuration q_c (the swept joint turned by sweep * MinJerk(contact_fraction) from
/// q0) the tube pose T comes from the DH forward kinematics. The intended contact (z, theta) has
/// theta = direction of motion of the tube axis point at z (about the axis) + the drawn angle
/// offset. With n = T (cos theta, sin theta, 0) the outward normal and a = T z the tube axis, the
/// target segment's axis is placed along a x n: it crosses the tube at 90 degrees, tangent to the
/// surface at (z, theta), (its radius + 1 mm) beyond the surface point along n, so the tube,
/// moving towards it, first touches it at (z, theta) about 1 mm of travel after q_c. The rest of
/// the object lies behind (along n; a cross's second rod, a branch's centroid), and its clamped
/// end or trunk points away from the joint-1 axis. A one-end-clamped rod is struck 5 cm from its
/// free tip, a both-ends-clamped rod, a cross or a branch segment in its middle 60 %.
///
/// Mode guided: the first object stands at scene.guided's pose; the tube starts at candidate
/// points (inverse kinematics, fixed orientation) and taps along joint 1 or 6.
///
/// Control (at every step, between mj_step1 and mj_step2):
///   tau = K (q_des(t) - q) - D qdot + qfrc_bias, clamped to the motor ranges,
/// with D_ii = 2 damping_ratio sqrt(K_i M_ii(q0)), K = stiffness_nm_rad (lateral_stiffness_nm_rad
/// for joint-6 motions). q_des follows a minimum-jerk path over strike.sweep_duration_s from q0
/// to the goal (travel to the object + sweep_overshoot_deg). In mode strike the path is timed so
/// that q_des reaches the object at the drawn onset, started earlier by the impedance's
/// low-frequency lag D/K of the swept joint, so that the arm itself arrives near the onset.
///
/// Leaves (foliage spheres of a branch structure) do not collide: a tube passing through one
/// records a brush episode (no localized hard contact, no force), which acoustics plays as noise.
///
/// Cost. Collision detection tests only object pairs (tube and every arm capsule against each
/// object geom; no self-collision), and a step skips it where a conservative bound (axis-segment
/// distances, minus the most the arm can have moved since they were taken) shows no pair can
/// touch; the simulation starts at the motion start, the arm holding q0 at rest before it, and
/// ends settle_s after the first contact (or after the motion without one). None of these
/// changes a result. A steady press after the impact steps rollout.press_step_multiple timesteps
/// at once: first contacts, labels, episode kinds and durations are unchanged and impulses move by
/// < 0.1 %, but the press's friction flicker re-contacts harder (its peak force rises).
///
/// Contact durations follow MuJoCo's soft contact (contact_timeconst_s, ms), longer than the Hertz
/// contact of wood on PVC (0.2-0.6 ms, docs/physics.md, "Hertz impact"): use the impulse, approach
/// speed and effective mass of a ContactRecord with a Hertz model for the sound, not its duration.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/rollout_result.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {

/// How a rollout steps MuJoCo. fast: every shortcut (collision detection skipped where no pair
/// can touch, the tube-only model where no arm pair can, free flight at k timesteps a step, a
/// steady press at press_step_multiple); exact: only the shortcuts that change no result
/// (collision skipping, the tube-only model), every step one timestep; plain: the full model,
/// collision detection at every step of one timestep (the reference the others are tested on).
enum class StepScheduler { kFast, kExact, kPlain };
inline constexpr EnumName<StepScheduler> kStepSchedulerNames[] = {
    {StepScheduler::kFast, "fast"}, {StepScheduler::kExact, "exact"}, {StepScheduler::kPlain, "plain"}};
inline std::span<const EnumName<StepScheduler>> EnumNames(StepScheduler) {
  return kStepSchedulerNames;
}

/// Settings of the dynamic rollout (keys under "rollout").
struct RolloutConfig {
  double timestep_s{0.0};             // 0 = derived: contact_timeconst_s / 4
  double contact_timeconst_s{0.002};  // solref time constant of object contacts, >= 2 timesteps
  double contact_dampratio{1.0};      // solref damping ratio of object contacts
  double contact_friction{0.4};       // sliding friction of object contacts (wood on PVC)
  std::vector<double> stiffness_nm_rad{1000, 1000, 1000, 4000, 1000, 1000, 4000};          // (7)
  std::vector<double> lateral_stiffness_nm_rad{4000, 4000, 4000, 4000, 4000, 1000, 4000};  // (7)
  double damping_ratio{1.0};          // joint damping = 2 ratio sqrt(K M_ii), M at the start
  double sweep_overshoot_deg{4.0};    // joint-1 goal this far beyond the contact angle
  double penetration_limit_m{0.001};  // a deeper object contact makes the sample invalid
  double settle_s{0.3};               // simulate this long after the first contact (or the motion)
  // a steady press (no contact episode opened or closed for 50 ms) steps this many timesteps at
  // once; 1 = every step at timestep_s; 0 = derived: the largest of 1 and 2 that the contact
  // allows. Needs contact_timeconst_s >= 2 x multiple x timestep (MuJoCo's 2-step limit)
  int64_t press_step_multiple{0};
  StepScheduler stepping{StepScheduler::kFast};

  int64_t ResolvedPressStepMultiple() const;

  void Serialize(Archive* a);
  /// Cross-field checks; throws ConfigError naming the key and the limit.
  void Validate() const;
  /// The timestep in use, s: timestep_s, or contact_timeconst_s / 4 where timestep_s is 0.
  double ResolvedTimestep() const;
};

/// A first contact of a rollout, as the acoustics stage plays it and the dataset labels it: the
/// first hard (non-brush) contact, with the object's contact properties; false where there is
/// none.
bool FirstHardContact(const RolloutResult& result, const SceneConfig& scene, ContactEvent* event,
                      ContactLabel* label);

/// Immutable rollout model: one compiled MuJoCo scene (the Panda, the tube, one object) per object
/// geometry of the scene is shared; Run is const and thread-safe, each call simulating on its own
/// mjData. Objects not in the scene are not built.
class StrikeRollout {
 public:
  /// Throws ConfigError on an invalid config (naming the key and the limit), or where the scene
  /// mode is not strike or guided.
  StrikeRollout(const TubeConfig& tube, const AudioConfig& audio, const StrikeConfig& strike,
                const SceneConfig& scene, const RolloutConfig& rollout);
  ~StrikeRollout();
  StrikeRollout(const StrikeRollout&) = delete;
  StrikeRollout& operator=(const StrikeRollout&) = delete;

  /// One strike (deterministic in its seed; guided mode picks its point and tap by index). A
  /// rollout that fails (bad placement, arm hits the object first, instability, penetration,
  /// off-surface contact) returns valid = false with the reason; it never throws.
  RolloutResult Run(uint64_t sample_index, uint64_t sample_seed) const;
  double timestep_s() const { return timestep_s_; }
  /// Guided mode: the tube-centre candidates kept (base frame, m); empty in mode strike.
  std::vector<Eigen::Vector3d> GuidedPoints() const;

 private:
  struct Variant;
  struct Guided;
  struct Plan;
  struct Simulation;
  void BuildGuided();
  Plan PlanStrike(const StrikeDraw& draw, const Variant& variant) const;
  RolloutResult Simulate(const Variant& variant, const Plan& plan) const;

  TubeConfig tube_;
  AudioConfig audio_;
  StrikeConfig strike_;
  SceneConfig scene_;
  RolloutConfig config_;
  double timestep_s_{0.0};
  std::vector<std::vector<std::unique_ptr<Variant>>> variants_;  // [object][variant]
  std::unique_ptr<Guided> guided_;
};

}  // namespace sonicboom::sim
