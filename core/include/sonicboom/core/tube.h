#pragma once
/// Tube geometry, material and microphone layout (docs/conventions.md), and the mapping between
/// surface coordinates (z, theta) and points in the tube frame.
/// Tube frame: origin at the tube centre, +z along the tube axis (= flange z axis, pointing away
/// from the flange), theta measured about +z from +x, in (-pi, pi].

#include <Eigen/Core>
#include <vector>

#include "sonicboom/core/archive.h"

namespace sonicboom {

/// 4" SDR35 PVC pipe by default.
struct TubeConfig {
  double outer_radius_m{0.05355};  // OD 107.1 mm
  double wall_thickness_m{0.00305};
  double length_m{0.3048};
  double center_from_flange_m{0.155};  // along the flange z axis
  double contact_z_min_m{-0.1015};     // contact region, from the tube centre
  double contact_z_max_m{0.1015};

  void Serialize(Archive* a);
  /// Cross-field checks (wall < radius, contact region inside the tube); throws ConfigError.
  void Validate() const;
  double mid_radius_m() const { return outer_radius_m - 0.5 * wall_thickness_m; }
};

/// Isotropic linear-elastic material with a constant loss factor.
/// How the tube's ends are held: free (the production tube on its mounts) or simply supported
/// (both ends; the textbook case the modal checks compare against).
enum class TubeEnds { kFree, kSimplySupported };
inline constexpr EnumName<TubeEnds> kTubeEndsNames[] = {
    {TubeEnds::kFree, "free"}, {TubeEnds::kSimplySupported, "simply-supported"}};
inline std::span<const EnumName<TubeEnds>> EnumNames(TubeEnds) {
  return kTubeEndsNames;
}

struct MaterialConfig {
  double youngs_modulus_pa{3.0e9};
  double poisson_ratio{0.38};
  double density_kg_m3{1400.0};
  double loss_factor{0.02};  // eta; modal damping ratio = eta / 2

  void Serialize(Archive* a);
};

/// Six piezo discs: two rings of three. Mic i and i+3 share theta.
struct MicArrayConfig {
  std::vector<double> z_m{-0.13, -0.13, -0.13, 0.13, 0.13, 0.13};
  std::vector<double> theta_deg{0.0, 120.0, 240.0, 0.0, 120.0, 240.0};
  double disc_diameter_m{0.020};

  void Serialize(Archive* a);
  /// Six entries each, inside the tube; throws ConfigError.
  void Validate(const TubeConfig& tube) const;
  int count() const { return static_cast<int>(z_m.size()); }
};

/// Audio clock.
struct AudioConfig {
  double sample_rate_hz{44100.0};
  double record_duration_s{2.0};  // one strike record
  double onset_time_s{0.5};       // nominal time of first contact in the record
  double onset_jitter_s{0.05};    // first contact drawn uniformly in onset_time_s +- this

  void Serialize(Archive* a);
  int64_t num_samples() const;  // record length in samples
};

/// Wraps an angle to (-pi, pi].
double WrapAngle(double theta_rad);
/// Point on the outer surface at (z, theta), tube frame, m.
Eigen::Vector3d SurfacePoint(const TubeConfig& tube, double z_m, double theta_rad);
/// Outward unit normal at theta, tube frame.
Eigen::Vector3d SurfaceNormal(double theta_rad);
/// Euclidean distance between two surface points (z, theta), m.
double SurfaceDistance(const TubeConfig& tube, double z1_m, double theta1_rad, double z2_m,
                       double theta2_rad);

}  // namespace sonicboom
