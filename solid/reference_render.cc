#include "sonicboom/solid/reference_render.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {

double ReferenceHertzStiffness(const ReferenceStrike& s, const TubeConfig& tube,
                               const MaterialConfig& material) {
  const double inv_e =
      (1.0 - material.poisson_ratio * material.poisson_ratio) / material.youngs_modulus_pa +
      (1.0 - s.striker_poisson_ratio * s.striker_poisson_ratio) / s.striker_youngs_modulus_pa;
  const double r_e = std::sqrt(s.striker_radius_m * tube.outer_radius_m);
  return 4.0 / 3.0 / inv_e * std::sqrt(r_e);
}

ReferenceRender RenderReferenceStrike(const ReferenceTube& tube, const ReferenceStrike& strike,
                                      const ReferenceRenderConfig& config) {
  const Eigen::VectorXd& omega = tube.omega_rad_s();
  const Eigen::Index modes = omega.size();
  const double fs = config.sample_rate_hz, t_audio = 1.0 / fs;
  if (modes > 0 && omega(modes - 1) / (2.0 * std::numbers::pi) >= 0.5 * fs) {
    throw ConfigError(fmt::format(
        "reference render: modes up to {:.0f} Hz do not fit below the Nyquist frequency {:.0f} Hz "
        "of audio.sample_rate_hz = {}",
        omega(modes - 1) / (2.0 * std::numbers::pi), 0.5 * fs, fs));
  }
  if (!(strike.speed_m_s > 0.0) || !(strike.striker_mass_kg > 0.0)) {
    throw ConfigError("reference render: the striker needs a positive speed and mass");
  }
  const Eigen::VectorXd drive = tube.ModalDrive(strike.z_m, strike.theta_rad);  // (modes)
  const double k_hertz =
      ReferenceHertzStiffness(strike, tube.config().tube, tube.config().material);
  // damping ratio of mode n: half its loss factor
  auto zeta_of = [&](Eigen::Index n) {
    const double f = omega(n) / (2.0 * std::numbers::pi);
    return 0.5 * config.loss_factor * std::pow(f / 2000.0, config.loss_exponent);
  };

  // each mode as a complex one-pole z = q' + (zeta w + i w_d) q, z' = p z + f; q = Im z / w_d
  std::vector<std::complex<double>> pole(modes), z(modes, 0.0);
  std::vector<double> wd(modes), zeta(modes);
  const double dt = t_audio / config.contact_substeps;
  std::vector<std::complex<double>> step(modes), gain(modes);
  for (Eigen::Index n = 0; n < modes; ++n) {
    zeta[n] = std::min(0.5, zeta_of(n));
    wd[n] = omega(n) * std::sqrt(1.0 - zeta[n] * zeta[n]);
    pole[n] = {-zeta[n] * omega(n), wd[n]};
    step[n] = std::exp(pole[n] * dt);
    gain[n] = (step[n] - 1.0) / pole[n];
  }
  auto wall_displacement = [&] {  // outward, at the contact
    double w = 0.0;
    for (Eigen::Index n = 0; n < modes; ++n) w += drive(n) * z[n].imag() / wd[n];
    return w;
  };

  ReferenceRender out;
  const Eigen::Index mics = tube.disc_strain().rows();
  out.strain = Eigen::MatrixXd::Zero(mics, config.samples);
  // stepped phase from the first touch: the striker (inward displacement s, speed u) against the
  // wall; penetration s + w; released and clear of the wall for watch_after_s ends it
  double s = 0.0, u = strike.speed_m_s, t = strike.onset_s, last_release = -1.0;
  bool in_contact = false;
  const int64_t first_sample = static_cast<int64_t>(std::ceil(strike.onset_s * fs));
  int64_t next_sample = first_sample;
  Eigen::VectorXd q(modes);
  out.striker_energy_in_j = 0.5 * strike.striker_mass_kg * u * u;
  const int64_t max_steps = static_cast<int64_t>(0.05 / dt);  // 50 ms: a press, not a strike
  for (int64_t i = 0; i < max_steps; ++i) {
    const double delta = s + wall_displacement();
    const double force = delta > 0.0 ? k_hertz * std::pow(delta, 1.5) : 0.0;
    if (force > 0.0 && !in_contact) {
      in_contact = true;
      ++out.touches;
    } else if (force == 0.0 && in_contact) {
      in_contact = false;
      last_release = t;
    }
    out.peak_force_n = std::max(out.peak_force_n, force);
    out.impulse_ns += force * dt;
    // the wall takes the inward force -F (outward positive) held over the step
    for (Eigen::Index n = 0; n < modes; ++n) z[n] = step[n] * z[n] - gain[n] * (drive(n) * force);
    u -= force / strike.striker_mass_kg * dt;
    s += u * dt;
    t += dt;
    // audio samples passed during the step
    while (next_sample < config.samples && next_sample * t_audio <= t) {
      for (Eigen::Index n = 0; n < modes; ++n) q(n) = z[n].imag() / wd[n];
      out.strain.col(next_sample) = tube.disc_strain() * q;
      ++next_sample;
    }
    if (!in_contact && last_release >= 0.0 && t - last_release > config.watch_after_s) break;
  }
  out.duration_s = (last_release >= 0.0 ? last_release : t) - strike.onset_s;
  out.striker_energy_out_j = 0.5 * strike.striker_mass_kg * u * u;
  for (Eigen::Index n = 0; n < modes; ++n) {
    const double qn = z[n].imag() / wd[n], vn = z[n].real() - zeta[n] * omega(n) * qn;
    out.wall_energy_j += 0.5 * (vn * vn + omega(n) * omega(n) * qn * qn);
  }

  // free ringing at the audio rate from the end of the stepped phase
  if (next_sample < config.samples) {
    const double floor = -std::log(std::pow(10.0, config.decay_floor_db / 20.0));  // > 0
    for (Eigen::Index n = 0; n < modes; ++n) {
      std::complex<double> zn = z[n] * std::exp(pole[n] * (next_sample * t_audio - t));
      const std::complex<double> per_sample = std::exp(pole[n] * t_audio);
      const int64_t ring =
          static_cast<int64_t>(std::min(1e12, floor / (zeta[n] * omega(n) + 1e-30) * fs)) + 1;
      const int64_t end = std::min<int64_t>(config.samples, next_sample + ring);
      const Eigen::VectorXd sensor = tube.disc_strain().col(n) / wd[n];
      for (int64_t k = next_sample; k < end; ++k) {
        out.strain.col(k) += sensor * zn.imag();
        zn *= per_sample;
      }
    }
  }
  return out;
}

}  // namespace sonicboom::solid
