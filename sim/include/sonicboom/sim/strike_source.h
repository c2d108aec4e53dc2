#pragma once
/// Where strikes come from: one interface over the simulator's strike engines, chosen by the
/// scene. scene.mode stationary: a hand-held striker hits the held tube (stationary.h); modes
/// strike and guided with strike.engine mujoco: the arm's dynamic rollout (rollout.h); mode strike
/// with strike.engine kinematic: DH kinematics alone (strike.h). The acoustics stage plays what a
/// source returns; it never needs to know which engine made it.

#include <cstdint>
#include <memory>
#include <vector>

#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {

/// One simulated strike as the acoustics stage and the dataset take it.
struct SimulatedStrike {
  StrikeEvents events;  // the first hard contact as acoustics plays it, label, proprioception
  std::vector<ContactEpisode> contacts;  // every tube contact of the record, in time order
  // true where the engine knows no contact forces (the kinematic engine): `contacts` holds the
  // one impact, whose duration, impulse and peak force the acoustics stage's contact solve gives
  bool forces_from_acoustics{false};
};

/// An immutable strike engine, shared across threads: Strike is const, thread-safe and
/// deterministic in (sample_index, sample_seed). A strike that fails returns events.valid = false
/// with the reason; it never throws.
class StrikeSource {
 public:
  virtual ~StrikeSource() = default;
  virtual SimulatedStrike Strike(uint64_t sample_index, uint64_t sample_seed) const = 0;
};

/// The source the scene and strike config ask for (see the top of this file); only that engine
/// is built. Throws ConfigError naming the key on an invalid config or an engine that cannot
/// simulate the scene's mode.
std::unique_ptr<StrikeSource> MakeStrikeSource(const TubeConfig& tube, const AudioConfig& audio,
                                               const StrikeConfig& strike, const SceneConfig& scene,
                                               const RolloutConfig& rollout);

}  // namespace sonicboom::sim
