// The simply supported tube in exact 3-D elasticity: the cross-section eigenproblem per (m, n)
// by Rayleigh-Ritz through the wall, and the Bessel closed forms that check it.
#include "sonicboom/solid/ss_exact.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/gll.h"
#include "sonicboom/solid/solid_modes.h"

namespace sonicboom::solid {
namespace {

// Lame's constants, Pa
struct Lame {
  double lambda, mu;
};
Lame LameOf(const MaterialConfig& m) {
  const double e = m.youngs_modulus_pa, nu = m.poisson_ratio;
  return {e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))};
}

// the quadrature through the wall: GLL of the highest degree (exact to degree 31 in r)
constexpr int kQuadratureDegree = 16;

// K and M ((3 (p + 1))^2, per unit of the (theta, z) integrals) of the cross-section problem:
// columns U_0..U_p, V_0..V_p, W_0..W_p
void AssembleWall(const TubeConfig& tube, const MaterialConfig& material, double k, double n,
                  int p, Eigen::MatrixXd* stiffness, Eigen::MatrixXd* mass) {
  const double a = tube.outer_radius_m - tube.wall_thickness_m, b = tube.outer_radius_m;
  const double jac = 0.5 * (b - a);  // dr / dxi
  const Lame l = LameOf(material);
  const GllRule basis = MakeGllRule(p), quad = MakeGllRule(kQuadratureDegree);
  const int nb = p + 1, dofs = 3 * nb;
  *stiffness = Eigen::MatrixXd::Zero(dofs, dofs);
  *mass = Eigen::MatrixXd::Zero(dofs, dofs);
  // the isotropic law on (e_rr, e_tt, e_zz, g_rt, g_rz, g_tz)
  Eigen::Matrix<double, 6, 6> d = Eigen::Matrix<double, 6, 6>::Zero();
  d.topLeftCorner<3, 3>().setConstant(l.lambda);
  for (int i = 0; i < 3; ++i) d(i, i) += 2 * l.mu;
  for (int i = 3; i < 6; ++i) d(i, i) = l.mu;
  Eigen::VectorXd val, slope;
  for (int q = 0; q <= kQuadratureDegree; ++q) {
    const double r = a + (quad.points(q) + 1) * jac;
    const double w = quad.weights(q) * jac * r;  // r dr
    LagrangeBasis(basis, quad.points(q), &val, &slope);
    slope /= jac;
    // (6 strains x dofs): strains of each nodal value
    Eigen::MatrixXd bq = Eigen::MatrixXd::Zero(6, dofs);
    for (int j = 0; j < nb; ++j) {
      const int u = j, v = nb + j, wz = 2 * nb + j;
      bq(0, u) = slope(j);               // e_rr = U'
      bq(1, u) = val(j) / r;             // e_tt = (U + n V) / r
      bq(1, v) = n * val(j) / r;
      bq(2, wz) = -k * val(j);           // e_zz = -k W
      bq(3, v) = slope(j) - val(j) / r;  // g_rt = V' - V / r - n U / r
      bq(3, u) = -n * val(j) / r;
      bq(4, wz) = slope(j);              // g_rz = W' + k U
      bq(4, u) = k * val(j);
      bq(5, v) = k * val(j);             // g_tz = k V - n W / r
      bq(5, wz) = -n * val(j) / r;
    }
    stiffness->noalias() += w * bq.transpose() * d * bq;
    const Eigen::MatrixXd nn = material.density_kg_m3 * w * val * val.transpose();
    for (int c = 0; c < 3; ++c) mass->block(c * nb, c * nb, nb, nb) += nn;
  }
}

// ascending omega (rad/s) of K x = omega^2 M x; round-off negatives of a rigid mode read as 0
Eigen::VectorXd Omegas(const Eigen::MatrixXd& stiffness, const Eigen::MatrixXd& mass) {
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> solver(
      stiffness, mass, Eigen::EigenvaluesOnly | Eigen::Ax_lBx);
  if (solver.info() != Eigen::Success)
    throw NumericalError("exact tube: the cross-section eigenproblem did not converge");
  return solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();
}

