// The coupled contact against plate-impact theory (Zener, Phys. Rev. 59:669, 1941): a sphere
// striking an infinite plate, whose point velocity under a force F is F / Z with the plate's
// point impedance Z = 8 sqrt(D rho h). The reference integrates m x'' = -F, w' = F / Z,
// F = K (x - w)^1.5 directly; the solve sees the plate through the modes of a large simply
// supported plate driven at its centre (boundary echoes return only after the contact).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <iostream>
#include <numbers>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/core/constants.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;
constexpr double kFs = 44100.0;

// the PVC wall as a plate (docs/conventions.md defaults)
constexpr double kE = 3.0e9, kNu = 0.38, kRho = 1400.0, kH = 0.00305;
const double kD = kE * kH * kH * kH / (12.0 * (1.0 - kNu * kNu));
const double kRhoH = kRho * kH;
const double kZ = 8.0 * std::sqrt(kD * kRhoH);  // N s/m, 47.6

struct Impact {
  double duration_s, peak_n, rebound_m_s;
};

// Zener's equations by RK4 at a step far below the Hertz time
Impact ZenerReference(double m_kg, double k_n_m15, double v_m_s) {
  // state: compression delta and the striker's approach speed u (delta' = u - F / Z)
  auto force = [&](double delta) { return delta > 0.0 ? k_n_m15 * std::pow(delta, 1.5) : 0.0; };
  auto rate = [&](double delta, double u, double* d_delta, double* d_u) {
    const double f = force(delta);
    *d_delta = u - f / kZ;
    *d_u = -f / m_kg;
  };
  // the step: a 200 000th of the half-space Hertz time
  const double t_hertz =
      2.9432 * std::pow(5.0 * m_kg * v_m_s * v_m_s / (4.0 * k_n_m15), 0.4) / v_m_s;
  const double dt = t_hertz / 200000.0;
  double delta = 0.0, u = v_m_s, t = 0.0, peak = 0.0;
  do {
    double a1, b1, a2, b2, a3, b3, a4, b4;
    rate(delta, u, &a1, &b1);
    rate(delta + 0.5 * dt * a1, u + 0.5 * dt * b1, &a2, &b2);
    rate(delta + 0.5 * dt * a2, u + 0.5 * dt * b2, &a3, &b3);
    rate(delta + dt * a3, u + dt * b3, &a4, &b4);
    delta += dt * (a1 + 2 * a2 + 2 * a3 + a4) / 6.0;
    u += dt * (b1 + 2 * b2 + 2 * b3 + b4) / 6.0;
    t += dt;
    peak = std::max(peak, force(delta));
  } while (delta > 0.0 || t < 10 * dt);
  // apart: the plate point is at rest again (F = 0), so the separation speed is the striker's
  return {t, peak, -u};
}

// a simply supported square plate of side a driven at its centre: the odd-odd modes up to
// f_max, mass-normalized (phi = 2 / sqrt(rho h a^2) at the centre), held (no rigid motion)
DrivingPoint PlateCentre(double a_m, double f_max_hz, double loss_factor) {
  std::vector<double> omega, phi;
  const double kappa = std::sqrt(kD / kRhoH);
  for (int m = 1;; m += 2) {
    if (kPi * kPi * m * m / (a_m * a_m) * kappa > 2 * kPi * f_max_hz) break;
    for (int n = 1;; n += 2) {
      const double w = kPi * kPi * (m * m + n * n) / (a_m * a_m) * kappa;
      if (w > 2 * kPi * f_max_hz) break;
      omega.push_back(w);
      // sin(m pi / 2) sin(n pi / 2) = +-1
      phi.push_back((((m + n) / 2) % 2 == 0 ? 1.0 : -1.0) * 2.0 / std::sqrt(kRhoH * a_m * a_m));
    }
  }
  DrivingPoint p;
  p.omega_rad_s =
      Eigen::Map<Eigen::VectorXd>(omega.data(), static_cast<Eigen::Index>(omega.size()));
  p.phi = Eigen::Map<Eigen::VectorXd>(phi.data(), static_cast<Eigen::Index>(phi.size()));
  p.zeta = Eigen::VectorXd::Constant(p.phi.size(), 0.5 * loss_factor);
  return p;
}

TEST(ZenerTest, CoupledContactOnAPlateFollowsPlateImpactTheory) {
  // a 1.6 m plate: from its centre the slowest echo of the modes that matter (~2 kHz, 260 m/s
  // group speed) is back after 6 ms, longer than any of these contacts
  const DrivingPoint plate = PlateCentre(1.6, 80000.0, 0.001);
  ASSERT_GT(plate.phi.size(), 5000);
  ContactConfig config;
  config.substeps_per_duration = 400;
  // steel ball r = 5 mm on PVC: K = 4/3 E* sqrt(r)
  const double e_star = 1.0 / ((1 - 0.3 * 0.3) / 2.1e11 + (1 - kNu * kNu) / kE);
  const double k = 4.0 / 3.0 * e_star * std::sqrt(0.005);
  struct Case {
    double m_kg, v_m_s;
  };
  // from a light ball, where the plate hardly yields (Hertz on a half-space), to a heavy one,
  // where the plate's yield sets the contact (Zener's inelastic regime)
  for (const Case c : {Case{0.0005, 1.0}, Case{0.0015, 1.0}, Case{0.004, 2.0}}) {
    const Impact zener = ZenerReference(c.m_kg, k, c.v_m_s);
    DrivingPoint ball;
    ball.rigid_mass_kg = c.m_kg;
    const ContactForce solved = SolveContact(plate, ball, k, c.v_m_s, 0.001, kFs, config);
    // the half-space Hertz time of the same impact, to show how far the plate moves it
    const double delta = std::pow(5.0 * c.m_kg * c.v_m_s * c.v_m_s / (4.0 * k), 0.4);
    const double hertz_s = 2.9432 * delta / c.v_m_s;
    std::cout << "m = " << c.m_kg * 1e3 << " g, v = " << c.v_m_s << " m/s: Hertz " << hertz_s * 1e6
              << " us, Zener " << zener.duration_s * 1e6 << " us, solved "
              << solved.duration_s * 1e6 << " us; peak " << zener.peak_n << " / "
              << solved.peak_force_n << " N; rebound " << zener.rebound_m_s << " / "
              << solved.rebound_speed_m_s << " m/s\n";
    EXPECT_EQ(solved.touches, 1);
    EXPECT_NEAR(solved.duration_s / zener.duration_s, 1.0, 0.03);
    EXPECT_NEAR(solved.peak_force_n / zener.peak_n, 1.0, 0.03);
    EXPECT_NEAR(solved.rebound_speed_m_s, zener.rebound_m_s, 0.03 * c.v_m_s);
    // the impulse is the striker's change of momentum
    EXPECT_NEAR(solved.impulse_ns, c.m_kg * (c.v_m_s + zener.rebound_m_s), 0.03 * c.m_kg * c.v_m_s);
  }
}

}  // namespace
}  // namespace sonicboom::acoustics
