#pragma once
/// One strike sample as it travels from sim through acoustics into a dataset file.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace sonicboom {

/// Ground-truth label of the (first, localized) tube contact of a strike.
struct ContactLabel {
  double z_m{0.0};                                   // along the tube axis from the tube centre
  double theta_rad{0.0};                             // (-pi, pi] about the tube axis from +x
  Eigen::Vector3d point_m{Eigen::Vector3d::Zero()};  // (3) tube frame, on the outer surface
  Eigen::Vector3d normal{Eigen::Vector3d::Zero()};   // (3) tube frame, outward unit normal
  double impulse_Ns{0.0};                            // normal impulse delivered to the tube
  double time_s{0.0};                                // first contact, from the start of the record
  double normal_speed_m_s{0.0};                      // relative normal approach speed
  double duration_s{0.0};                            // contact duration
};

/// One striker-tube contact as sim hands it to acoustics (tube frame).
struct ContactEvent {
  double time_s{0.0};  // first touch, from the start of the record
  double z_m{0.0};
  double theta_rad{0.0};
  double normal_speed_m_s{0.0};   // relative approach speed along the normal
  double effective_mass_kg{0.0};  // striker (or struck rod) mass seen at the contact
  double striker_radius_m{0.0};   // radius of the striker's contact surface
  double striker_youngs_modulus_pa{0.0};
  double striker_poisson_ratio{0.0};
  // the struck rod as a beam, when it is one (acoustics plays its bending modes in the contact);
  // beam_length_m = 0: the striker is a rigid body of effective_mass_kg
  double beam_length_m{0.0};                // free length between clamps
  double beam_contact_from_clamp_m{0.0};    // where the tube touches it
  double beam_flexural_rigidity_n_m2{0.0};  // E I
  double beam_linear_density_kg_m{0.0};     // rho A
  bool beam_clamped_both_ends{false};
  double beam_loss_factor{0.01};
  double robot_side_mass_kg{0.0};  // the tube side's mass at the contact; 0 = held
};

/// One tube contact episode of a strike, from touch to release (tube frame).
struct ContactEpisode {
  // brush: foliage sweeping over the tube, a noise event with no localized hard contact
  enum class Kind : uint8_t { kImpact = 0, kBounce = 1, kPress = 2, kBrush = 3 };
  double time_s{0.0};  // touch, from the start of the record
  double duration_s{0.0};
  double z_m{0.0};
  double theta_rad{0.0};
  Eigen::Vector3d point_m{Eigen::Vector3d::Zero()};  // (3) raw contact point, tube frame
  Eigen::Vector3d normal{Eigen::Vector3d::Zero()};   // (3) outward tube normal, tube frame
  double normal_speed_m_s{0.0};                      // approach speed at touch
  double effective_mass_kg{0.0};
  double impulse_Ns{0.0};
  double peak_force_N{0.0};
  Kind kind{Kind::kImpact};
  std::string object;    // what the tube touched, e.g. "rod T22L42"
  std::string material;  // its material, e.g. "wood"
};

/// Number of proprioception features per row: position (3), quaternion w,x,y,z (4), velocity (3).
inline constexpr int kProprioFeatures = 10;

/// A simulated or recorded strike.
struct StrikeSample {
  uint64_t index{0};  // global sample index
  uint64_t seed{0};   // SampleSeed(global seed, index)
  bool valid{true};
  std::string invalid_reason;  // empty when valid
  ContactLabel label;
  Eigen::MatrixXf audio;                 // (channels x T) in [-1, 1] full scale
  Eigen::MatrixXf proprio;               // (K x kProprioFeatures) at the proprio rate
  bool clipped{false};                   // any audio sample hit full scale
  std::vector<ContactEpisode> contacts;  // every tube contact, in time order (may be empty)
  std::vector<double> variation;         // (P) randomized draws (DatasetInfo::variation_names)
  std::string provenance;                // a recorded sample's origin (file it was read
                                         // from); empty for simulated samples
};

}  // namespace sonicboom