// the lowest `count` roots above 0 of a continuous f(beta), by sign changes on steps of `step`
// then bisection; throws when `count` are not found below beta_max
std::vector<double> Roots(const std::function<double(double)>& f, double step, double beta_max,
                          int count) {
  std::vector<double> roots;
  double lo = 0.5 * step, f_lo = f(lo);
  while (static_cast<int>(roots.size()) < count && lo < beta_max) {
    const double hi = lo + step, f_hi = f(hi);
    if ((f_lo < 0) != (f_hi < 0)) {
      double x0 = lo, x1 = hi, f0 = f_lo;
      for (int it = 0; it < 200 && x1 - x0 > 1e-15 * x1; ++it) {
        const double mid = 0.5 * (x0 + x1), fm = f(mid);
        if ((fm < 0) == (f0 < 0)) {
          x0 = mid;
          f0 = fm;
        } else {
          x1 = mid;
        }
      }
      roots.push_back(0.5 * (x0 + x1));
    }
    lo = hi;
    f_lo = f_hi;
  }
  if (static_cast<int>(roots.size()) < count)
    throw NumericalError(fmt::format("exact tube: {} of {} Bessel roots below {:.0f} rad/m",
                                     roots.size(), count, beta_max));
  return roots;
}

double J(double nu, double x) { return std::cyl_bessel_j(nu, x); }
double Y(double nu, double x) { return std::cyl_neumann(nu, x); }
// derivatives of J_n and Y_n by the recurrence X_n' = (X_{n-1} - X_{n+1}) / 2
double Jp(double n, double x) {
  return n == 0 ? -J(1, x) : 0.5 * (J(n - 1, x) - J(n + 1, x));
}
double Yp(double n, double x) {
  return n == 0 ? -Y(1, x) : 0.5 * (Y(n - 1, x) - Y(n + 1, x));
}

// the root scan's step and reach for a wall of radii a < b: 1/200 of the ring's wavenumber
// 1/b, out past `count` thickness resonances pi / (b - a)
struct Scan {
  double a, b, step, reach;
};
Scan ScanOf(const TubeConfig& tube, int count) {
  const double b = tube.outer_radius_m, a = b - tube.wall_thickness_m;
  return {a, b, 0.005 / b, (count + 2) * kPi / (b - a) + 100.0 / b};
}

}  // namespace

Eigen::VectorXd WallSpectrum(const TubeConfig& tube, const MaterialConfig& material,
                             double k_rad_m, int64_t n, int radial_degree, WallFields fields) {
  if (radial_degree < kMinRadialDegree || radial_degree > kMaxRadialDegree) {
    throw ConfigError(fmt::format("exact tube: radial degree must be in [{}, {}], got {}",
                                  kMinRadialDegree, kMaxRadialDegree, radial_degree));
  }
  if (n < 0 || !(k_rad_m >= 0.0))
    throw ConfigError(fmt::format("exact tube: n = {} and k = {} must not be negative", n, k_rad_m));
  Eigen::MatrixXd stiffness, mass;
  AssembleWall(tube, material, k_rad_m, static_cast<double>(n), radial_degree, &stiffness, &mass);
  if (fields == WallFields::kAll) return Omegas(stiffness, mass);
  const int nb = radial_degree + 1;
  return Omegas(stiffness.bottomRightCorner(nb, nb), mass.bottomRightCorner(nb, nb));
}

int64_t ExactModeList::CountBelow(double f_hz) const {
  int64_t count = 0;
  for (const ExactMode& m : modes) count += m.frequency_hz < f_hz ? m.multiplicity : 0;
  return count;
}

std::vector<double> ExactModeList::ExpandedFrequenciesHz() const {
  std::vector<double> f;
  for (const ExactMode& m : modes) f.insert(f.end(), m.multiplicity, m.frequency_hz);
  return f;
}

