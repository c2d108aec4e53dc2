#include "sonicboom/solid/theory.h"

#include <cmath>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {
namespace {

// cos(a d) and sin(a d) / a as entire functions of a^2 (hyperbolic where a^2 < 0)
double CosOf(double a2, double d) {
  return a2 >= 0.0 ? std::cos(std::sqrt(a2) * d) : std::cosh(std::sqrt(-a2) * d);
}
double SincOf(double a2, double d) {
  if (std::abs(a2) * d * d < 1e-12) return d;
  const double a = std::sqrt(std::abs(a2));
  return a2 >= 0.0 ? std::sin(a * d) / a : std::sinh(a * d) / a;
}

}  // namespace

double RayleighLambA0(const MaterialConfig& material, double thickness_m, double k_rad_m) {
  const double e = material.youngs_modulus_pa, nu = material.poisson_ratio;
  const double rho = material.density_kg_m3;
  const double c_p2 = e * (1.0 - nu) / (rho * (1.0 + nu) * (1.0 - 2.0 * nu));  // dilatational
  const double c_s2 = e / (2.0 * rho * (1.0 + nu));                            // shear
  const double d = 0.5 * thickness_m, k2 = k_rad_m * k_rad_m;
  // antisymmetric: (q^2 - k^2)^2 sin(pd) cos(qd) + 4 k^2 p q cos(pd) sin(qd) = 0, divided by p
  auto g = [&](double omega) {
    const double p2 = omega * omega / c_p2 - k2, q2 = omega * omega / c_s2 - k2;
    return (q2 - k2) * (q2 - k2) * SincOf(p2, d) * CosOf(q2, d) +
           4.0 * k2 * q2 * CosOf(p2, d) * SincOf(q2, d);
  };
  // bracket the first sign change above 0 from the Kirchhoff estimate downwards, then bisect
  const double kirchhoff = KirchhoffFlexural(material, thickness_m, k_rad_m);
  double lo = 1e-3 * kirchhoff, hi = lo;
  const double g_lo = g(lo);
  while (hi < 10.0 * kirchhoff) {
    const double next = hi * 1.01;
    if ((g(next) > 0.0) != (g_lo > 0.0)) {
      lo = hi;
      hi = next;
      for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        if ((g(mid) > 0.0) == (g_lo > 0.0))
          lo = mid;
        else
          hi = mid;
      }
      return 0.5 * (lo + hi);
    }
    hi = next;
  }
  SONICBOOM_DEMAND(false && "the A0 root lies below 10x the Kirchhoff frequency");
  return 0.0;
}

double MindlinFlexural(const MaterialConfig& material, double thickness_m, double k_rad_m) {
  const double e = material.youngs_modulus_pa, nu = material.poisson_ratio;
  const double rho = material.density_kg_m3, h = thickness_m, k2 = k_rad_m * k_rad_m;
  const double d = e * h * h * h / (12.0 * (1.0 - nu * nu));
  const double ks = std::numbers::pi * std::numbers::pi / 12.0;
  const double s = ks * e / (2.0 * (1.0 + nu)) * h;  // kappa G h
  const double i = rho * h * h * h / 12.0;           // rotary inertia per area
  // det [[s k^2 - rho h w^2, s k], [s k, D k^2 + s - I w^2]] = 0: a quadratic in x = w^2
  const double a = rho * h * i;
  const double b = -(rho * h * (d * k2 + s) + i * s * k2);
  const double c = s * k2 * (d * k2 + s) - s * s * k2;
  const double x = (-b - std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
  return std::sqrt(x);
}

double KirchhoffFlexural(const MaterialConfig& material, double thickness_m, double k_rad_m) {
  const double e = material.youngs_modulus_pa, nu = material.poisson_ratio;
  const double h = thickness_m;
  const double d = e * h * h * h / (12.0 * (1.0 - nu * nu));
  return std::sqrt(d / (material.density_kg_m3 * h)) * k_rad_m * k_rad_m;
}

Extrapolation Richardson(const std::vector<double>& h, const std::vector<double>& f) {
  SONICBOOM_DEMAND(h.size() == f.size() && h.size() >= 3);
  const size_t n = h.size();
  const double h1 = h[n - 3], h2 = h[n - 2], h3 = h[n - 1];
  const double f1 = f[n - 3], f2 = f[n - 2], f3 = f[n - 1];
  const double d12 = f1 - f2, d23 = f2 - f3;
  Extrapolation out;
  out.limit = f3;
  out.error = std::abs(d23);
  if (d23 == 0.0) return out;
  const double ratio = d12 / d23;
  // monotone convergence: same sign and shrinking differences
  if (!(ratio > 0.0) || std::abs(d12) <= std::abs(d23)) return out;
  // solve (h1^p - h2^p) / (h2^p - h3^p) = ratio for p by bisection
  auto model = [&](double p) {
    return (std::pow(h1, p) - std::pow(h2, p)) / (std::pow(h2, p) - std::pow(h3, p));
  };
  double lo = 1.0, hi = 40.0;  // slower than first order: not in the asymptotic range
  if ((model(lo) - ratio) * (model(hi) - ratio) > 0.0) return out;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    if ((model(lo) - ratio) * (model(mid) - ratio) <= 0.0)
      hi = mid;
    else
      lo = mid;
  }
  const double p = 0.5 * (lo + hi);
  const double c = d23 / (std::pow(h2, p) - std::pow(h3, p));
  out.order = p;
  out.limit = f3 - c * std::pow(h3, p);
  out.error = std::abs(f3 - out.limit);
  return out;
}

}  // namespace sonicboom::solid
