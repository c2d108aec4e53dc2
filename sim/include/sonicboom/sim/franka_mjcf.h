#pragma once
/// The Franka Panda carrying the SonicBoom tube, as MuJoCo MJCF text generated from public facts:
/// the Craig (modified) DH parameters and joint limits of franka.h, the link inertials identified
/// by Gaz et al. (IEEE RA-L 2019), the published joint torque limits, and capsule collision shapes.
/// Body frames are the DH frames, so MuJoCo's kinematic chain reproduces PandaForwardKinematics.
/// Names: bodies panda_link1..7 and panda_flange, hinges panda_joint1..7, motors panda_motor1..7,
/// geom "tube", sites "flange" (flange frame) and "tube_center" (tube frame).

#include <string>

#include "sonicboom/core/tube.h"

namespace sonicboom::sim {

/// Simulation settings written into the model.
struct PandaMjcfOptions {
  double timestep_s{0.001};
  double tube_density_kg_m3{1400.0};  // PVC, as MaterialConfig's default; sets the tube's inertial
};

/// Sum of the seven link masses written into the model (Gaz et al. 2019), kg; excludes the tube.
double PandaLinkMassSumKg();

/// MJCF XML text of the Panda with `tube` on its flange. Throws ConfigError on a non-positive or
/// non-finite timestep or density, or on a tube that fails TubeConfig::Validate.
std::string PandaMjcf(const TubeConfig& tube, const PandaMjcfOptions& options = {});

}  // namespace sonicboom::sim
