#pragma once
/// The Franka Panda carrying the SonicBoom tube, as MuJoCo MJCF text generated from public facts:
/// the Craig (modified) DH parameters and joint limits of franka.h, the link inertials identified
/// by Gaz et al. (IEEE RA-L 2019), the published joint torque limits, and capsule collision shapes.
/// Body frames are the DH frames, so MuJoCo's kinematic chain reproduces PandaForwardKinematics.
/// Names: bodies panda_link1..7 and panda_flange, hinges panda_joint1..7, motors panda_motor1..7,
/// geom "tube", sites "flange" (flange frame) and "tube_center" (tube frame); objects (options) are
/// mocap bodies "object0", "object1", ... with geoms "object<i>_<k>"; with object_contacts_only,
/// collision detection tests only the <pair>s of each object geom with the tube and every arm
/// capsule.

#include <string>
#include <vector>

#include "sonicboom/core/tube.h"
#include "sonicboom/sim/scene.h"

namespace sonicboom::sim {

/// A fixed object the arm can strike: a mocap body "object<i>" carrying one cylinder geom
/// "object<i>_<k>" per segment (object frame, see scene.h). It is parked 10 m below the base; a
/// simulation places it through mjData's mocap_pos/mocap_quat. Its geoms have contact priority,
/// so every contact with them uses these parameters.
struct MjcfObject {
  std::vector<ObjectSegment> segments;  // object frame, m
  double contact_timeconst_s{0.002};    // MuJoCo solref time constant, s
  double contact_dampratio{1.0};        // MuJoCo solref damping ratio
  double friction{0.4};                 // sliding friction coefficient
};

/// Simulation settings written into the model.
struct PandaMjcfOptions {
  double timestep_s{0.001};
  double tube_density_kg_m3{1400.0};  // PVC, as MaterialConfig's default; sets the tube's inertial
  std::vector<MjcfObject> objects;    // struck objects; none in the default model
  bool elliptic_friction_cones{false};  // MuJoCo's elliptic friction cones (default: pyramidal)
  // Only object contacts: collision detection tests predefined pairs alone, each object geom
  // against the tube and against every arm capsule (no broad phase, no arm self-collision). The
  // pairs carry the object's contact parameters, as its priority gives them in the default
  // (dynamic) detection.
  bool object_contacts_only{false};
};

/// Sum of the seven link masses written into the model (Gaz et al. 2019), kg; excludes the tube.
double PandaLinkMassSumKg();

/// MJCF XML text of the Panda with `tube` on its flange. Throws ConfigError on a non-positive or
/// non-finite timestep, density or object parameter, or on a tube that fails TubeConfig::Validate.
std::string PandaMjcf(const TubeConfig& tube, const PandaMjcfOptions& options = {});

}  // namespace sonicboom::sim
