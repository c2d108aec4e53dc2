#include "sonicboom/core/tube.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom {

void TubeConfig::Serialize(Archive* a) {
  a->Visit("outer_radius_m", &outer_radius_m, Bounds::Open(0.0, 1.0));
  a->Visit("wall_thickness_m", &wall_thickness_m, Bounds::Open(0.0, 0.5));
  a->Visit("length_m", &length_m, Bounds::Open(0.0, 10.0));
  a->Visit("center_from_flange_m", &center_from_flange_m, Bounds::Closed(0.0, 10.0));
  a->Visit("contact_z_min_m", &contact_z_min_m);
  a->Visit("contact_z_max_m", &contact_z_max_m);
}

void TubeConfig::Validate() const {
  if (wall_thickness_m >= outer_radius_m) {
    throw ConfigError(
        fmt::format("tube.wall_thickness_m = {} must be smaller than tube.outer_radius_m = {}",
                    wall_thickness_m, outer_radius_m));
  }
  if (!(contact_z_min_m < contact_z_max_m)) {
    throw ConfigError(fmt::format("tube.contact_z_min_m = {} must be < tube.contact_z_max_m = {}",
                                  contact_z_min_m, contact_z_max_m));
  }
  if (contact_z_min_m < -0.5 * length_m || contact_z_max_m > 0.5 * length_m) {
    throw ConfigError(fmt::format(
        "contact region [tube.contact_z_min_m, tube.contact_z_max_m] = [{}, {}] m lies outside "
        "the tube (tube.length_m = {} m, so |z| <= {} m)",
        contact_z_min_m, contact_z_max_m, length_m, 0.5 * length_m));
  }
}

void MaterialConfig::Serialize(Archive* a) {
  a->Visit("youngs_modulus_pa", &youngs_modulus_pa, Bounds::Open(1e6, 1e13));
  a->Visit("poisson_ratio", &poisson_ratio, Bounds::Open(-1.0, 0.5));
  a->Visit("density_kg_m3", &density_kg_m3, Bounds::Open(1.0, 1e5));
  a->Visit("loss_factor", &loss_factor, Bounds::Closed(1e-5, 0.5));
}

void MicArrayConfig::Serialize(Archive* a) {
  a->Visit("z_m", &z_m);
  a->Visit("theta_deg", &theta_deg);
  a->Visit("disc_diameter_m", &disc_diameter_m, Bounds::Open(0.0, 0.1));
}

void MicArrayConfig::Validate(const TubeConfig& tube) const {
  if (z_m.size() != 6 || theta_deg.size() != 6) {
    throw ConfigError(fmt::format("mics.z_m and mics.theta_deg need 6 entries each, got {} and {}",
                                  z_m.size(), theta_deg.size()));
  }
  for (size_t i = 0; i < z_m.size(); ++i) {
    if (std::abs(z_m[i]) >= 0.5 * tube.length_m) {
      throw ConfigError(fmt::format("mics.z_m[{}] = {} m lies outside the tube (|z| < {} m)", i,
                                    z_m[i], 0.5 * tube.length_m));
    }
  }
}

void AudioConfig::Serialize(Archive* a) {
  a->Visit("sample_rate_hz", &sample_rate_hz, Bounds::Closed(8000.0, 384000.0));
  a->Visit("record_duration_s", &record_duration_s, Bounds::Open(0.0, 60.0));
  a->Visit("onset_time_s", &onset_time_s, Bounds::NonNegative());
  a->Visit("onset_jitter_s", &onset_jitter_s, Bounds::NonNegative());
}

int64_t AudioConfig::num_samples() const {
  return static_cast<int64_t>(std::llround(record_duration_s * sample_rate_hz));
}

double WrapAngle(double theta_rad) {
  // map to (-pi, pi]
  double t = std::remainder(theta_rad, 2.0 * std::numbers::pi);
  if (t <= -std::numbers::pi) t += 2.0 * std::numbers::pi;
  return t;
}

Eigen::Vector3d SurfacePoint(const TubeConfig& tube, double z_m, double theta_rad) {
  return {tube.outer_radius_m * std::cos(theta_rad), tube.outer_radius_m * std::sin(theta_rad),
          z_m};
}

Eigen::Vector3d SurfaceNormal(double theta_rad) {
  return {std::cos(theta_rad), std::sin(theta_rad), 0.0};
}

double SurfaceDistance(const TubeConfig& tube, double z1_m, double theta1_rad, double z2_m,
                       double theta2_rad) {
  return (SurfacePoint(tube, z1_m, theta1_rad) - SurfacePoint(tube, z2_m, theta2_rad)).norm();
}

}  // namespace sonicboom
