#pragma once
/// Dynamic strike rollout in MuJoCo: the reference strike of reference_impl.md §6.1 simulated
/// instead of prescribed. A joint-space impedance controller sweeps joint 1 towards a clamped
/// wooden rod with its goal beyond the rod, so the tube hits the rod and stays pressed against
/// it; the contacts (touch, release, impulse, approach speed, effective mass) come from MuJoCo.
///
/// The strike is drawn from the sample seed with the same draws, in the same order, as
/// StrikeModel::Generate (j7, side, tilt, sweep, contact fraction, z, angle offset, onset jitter),
/// so one seed names the same intended contact in both generators.
///
/// Rod placement. At the kinematic contact configuration q_c (joint 1 turned by
/// sweep * MinJerk(contact_fraction) from home, as in StrikeModel) the tube pose T comes from the
/// DH forward kinematics. The intended contact (z, theta) has theta = direction of motion of the
/// tube axis point at z (about the axis) + the sampled angle offset. With n = T (cos theta,
/// sin theta, 0) the outward normal and a = T z the tube axis, the rod axis is a x n: the rod
/// crosses the tube at 90 degrees, tangent to the surface at (z, theta). Its axis passes
/// (rod radius + 1 mm) beyond the surface point along n, so the tube, moving towards it, first
/// touches it at (z, theta) about 1 mm of travel after q_c. Along its axis the rod is a
/// cantilever struck near its free tip (5 cm in, which leaves room to slide while pressed; its
/// tip modal mass is m_rod / 4, physics.md §1.4), with the clamped end pointing away from the
/// joint-1 axis, so the rod does not reach back across the arm. It is a mocap body: fixed in
/// space during the rollout. Contacts use MuJoCo's elliptic friction cones.
///
/// Control (at every step, between mj_step1 and mj_step2):
///   tau = K (q_des(t) - q) - D qdot + qfrc_bias, clamped to the motor ranges,
/// with D_ii = 2 damping_ratio sqrt(K_i M_ii(q0)). q_des holds q0 except joint 1, which follows a
/// minimum-jerk profile over strike.sweep_duration_s from q0 to q0 + side (travel to the rod +
/// sweep_overshoot_deg). The profile is timed so that q_des reaches the rod at the sampled onset
/// (audio.onset_time_s + jitter), started earlier by the impedance's low-frequency lag
/// D_11 / K_1 so that the arm itself, not only its set point, arrives near the onset.
///
/// Cost. Collision detection tests only rod pairs (tube and every arm capsule; no self-collision),
/// and a step skips it where a conservative bound (axis-segment distances, minus the most the
/// arm can have moved since they were taken) shows no pair can touch; the simulation starts at
/// the sweep start, the arm holding q0 at rest before it. None of these changes a result.
///
/// Contact durations follow MuJoCo's soft contact (contact_timeconst_s, milliseconds), longer than
/// the Hertz contact of wood on PVC (0.2-0.6 ms, physics.md §1.6): use the impulse, approach speed
/// and effective mass of a ContactRecord with a Hertz model for the sound, not its duration.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {

class PandaScene;

/// Settings of the dynamic rollout (keys under "rollout").
struct RolloutConfig {
  double timestep_s{0.0};            // 0 = derived: contact_timeconst_s / 4
  double contact_timeconst_s{0.002}; // solref time constant of object contacts, >= 2 timesteps
  double contact_dampratio{1.0};     // solref damping ratio of object contacts
  double contact_friction{0.4};      // sliding friction of object contacts (wood on PVC)
  std::vector<double> stiffness_nm_rad{1000, 1000, 1000, 4000, 1000, 1000, 4000};  // (7)
  double damping_ratio{1.0};         // joint damping = 2 ratio sqrt(K M_ii), M at the start
  double sweep_overshoot_deg{4.0};   // joint-1 goal this far beyond the contact angle
  double penetration_limit_m{0.001}; // a deeper object contact makes the sample invalid
  double settle_s{0.3};              // simulate this long after the first contact, then stop

  void Serialize(Archive* a);
  /// Cross-field checks; throws ConfigError naming the key and the limit.
  void Validate() const;
  /// The timestep in use, s: timestep_s, or contact_timeconst_s / 4 where timestep_s is 0.
  double ResolvedTimestep() const;
};

/// One tube contact episode with one object, from touch to release.
struct ContactRecord : ContactEpisode {
  // ContactEpisode: time and duration on the audio clock, raw MuJoCo point and outward
  // (tube to object) unit normal in the tube frame, z and theta from the raw point, approach
  // speed at touch, effective mass (robot side in series with the object side), impulse, peak
  // force and kind; object and material are named by the caller
  Eigen::Vector3d point_world_m{Eigen::Vector3d::Zero()};  // (3) raw MuJoCo point, base frame
  int object_index{0};
};

/// Outcome of one rollout.
struct RolloutResult {
  bool valid{true};
  std::string invalid_reason;               // empty when valid
  std::vector<ContactRecord> contacts;      // in time order
  Eigen::MatrixXf proprio;                  // (proprio_rows x 10) tube frame in the base frame:
                                            // pos m, quat wxyz, lin vel m/s; row k at k / rate
  std::vector<double> joint_speed_rad_s;    // (ceil(record s x rate)) |qdot| 2-norm, rad/s
  double joint_speed_rate_hz{100.0};
  // the sampled strike
  double target_z_m{0.0};                   // intended first contact, tube frame
  double target_theta_rad{0.0};
  double target_time_s{0.0};                // intended onset, audio clock
  Eigen::Vector3d rod_center_world_m{Eigen::Vector3d::Zero()};  // (3) base frame
  Eigen::Vector3d rod_axis_world{Eigen::Vector3d::Zero()};      // (3) unit, base frame
  // the simulation
  double timestep_s{0.0};
  int64_t steps{0};
  double simulated_s{0.0};
};

/// Immutable rollout model: the compiled MuJoCo scene (the Panda, the tube, one rod) is shared;
/// Run is const and thread-safe, each call simulating on its own mjData.
class StrikeRollout {
 public:
  /// Throws ConfigError on an invalid config (naming the key and the limit).
  StrikeRollout(const TubeConfig& tube, const AudioConfig& audio, const StrikeConfig& strike,
                const RolloutConfig& rollout);
  ~StrikeRollout();
  StrikeRollout(const StrikeRollout&) = delete;
  StrikeRollout& operator=(const StrikeRollout&) = delete;

  /// One strike from its sample seed (deterministic). A rollout that fails (bad placement, arm
  /// hits the rod first, instability, penetration, off-surface contact) returns valid = false
  /// with the reason; it never throws.
  RolloutResult Run(uint64_t sample_seed) const;
  double timestep_s() const { return timestep_s_; }

 private:
  struct Ids;
  TubeConfig tube_;
  AudioConfig audio_;
  StrikeConfig strike_;
  RolloutConfig config_;
  double timestep_s_{0.0};
  std::unique_ptr<PandaScene> scene_;
  std::unique_ptr<Ids> ids_;
};

}  // namespace sonicboom::sim
