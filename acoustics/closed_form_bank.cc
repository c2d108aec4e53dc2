#include "sonicboom/acoustics/closed_form_bank.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/core/constants.h"

namespace sonicboom::acoustics {

namespace {
}  // namespace

ClosedFormBank::ClosedFormBank(const TubeConfig& tube, const MaterialConfig& material,
                               const MicArrayConfig& mics, double sample_rate_hz, double band_hz,
                               double decay_floor_db)
    : half_length_m_(0.5 * tube.length_m),
      floor_ln_(std::abs(decay_floor_db) / 20.0 * std::log(10.0)) {
  const double T = 1.0 / sample_rate_hz;
  const double R = tube.mid_radius_m();
  const double h = tube.wall_thickness_m;
  const double rho_h = material.density_kg_m3 * h;
  const double zeta = 0.5 * material.loss_factor;
  const int num_mics = mics.count();
  mic_theta_rad_.resize(num_mics);
  for (int i = 0; i < num_mics; ++i) mic_theta_rad_[i] = mics.theta_deg[i] * kPi / 180.0;
  for (const ShellMode& sm : SimplySupportedModes(tube, material, band_hz)) {
    if (std::abs(sm.w) < 1e-9) continue;  // no radial part: a normal force cannot excite it
    Mode mb;
    mb.frequency_hz = sm.frequency_hz;
    const double omega = 2 * kPi * sm.frequency_hz;
    const double sigma = zeta * omega;
    const double omega_d = omega * std::sqrt(1 - zeta * zeta);
    const std::complex<double> pole = std::exp(std::complex<double>(-sigma * T, omega_d * T));
    mb.pole_re = pole.real();
    mb.pole_im = pole.imag();
    mb.decay_per_sample = sigma * T;
    // modal mass of one member of the pair: rho h R (L / 2) pi (2 pi for n = 0), unit-norm shape
    const double modal_mass = rho_h * R * 0.5 * tube.length_m * (sm.n == 0 ? 2 * kPi : kPi);
    mb.response_scale = T / (omega_d * modal_mass);
    mb.wavenumber_m = sm.m * kPi / tube.length_m;
    mb.n = sm.n;
    mb.drive_w = sm.w;
    // outer-surface strain eps_x + eps_th: membrane (-lambda U + n V + W) / R plus bending
    const double lambda = mb.wavenumber_m * R;
    const double membrane = (-lambda * sm.u + sm.n * sm.v + sm.w) / R;
    const double bending = 0.5 * h * sm.w * (lambda * lambda + sm.n * sm.n) / (R * R);
    // disc aperture: 2 J1(x) / x with x = k_t d / 2
    const double k_t = std::hypot(mb.wavenumber_m, sm.n / tube.outer_radius_m);
    const double x = 0.5 * k_t * mics.disc_diameter_m;
    const double aperture = x < 1e-6 ? 1.0 : 2 * std::cyl_bessel_j(1.0, x) / x;
    mb.strain_factor = (membrane + bending) * aperture;
    mb.mic_axial.resize(num_mics);
    for (int i = 0; i < num_mics; ++i) {
      mb.mic_axial[i] = std::sin(mb.wavenumber_m * (mics.z_m[i] + 0.5 * tube.length_m));
    }
    modes_.push_back(std::move(mb));
  }
}

Eigen::MatrixXd ClosedFormBank::Render(std::span<const ForceInput> forces, double band_hz,
                                       int64_t samples, int64_t* modes_used) const {
  const Eigen::Index num_mics = mic_theta_rad_.size();
  Eigen::MatrixXd strain = Eigen::MatrixXd::Zero(num_mics, samples);
  Eigen::VectorXd gain(num_mics);
  int64_t used = 0;
  for (const Mode& mb : modes_) {
    if (mb.frequency_hz > band_hz) break;
    ++used;
    for (const ForceInput& f : forces) {
      const int64_t k_first = f.first_sample;
      const int64_t k_end_force = k_first + static_cast<int64_t>(f.force_n.size());
      // drive at the contact and pickup at each mic (the degenerate pair collapses to
      // cos n dtheta); a positive contact force pushes the wall inward, against the outward w
      const double drive = -mb.drive_w * std::sin(mb.wavenumber_m * (f.z_m + half_length_m_));
      for (Eigen::Index i = 0; i < num_mics; ++i) {
        gain[i] = mb.response_scale * drive * mb.strain_factor * mb.mic_axial[i] *
                  std::cos(mb.n * (mic_theta_rad_[i] - f.theta_rad));
      }
      // complex one-pole recursion z[k] = p z[k-1] + F[k]; q = Im(z) T / (omega_d M)
      const int64_t k_end = std::min<int64_t>(
          samples, k_end_force + static_cast<int64_t>(floor_ln_ / mb.decay_per_sample));
      double zr = 0, zi = 0;
      for (int64_t k = std::max<int64_t>(k_first, 0); k < k_end; ++k) {
        const double force = k < k_end_force ? f.force_n[static_cast<size_t>(k - k_first)] : 0.0;
        const double nr = zr * mb.pole_re - zi * mb.pole_im + force;
        zi = zr * mb.pole_im + zi * mb.pole_re;
        zr = nr;
        strain.col(k) += gain * zi;
      }
    }
  }
  if (modes_used != nullptr) *modes_used = used;
  return strain;
}

Eigen::VectorXd ClosedFormBank::FrequenciesHz(double band_hz) const {
  std::vector<double> f;
  for (const Mode& mb : modes_) {
    if (mb.frequency_hz > band_hz) break;
    f.push_back(mb.frequency_hz);
    if (mb.n >= 1) f.push_back(mb.frequency_hz);
  }
  return Eigen::Map<const Eigen::VectorXd>(f.data(), static_cast<Eigen::Index>(f.size()));
}

}  // namespace sonicboom::acoustics
