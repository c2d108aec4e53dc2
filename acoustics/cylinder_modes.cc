#include "sonicboom/acoustics/cylinder_modes.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {


// Flügge stiffness (Donnell + k corrections) in Leissa's nondimensional form; mass = identity
Eigen::Matrix3d FluggeStiffness(double lambda, double n, double nu, double k) {
  Eigen::Matrix3d K;
  const double l2 = lambda * lambda, n2 = n * n;
  K << l2 + (1 - nu) * n2 / 2, -(1 + nu) * lambda * n / 2, -nu * lambda, -(1 + nu) * lambda * n / 2,
      (1 - nu) * l2 / 2 + n2, n, -nu * lambda, n, 1 + k * (l2 + n2) * (l2 + n2);
  Eigen::Matrix3d C;
  C << (1 - nu) * n2 / 2, 0, -lambda * l2 + (1 - nu) * lambda * n2 / 2, 0, 3 * (1 - nu) * l2 / 2,
      (3 - nu) * l2 * n / 2, -lambda * l2 + (1 - nu) * lambda * n2 / 2, (3 - nu) * l2 * n / 2,
      1 - 2 * n2;
  return K + k * C;
}

}  // namespace

std::vector<ShellMode> SimplySupportedModes(const TubeConfig& tube, const MaterialConfig& material,
                                            double max_frequency_hz) {
  const double R = tube.mid_radius_m();
  const double h = tube.wall_thickness_m;
  const double nu = material.poisson_ratio;
  const double k = h * h / (12 * R * R);
  // Omega = omega R sqrt(rho (1 - nu^2) / E)
  const double omega_scale =
      std::sqrt(material.youngs_modulus_pa / (material.density_kg_m3 * (1 - nu * nu))) / R;
  std::vector<ShellMode> modes;
  // m = 0: v = w = 0 (they carry sin(k x)), u = cos(n th) uniform along the tube, an in-plane
  // shear of the wall; Flügge's (1, 1) entry at lambda = 0 (n = 0 is the rigid slide)
  for (int n = 1; n < 400; ++n) {
    const double f = std::sqrt((1 - nu) * n * n * (1 + k) / 2) * omega_scale / (2 * kPi);
    if (f > max_frequency_hz) break;
    modes.push_back({0, n, 0, f, 1.0, 0.0, 0.0});
  }
  for (int m = 1; m < 400; ++m) {
    const double lambda = m * kPi * R / tube.length_m;
    double lowest_over_n = std::numeric_limits<double>::infinity();
    for (int n = 0; n < 400; ++n) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(FluggeStiffness(lambda, n, nu, k));
      const Eigen::Vector3d omega2 = eig.eigenvalues();
      const double f0 = std::sqrt(std::max(omega2[0], 0.0)) * omega_scale / (2 * kPi);
      lowest_over_n = std::min(lowest_over_n, f0);
      for (int r = 0; r < 3; ++r) {
        const double f = std::sqrt(std::max(omega2[r], 0.0)) * omega_scale / (2 * kPi);
        if (f > max_frequency_hz) break;
        const Eigen::Vector3d shape = eig.eigenvectors().col(r);
        // n = 0 torsion has no radial part and is not excited by a normal force; keep it anyway
        modes.push_back({m, n, r, f, shape[0], shape[1], shape[2]});
      }
      // past the minimum over n, frequencies only grow
      if (n > 3 && f0 > max_frequency_hz) break;
    }
    if (lowest_over_n > max_frequency_hz) break;
  }
  std::sort(modes.begin(), modes.end(),
            [](const ShellMode& a, const ShellMode& b) { return a.frequency_hz < b.frequency_hz; });
  return modes;
}

double RayleighFrequency(const TubeConfig& tube, const MaterialConfig& material, int n) {
  const double R = tube.mid_radius_m();
  const double h = tube.wall_thickness_m;
  const double nu = material.poisson_ratio;
  const double nn = n;
  return h / (2 * kPi * R * R) *
         std::sqrt(material.youngs_modulus_pa / (12 * material.density_kg_m3 * (1 - nu * nu))) *
         nn * (nn * nn - 1) / std::sqrt(nn * nn + 1);
}

std::vector<double> ClosedFormFrequencies(const TubeConfig& tube, const MaterialConfig& material,
                                          TubeEnds ends, int count) {
  if (count < 1) throw ConfigError(fmt::format("--count must be >= 1, got {}", count));
  std::vector<double> freqs;
  if (ends == TubeEnds::kSimplySupported) {
    // widen the band until it holds `count` modes (pairs counted twice)
    for (double f_max = 2000.0;; f_max *= 2) {
      freqs.clear();
      for (const auto& mode : SimplySupportedModes(tube, material, f_max)) {
        freqs.push_back(mode.frequency_hz);
        if (mode.n > 0) freqs.push_back(mode.frequency_hz);
      }
      if (static_cast<int>(freqs.size()) >= count || f_max > 1e7) break;
    }
  } else {
    // Rayleigh families: f_n0 and f_n1 = f_n0 sqrt((1 + 24 (1 - nu) R^2 / (n^2 L^2)) /
    // (1 + 12 R^2 / (n^2 (n^2 + 1) L^2))), each a degenerate pair
    const double R = tube.mid_radius_m(), L = tube.length_m, nu = material.poisson_ratio;
    for (int n = 2; static_cast<int>(freqs.size()) < 2 * count + 4; ++n) {
      const double f0 = RayleighFrequency(tube, material, n);
      const double nn = n;
      const double f1 = f0 * std::sqrt((1 + 24 * (1 - nu) * R * R / (nn * nn * L * L)) /
                                       (1 + 12 * R * R / (nn * nn * (nn * nn + 1) * L * L)));
      freqs.insert(freqs.end(), {f0, f0, f1, f1});
    }
  }
  std::sort(freqs.begin(), freqs.end());
  if (static_cast<int>(freqs.size()) > count) freqs.resize(count);
  return freqs;
}

}  // namespace sonicboom::acoustics
