#pragma once
/// Strikes rendered by the reference solid with its own contact: a Hertz spring between a rigid
/// striker and the modal wall at the contact point (the impact theory of a sphere on a plate in
/// Zener's sense, with the tube's own modes as the plate), integrated at sub-sample steps while
/// the striker is near, then every mode ringing freely at the audio rate. The discs read the
/// solid's in-plane surface strain. Damping: a constant loss factor per mode.

#include <Eigen/Core>
#include <cstdint>

#include "sonicboom/solid/reference_tube.h"

namespace sonicboom::solid {

/// One strike: where, what hits, how fast.
struct ReferenceStrike {
  double z_m{0.0};
  double theta_rad{0.0};
  double speed_m_s{0.5};           // normal approach speed
  double striker_mass_kg{0.01};    // effective mass at the contact
  double striker_radius_m{0.006};  // radius of the striker's tip (crossed with the tube)
  double striker_youngs_modulus_pa{12e9};
  double striker_poisson_ratio{0.35};
  double onset_s{0.0};  // first touch from the record start
};

struct ReferenceRenderConfig {
  double sample_rate_hz{44100.0};
  int64_t samples{4410};     // record length
  double loss_factor{0.02};  // eta of every mode (damping ratio eta / 2)
  // eta(f) = loss_factor (f / 2 kHz)^loss_exponent: 0 is PVC's flat loss; a positive exponent
  // damps the high modes more (joints, glue, the discs)
  double loss_exponent{0.0};
  int64_t contact_substeps{64};   // integration steps per audio sample near the contact
  double watch_after_s{5e-4};     // keep stepping this long after a release (re-contact)
  double decay_floor_db{-100.0};  // a mode stops ringing once decayed this far
};

struct ReferenceRender {
  Eigen::MatrixXd strain;  // (mics x samples) disc strain
  double duration_s{0.0};  // first touch to last release
  double impulse_ns{0.0};
  double peak_force_n{0.0};
  int64_t touches{0};  // closures (> 1: chatter)
  // energy bookkeeping at the end of the stepped phase (J): the striker's kinetic energy before
  // and after, the modes' energy and what the loss took
  double striker_energy_in_j{0.0}, striker_energy_out_j{0.0};
  double wall_energy_j{0.0};
};

/// The Hertz contact stiffness K (F = K delta^1.5) of the striker's tip crossing the tube's
/// outer surface, N/m^1.5 (effective radius sqrt(r R), combined modulus).
double ReferenceHertzStiffness(const ReferenceStrike& strike, const TubeConfig& tube,
                               const MaterialConfig& material);

/// Renders one strike. Throws ConfigError for a point off the tube or a band above Nyquist.
ReferenceRender RenderReferenceStrike(const ReferenceTube& tube, const ReferenceStrike& strike,
                                      const ReferenceRenderConfig& config);

}  // namespace sonicboom::solid