ExactModeList ExactSimplySupportedModes(const TubeConfig& tube, const MaterialConfig& material,
                                        const ExactModeRequest& request) {
  const double omega_max = 2 * kPi * request.max_frequency_hz;
  // a root below this is the rigid axial slide (m = 0, n = 0; round-off leaves it near, not
  // at, 0), not an elastic mode: the solid's threshold
  const double rigid_omega = 2 * kPi * kSolidRigidBodyHz;
  ExactModeList list;
  constexpr int kEmptyInARow = 3;
  int empty_n = 0;
  for (int64_t n = 0; empty_n < kEmptyInARow; ++n) {
    bool n_has_modes = false;
    int empty_m = 0;
    double previous_lowest = 0.0;
    for (int64_t m = 0;; ++m) {
      const double k = kPi * static_cast<double>(m) / tube.length_m;
      const Eigen::VectorXd omega =
          WallSpectrum(tube, material, k, n, request.radial_degree,
                       m == 0 ? WallFields::kAxialOnly : WallFields::kAll);
      int64_t branch = 0;
      for (Eigen::Index i = 0; i < omega.size() && omega(i) <= omega_max; ++i) {
        if (omega(i) < rigid_omega) {
          ++list.rigid_body_modes;
          continue;
        }
        list.modes.push_back({m, n, branch++, omega(i) / (2 * kPi), n == 0 ? 1 : 2});
      }
      n_has_modes = n_has_modes || branch > 0;
      // past the family's minimum the lowest root only rises: stop after kEmptyInARow empty m
      const double lowest = omega(omega.size() > 1 && omega(0) < rigid_omega ? 1 : 0);
      empty_m = branch == 0 && lowest >= previous_lowest ? empty_m + 1 : 0;
      previous_lowest = lowest;
      if (m >= 1 && empty_m >= kEmptyInARow) break;
    }
    empty_n = n_has_modes ? 0 : empty_n + 1;
  }
  std::stable_sort(list.modes.begin(), list.modes.end(),
                   [](const ExactMode& x, const ExactMode& y) {
                     return x.frequency_hz < y.frequency_hz;
                   });
  return list;
}

std::vector<double> TorsionOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                  double k_rad_m, int count) {
  const double cs = std::sqrt(LameOf(material).mu / material.density_kg_m3);
  const Scan s = ScanOf(tube, count);
  const auto f = [&s](double beta) {
    return J(2, beta * s.a) * Y(2, beta * s.b) - J(2, beta * s.b) * Y(2, beta * s.a);
  };
  std::vector<double> omega{cs * k_rad_m};  // V = r: a rigid twist of each section
  if (count > 1) {
    for (double beta : Roots(f, s.step, s.reach, count - 1))
      omega.push_back(cs * std::hypot(k_rad_m, beta));
  }
  omega.resize(count);
  return omega;
}

std::vector<double> AntiPlaneOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                    int64_t n, int count) {
  const double cs = std::sqrt(LameOf(material).mu / material.density_kg_m3);
  const Scan s = ScanOf(tube, count);
  const double nu = static_cast<double>(n);
  const auto f = [&s, nu](double beta) {
    return Jp(nu, beta * s.a) * Yp(nu, beta * s.b) - Jp(nu, beta * s.b) * Yp(nu, beta * s.a);
  };
  std::vector<double> omega;
  if (n == 0) omega.push_back(0.0);  // the rigid slide
  const int wanted = count - static_cast<int>(omega.size());
  if (wanted > 0)
    for (double beta : Roots(f, s.step, s.reach, wanted)) omega.push_back(cs * beta);
  omega.resize(count);
  return omega;
}

std::vector<double> BreathingOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                    int count) {
  const Lame l = LameOf(material);
  const double cp = std::sqrt((l.lambda + 2 * l.mu) / material.density_kg_m3);
  const Scan s = ScanOf(tube, count);
  // sigma_rr of U = X1(alpha r) on the face at r, up to the amplitude
  const auto face = [&l](double alpha, double r, bool second_kind) {
    const double x0 = second_kind ? Y(0, alpha * r) : J(0, alpha * r);
    const double x1 = second_kind ? Y(1, alpha * r) : J(1, alpha * r);
    return (l.lambda + 2 * l.mu) * alpha * x0 - 2 * l.mu * x1 / r;
  };
  const auto f = [&](double alpha) {
    return face(alpha, s.a, false) * face(alpha, s.b, true) -
           face(alpha, s.b, false) * face(alpha, s.a, true);
  };
  std::vector<double> omega;
  for (double alpha : Roots(f, s.step, s.reach, count)) omega.push_back(cp * alpha);
  return omega;
}

}  // namespace sonicboom::solid
