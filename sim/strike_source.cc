#include "sonicboom/sim/strike_source.h"

#include <memory>
#include <utility>

#include "sonicboom/sim/stationary.h"

namespace sonicboom::sim {
namespace {

// A dynamic rollout in the form the acoustics stage plays: its first hard tube contact, and
// every episode of the record.
SimulatedStrike FromRollout(const RolloutResult& r, const SceneConfig& scene) {
  SimulatedStrike s;
  StrikeEvents& ev = s.events;
  ev.valid = r.valid;
  ev.invalid_reason = r.invalid_reason;
  ev.proprio = r.proprio;
  ev.joint_speed_rad_s = r.joint_speed_rad_s;
  ev.joint_speed_rate_hz = r.joint_speed_rate_hz;
  s.contacts.assign(r.contacts.begin(), r.contacts.end());
  if (!FirstHardContact(r, scene, &ev.contact, &ev.label)) {
    if (ev.valid) {
      ev.valid = false;
      ev.invalid_reason = "the tube never touched the object";
    }
    return s;
  }
  if (ev.valid && !(ev.label.normal_speed_m_s > 1e-4)) {
    ev.valid = false;
    ev.invalid_reason = "no approach speed at the first contact";
  }
  return s;
}

// A dynamic simulation in MuJoCo: the arm's rollout (StrikeRollout: modes strike and guided) or
// a hand-held striker on the held tube (HandStrikeRollout: mode stationary).
template <typename Rollout>
class RolloutSource final : public StrikeSource {
 public:
  RolloutSource(const TubeConfig& tube, const AudioConfig& audio, const StrikeConfig& strike,
                const SceneConfig& scene, const RolloutConfig& rollout)
      : scene_(scene), rollout_(tube, audio, strike, scene, rollout) {}
  SimulatedStrike Strike(uint64_t sample_index, uint64_t sample_seed) const override {
    return FromRollout(rollout_.Run(sample_index, sample_seed), scene_);
  }

 private:
  SceneConfig scene_;
  Rollout rollout_;
};

// DH kinematics alone (mode strike, strike.engine kinematic): one contact, its forces unknown.
class KinematicSource final : public StrikeSource {
 public:
  KinematicSource(const TubeConfig& tube, const AudioConfig& audio, const StrikeConfig& strike,
                  const SceneConfig& scene)
      : model_(strike, scene, tube, audio) {}
  SimulatedStrike Strike(uint64_t, uint64_t sample_seed) const override {
    SimulatedStrike s;
    s.events = model_.Generate(sample_seed);
    s.forces_from_acoustics = true;
    const StrikeEvents& ev = s.events;
    ContactEpisode e;
    e.time_s = ev.label.time_s;
    e.z_m = ev.label.z_m;
    e.theta_rad = ev.label.theta_rad;
    e.point_m = ev.label.point_m;
    e.normal = ev.label.normal;
    e.normal_speed_m_s = ev.label.normal_speed_m_s;
    e.effective_mass_kg = ev.contact.effective_mass_kg;
    e.object = ev.object;
    e.material = ev.material;
    s.contacts = {e};
    return s;
  }

 private:
  StrikeModel model_;
};

}  // namespace

std::unique_ptr<StrikeSource> MakeStrikeSource(const TubeConfig& tube, const AudioConfig& audio,
                                               const StrikeConfig& strike, const SceneConfig& scene,
                                               const RolloutConfig& rollout) {
  if (scene.mode == SceneMode::kStationary) {
    return std::make_unique<RolloutSource<HandStrikeRollout>>(tube, audio, strike, scene, rollout);
  }
  if (strike.engine == StrikeEngine::kMujoco) {
    return std::make_unique<RolloutSource<StrikeRollout>>(tube, audio, strike, scene, rollout);
  }
  return std::make_unique<KinematicSource>(tube, audio, strike, scene);
}

}  // namespace sonicboom::sim
