#pragma once
/// Kinematic strike generator (docs/reference.md, "The reference strike motion"): the arm sweeps
/// joint 1 (or joint 6) towards a fixed object; the tube meets it at a sampled height; the object
/// stops it. The contact is where the rod lies relative to the tube's direction of motion; joint 7
/// sets which side of the tube faces the motion, as in the paper's data collection.
/// Proprioception (tube-frame pose and velocity in the robot base frame, 100 Hz) is sampled on
/// the audio clock: row k is time k / proprio_rate_hz from the start of the record.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/scene.h"

namespace sonicboom::sim {

/// The strike motion (keys under "strike"); the struck objects are scene.objects (scene.h).
/// Motions, one drawn per strike from `motions`: sweep (joint 1 towards +, the reference strike),
/// opposite (joint 1 towards -, the paper's opposite-side strikes) and lateral (joint 6, either
/// way, the paper's lateral variant). Tilted strikes: tilt_max_deg > 0.
/// mujoco: dynamic rollout (rollout.h); kinematic: DH only.
enum class StrikeEngine { kMujoco, kKinematic };
inline constexpr EnumName<StrikeEngine> kStrikeEngineNames[] = {
    {StrikeEngine::kMujoco, "mujoco"}, {StrikeEngine::kKinematic, "kinematic"}};
inline std::span<const EnumName<StrikeEngine>> EnumNames(StrikeEngine) {
  return kStrikeEngineNames;
}

/// The motions above.
enum class StrikeMotion { kSweep, kOpposite, kLateral };
inline constexpr EnumName<StrikeMotion> kStrikeMotionNames[] = {
    {StrikeMotion::kSweep, "sweep"},
    {StrikeMotion::kOpposite, "opposite"},
    {StrikeMotion::kLateral, "lateral"}};
inline std::span<const EnumName<StrikeMotion>> EnumNames(StrikeMotion) {
  return kStrikeMotionNames;
}

struct StrikeConfig {
  StrikeEngine engine{StrikeEngine::kMujoco};
  std::vector<double> home_joints_rad{1.2614, -0.8973, -0.0474, -2.3464, -0.0790, 1.4341, -1.7109};
  // drawn uniformly per strike, by name (StrikeMotion)
  std::vector<std::string> motions{"sweep", "opposite"};
  double sweep_min_deg{12.0};  // joint goal beyond the object, uniform in [min, max]
  double sweep_max_deg{16.0};
  double sweep_duration_s{1.0};       // minimum-jerk profile to the goal
  double contact_fraction_min{0.35};  // contact at this fraction of the sweep (object place)
  double contact_fraction_max{0.65};
  double contact_angle_spread_deg{40.0};  // object offset from the motion direction, +- this
  double tilt_max_deg{0.0};               // joint-2/4 tilt of the strike, uniform in [-max, 0]
  // proprioception
  double proprio_rate_hz{100.0};
  int64_t proprio_rows{50};  // window length fed to the model (0.5 s)

  void Serialize(Archive* a);
  void Validate() const;
};

/// The random part of one strike, drawn from its sample seed; both strike engines start here.
struct StrikeDraw {
  Eigen::Matrix<double, 7, 1> q0;             // rad: home pose with the drawn joint 7 and tilt
  StrikeMotion motion{StrikeMotion::kSweep};  // one of StrikeConfig::motions
  int joint{0};                               // swept joint, 0-based (0: joint 1, 5: joint 6)
  double side{1.0};                           // sweep direction (+-1)
  double sweep_rad{0.0};                      // goal magnitude of the swept joint
  double contact_fraction{0.5};               // contact at this fraction of the sweep time
  double z_m{0.0};                            // contact height, tube frame
  double angle_offset_rad{0.0};               // object offset from the motion direction
  double onset_s{0.0};                        // contact time on the audio clock
  // the object (stream Stream::kScene)
  int object{0};         // index into scene.objects
  int64_t variant{0};    // its geometry variant (branch structures)
  double target_u{0.0};  // uniform in [0, 1): which target segment
  double target_v{0.0};  // uniform in [0, 1): where along it
};
/// Draws a strike (deterministic in sample_seed; streams Stream::kStrike and Stream::kScene).
StrikeDraw DrawStrike(uint64_t sample_seed, const StrikeConfig& strike, const SceneConfig& scene,
                      const TubeConfig& tube, const AudioConfig& audio);

/// The arm's joint speed (rad/s, |qdot| at proprio_rate_hz over the record) in a no-contact
/// recording of the scene's robot, as the spectral gate's reference clip hears its motors: the
/// peak speed of a minimum-jerk sweep of the mean angle (sweep_min_deg, sweep_max_deg) over
/// sweep_duration_s, held; empty (no motor) where the robot holds still (scene.mode stationary).
std::vector<double> NoContactJointSpeed(const StrikeConfig& strike, const SceneConfig& scene,
                                        const AudioConfig& audio);

/// Minimum-jerk position fraction at normalised time s (clamped to [0, 1]), and its rate.
double MinJerk(double s);
double MinJerkRate(double s);

/// Everything the acoustics stage and the dataset need from one strike.
struct StrikeEvents {
  bool valid{true};
  std::string invalid_reason;
  ContactLabel label;    // tube frame; impulse and duration filled by acoustics
  ContactEvent contact;  // what acoustics needs to play the contact
  std::string object;    // the struck object's name and material
  std::string material;
  Eigen::Vector3d point_world_m{Eigen::Vector3d::Zero()};
  Eigen::MatrixXf proprio;  // (proprio_rows x 10): pos m, quat wxyz, vel m/s (base)
  std::vector<double>
      joint_speed_rad_s;  // (record duration x proprio rate) |qdot|, for motor noise
  double joint_speed_rate_hz{100.0};
};

/// Immutable strike model shared across threads.
class StrikeModel {
 public:
  /// Throws ConfigError where the scene needs the dynamic engine (modes stationary and guided).
  StrikeModel(const StrikeConfig& strike, const SceneConfig& scene, const TubeConfig& tube,
              const AudioConfig& audio);
  /// One strike from its sample seed (thread-safe, deterministic).
  StrikeEvents Generate(uint64_t sample_seed) const;
  const StrikeConfig& config() const { return strike_; }

 private:
  StrikeConfig strike_;
  SceneConfig scene_;
  TubeConfig tube_;
  AudioConfig audio_;
};

}  // namespace sonicboom::sim
