#pragma once
/// Striker-tube contact solved at audio-rate substeps (docs/physics.md, "Hertz impact"): a Hertz
/// spring F = K delta^1.5 (1 + lambda d(delta)/dt) (Hunt-Crossley when lambda > 0) between two
/// bodies, each seen at the contact as a rigid mass plus modes (driving-point modal model). The
/// tube side is the wall's modes at the contact point (so the wall is not rigid) and the robot-side
/// mass; the striker side is the struck rod's cantilever (or clamped-clamped) beam modes, or a
/// rigid mass. Bounces and chatter follow: the solve runs until the bodies separate for good.

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"

namespace sonicboom::acoustics {

/// Keys under "acoustics.contact".
enum class ContactWall { kCoupled, kRigid };
inline constexpr EnumName<ContactWall> kContactWallNames[] = {{ContactWall::kCoupled, "coupled"},
                                                              {ContactWall::kRigid, "rigid"}};
inline std::span<const EnumName<ContactWall>> EnumNames(ContactWall) {
  return kContactWallNames;
}

struct ContactConfig {
  int64_t substeps_per_duration{200};     // substeps per rigid-target Hertz duration (>= 50)
  int64_t min_substeps{4};                // per audio sample, at least
  double hunt_crossley_s_m{0.0};          // lambda, s/m; 0 = elastic Hertz
  double separation_window_s{0.002};      // stop once apart this long without re-contact
  double max_duration_s{0.05};            // a contact still closed after this is an error
  double beam_max_frequency_hz{20000.0};  // striker beam modes kept up to here
  // the tube side of the contact: coupled (the wall's modes at the point, so the wall yields)
  // or rigid (a held half-space: the classic Hertz pulse, the wall's modes only listen)
  ContactWall wall{ContactWall::kCoupled};

  void Serialize(Archive* a);
};

/// One body seen at the contact point: x(t) = rigid part + sum_n phi_n q_n, with
/// q_n'' + 2 zeta_n omega_n q_n' + omega_n^2 q_n = phi_n F (mass-normalized modes).
struct DrivingPoint {
  double rigid_mass_kg{std::numeric_limits<double>::infinity()};  // inf = held (no rigid motion)
  Eigen::VectorXd omega_rad_s;                                    // (modes)
  Eigen::VectorXd zeta;                                           // (modes) damping ratio
  Eigen::VectorXd phi;  // (modes) mass-normalized shape at the contact, 1/sqrt(kg)
};

/// Rigid-target Hertz contact time of a mass m_kg arriving at v_m_s on a spring F = K delta^1.5
/// (docs/physics.md, "Hertz impact"), s.
double HertzDuration(double m_kg, double stiffness_n_m15, double v_m_s);

/// Euler-Bernoulli rod clamped at one end (cantilever) or both.
struct BeamSpec {
  double length_m{0.42};
  double flexural_rigidity_n_m2{0.0};  // E I
  double linear_density_kg_m{0.0};     // rho A
  double contact_from_clamp_m{0.37};   // where the tube touches it
  bool clamped_both_ends{false};
  double loss_factor{0.01};  // eta = 2 zeta, every mode
};

/// Modes of the rod by Hermite-cubic finite elements (`elements` of them, consistent mass, a node
/// at the contact point): natural frequencies, ascending, Hz, up to max_frequency_hz (<= 0: no
/// limit) and only those the mesh resolves (>= 2 of the largest elements per half flexural
/// wavelength, never the top third of the FE spectrum). Throws ConfigError naming the field for
/// a non-positive length_m, flexural_rigidity_n_m2 or linear_density_kg_m, or a
/// contact_from_clamp_m outside (0, L] ((0, L) when clamped at both ends).
Eigen::VectorXd BeamFrequenciesHz(const BeamSpec& beam, int elements, double max_frequency_hz);
/// The rod seen at its contact point (48 elements), modes up to max_frequency_hz: held
/// (infinite rigid mass), phi = the mass-normalized modes' displacement at the contact node,
/// zeta = loss_factor / 2. Each thread remembers its last 8 rods.
DrivingPoint BeamDrivingPoint(const BeamSpec& beam, double max_frequency_hz);

/// Result of one contact: the force on the tube (positive pushes the wall inward), averaged over
/// each audio sample interval [k T, (k+1) T) from first_sample (the sample holding time_s) to
/// the final release: force_n[j] T = the impulse within sample first_sample + j.
struct ContactForce {
  int64_t first_sample{0};      // audio sample index of force_n[0]
  std::vector<double> force_n;  // N, one per audio sample
  double duration_s{0.0};       // first touch to final release
  double first_closure_s{0.0};  // first touch to first release (the impact proper;
                                // = duration_s without chatter)
  double peak_force_n{0.0};
  double impulse_ns{0.0};
  int64_t touches{0};             // closures: 1 = clean impact, > 1 = chatter
  double rebound_speed_m_s{0.0};  // relative separation speed at the final release
  int64_t substeps{0};            // integration steps over all passes (substeps,
                                  // free strides and whole free samples)
};

/// Solves the contact of `tube` (moving towards `striker` at approach_speed_m_s at first touch,
/// time_s from the record start) with Hertz constant stiffness_n_m15 (K in F = K delta^1.5).
///
/// Convention: one axis along the approach, positive from the tube towards the striker. The
/// tube's rigid part starts at +v, the striker's at rest, every mode at rest (only the relative
/// motion matters, so this covers a held tube hit by a moving striker too). Compression
/// delta = x_tube - x_striker; the force F >= 0 acts as -F on the tube (inward: the positive
/// force_n) and +F on the striker.
///
/// Numerics: substep h = T / (integer >= min_substeps), T = 1 / sample_rate_hz, sized to give
/// substeps_per_duration substeps per contact time: first the rigid-mass Hertz time (series of
/// the rigid masses), redone once the first closure is measured if it took under half or over
/// twice that; never over 1/20 of the Hertz time of the lightest mass the contact can see (all
/// modes as masses). Per substep the force is evaluated at the midpoint (predicted under the
/// start force) and held; modes and rigid parts step exactly for a held force. Apart, the
/// bodies move freely by whole samples where an energy bound proves no contact, else by strides
/// of substeps_per_duration / 50 substeps checked at both ends (a shorter graze can be missed).
/// The solve ends once apart for separation_window_s with the rigid parts not closing.
/// Throws ConfigError for both sides held or invalid inputs, NumericalError (naming
/// acoustics.contact.max_duration_s) when the contact is not over after max_duration_s, or when
/// the state turns non-finite.
ContactForce SolveContact(const DrivingPoint& tube, const DrivingPoint& striker,
                          double stiffness_n_m15, double approach_speed_m_s, double time_s,
                          double sample_rate_hz, const ContactConfig& config);

}  // namespace sonicboom::acoustics
