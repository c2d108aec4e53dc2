// The predictive distribution (no libtorch here): scaled Bessel functions, von Mises and
// Gaussian intervals and likelihoods, and the post-hoc calibration of both scales.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "internal/uncertainty.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/learning/conformal.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace internal {
namespace {


// exp(-x) I_nu(x) for nu = 0 or 1 and x >= 0.
double BesselScaled(int nu, double x) {
  SONICBOOM_DEMAND(x >= 0.0);
  if (std::isinf(x)) return 0.0;
  if (x < 100.0) {
    // Power series sum_k (x/2)^(2k+nu) / (k! (k+nu)!); every term is positive, so there is no
    // cancellation, and below x = 100 nothing overflows.
    const double q = 0.25 * x * x;
    double term = nu == 0 ? 1.0 : 0.5 * x;
    double sum = term;
    for (int k = 1; k < 500; ++k) {
      term *= q / (double(k) * double(k + nu));
      sum += term;
      if (term < 1e-17 * sum) break;
    }
    return sum * std::exp(-x);
  }
  // Hankel expansion: I_nu(x) ~ e^x / sqrt(2 pi x) * sum_k (-1)^k prod_j (mu - (2j-1)^2) /
  // (k! (8x)^k), mu = 4 nu^2; at x >= 100 the terms fall below 1e-17 within a few dozen.
  const double mu = 4.0 * double(nu * nu);
  double term = 1.0, sum = 1.0;
  for (int k = 1; k < 60; ++k) {
    const double odd = double(2 * k - 1);
    term *= -(mu - odd * odd) / (double(k) * 8.0 * x);
    sum += term;
    if (std::abs(term) < 1e-17 * std::abs(sum)) break;
  }
  return sum / std::sqrt(2.0 * kPi * x);
}

}  // namespace

double BesselI0Scaled(double x) {
  return BesselScaled(0, x);
}
double BesselI1Scaled(double x) {
  return BesselScaled(1, x);
}

double VonMisesMeanResultant(double kappa) {
  if (std::isinf(kappa)) return 1.0;
  return BesselI1Scaled(kappa) / BesselI0Scaled(kappa);
}

double GaussianNll(double error, double std) {
  const double u = error / std;
  return std::log(std) + 0.5 * std::log(2.0 * kPi) + 0.5 * u * u;
}

double VonMisesNll(double angle_error, double kappa) {
  // kappa (1 - cos d) = 2 kappa sin^2(d / 2) avoids the cancellation at large kappa.
  const double s = std::sin(0.5 * angle_error);
  return 2.0 * kappa * s * s + std::log(2.0 * kPi) + std::log(BesselI0Scaled(kappa));
}

}  // namespace internal

double LogBesselI0(double kappa) {
  SONICBOOM_DEMAND(kappa >= 0.0);
  return std::log(internal::BesselI0Scaled(kappa)) + kappa;
}

double GaussianIntervalHalfWidth(double probability) {
  SONICBOOM_DEMAND(probability > 0.0 && probability < 1.0);
  // sqrt(2) erfinv(p): a closed-form start (Winitzki), then Newton steps on erf.
  constexpr double a = 0.147;
  const double l = std::log(1.0 - probability * probability);
  const double b = 2.0 / (std::numbers::pi * a) + 0.5 * l;
  double x = std::sqrt(std::sqrt(b * b - l / a) - b);
  for (int i = 0; i < 50; ++i) {
    const double step =
        (std::erf(x) - probability) / (2.0 / std::sqrt(std::numbers::pi) * std::exp(-x * x));
    x -= step;
    if (std::abs(step) < 1e-15 * std::max(1.0, x)) break;
  }
  return std::sqrt(2.0) * x;
}

namespace {

// 16-point Gauss-Legendre rule on [-1, 1]: nodes by Newton iteration on P_16.
struct GaussLegendreRule {
  static constexpr int kPoints = 16;
  std::array<double, kPoints> node{}, weight{};
};

const GaussLegendreRule& Rule() {
  static const GaussLegendreRule rule = [] {
    constexpr int n = GaussLegendreRule::kPoints;
    GaussLegendreRule r;
    for (int i = 0; i < n; ++i) {
      double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
      double derivative = 1.0;
      for (int iteration = 0; iteration < 100; ++iteration) {
        // P_n(x) by the three-term recurrence, then P_n'(x)
        double p0 = 1.0, p1 = x;
        for (int k = 2; k <= n; ++k) {
          const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        derivative = n * (x * p1 - p0) / (x * x - 1.0);
        const double step = p1 / derivative;
        x -= step;
        if (std::abs(step) < 1e-16) break;
      }
      r.node[i] = x;
      r.weight[i] = 2.0 / ((1.0 - x * x) * derivative * derivative);
    }
    return r;
  }();
  return rule;
}

// The von Mises density around 0 up to its normalization: exp(kappa (cos x - 1)), written as
// exp(-2 kappa sin^2(x / 2)) so that it is exact for tiny x and huge kappa.
double PeakDensity(double kappa, double x) {
  const double s = std::sin(0.5 * x);
  return std::exp(-2.0 * kappa * s * s);
}

// Beyond this angle the density is below exp(-39) of its peak (1 - cos x >= 2 x^2 / pi^2).
double PeakSpan(double kappa) {
  return kappa > 0.0 ? std::min(std::numbers::pi, 14.0 / std::sqrt(kappa)) : std::numbers::pi;
}

// Integral of PeakDensity over [0, a] by composite Gauss-Legendre, with panels no wider than
// 1.5 standard deviations (1 / sqrt(kappa)) and pi / 4: near machine precision at any kappa.
double PeakIntegral(double kappa, double a) {
  if (a <= 0.0) return 0.0;
  const GaussLegendreRule& rule = Rule();
  const double panel = kappa > 0.0 ? std::min(std::numbers::pi / 4.0, 1.5 / std::sqrt(kappa))
                                   : std::numbers::pi / 4.0;
  const int panels = std::max(1, static_cast<int>(std::ceil(a / panel)));
  const double width = a / panels;
  double sum = 0.0;
  for (int p = 0; p < panels; ++p) {
    const double centre = (p + 0.5) * width;
    for (int i = 0; i < GaussLegendreRule::kPoints; ++i) {
      sum += rule.weight[i] * PeakDensity(kappa, centre + 0.5 * width * rule.node[i]);
    }
  }
  return 0.5 * width * sum;
}

}  // namespace

double VonMisesCentralProbability(double kappa, double half_width) {
  SONICBOOM_DEMAND(kappa >= 0.0);
  SONICBOOM_DEMAND(half_width >= 0.0);
  if (std::isinf(kappa)) return 1.0;
  const double span = PeakSpan(kappa);
  if (half_width >= span) return 1.0;
  return PeakIntegral(kappa, half_width) / PeakIntegral(kappa, span);
}

double VonMisesIntervalHalfWidth(double kappa, double probability) {
  SONICBOOM_DEMAND(probability > 0.0 && probability < 1.0);
  SONICBOOM_DEMAND(kappa >= 0.0);
  if (std::isinf(kappa)) return 0.0;
  // Solve integral(0, h) = probability * integral(0, span) by Newton's method (the derivative
  // is the density itself), falling back to bisection whenever a step leaves the bracket.
  const double span = PeakSpan(kappa);
  const double target = probability * PeakIntegral(kappa, span);
  double lo = 0.0, hi = span;
  double h = kappa > 0.0 ? std::min(GaussianIntervalHalfWidth(probability) / std::sqrt(kappa),
                                    probability * span)
                         : probability * span;
  for (int iteration = 0; iteration < 200; ++iteration) {
    const double f = PeakIntegral(kappa, h) - target;
    (f > 0.0 ? hi : lo) = h;
    double next = h - f / PeakDensity(kappa, h);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const bool done = std::abs(next - h) <= 1e-15 * span;
    h = next;
    if (done || hi - lo <= 1e-15 * span) break;
  }
  return h;
}

double VonMisesCircularStd(double kappa) {
  SONICBOOM_DEMAND(kappa >= 0.0);
  const double r = internal::VonMisesMeanResultant(kappa);
  if (r <= 0.0) return std::numeric_limits<double>::infinity();
  return std::sqrt(-2.0 * std::log(r));
}

Prediction ApplyCalibration(const Prediction& p, const UncertaintyCalibration& calibration) {
  Prediction out = p;
  if (!p.has_uncertainty()) return out;
  out.z_std_m = p.z_std_m * calibration.z_std_scale;
  out.theta_kappa = p.theta_kappa * calibration.kappa_scale;
  return out;
}

double VonMisesKappaForResultant(double r) {
  SONICBOOM_DEMAND(r >= 0.0 && r < 1.0);
  if (r == 0.0) return 0.0;
  // A(kappa) = I1 / I0 rises monotonically from 0 to 1: bisection on log kappa
  double lo = std::log(1e-8), hi = std::log(1e12);
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (internal::VonMisesMeanResultant(std::exp(mid)) < r ? lo : hi) = mid;
  }
  return std::exp(0.5 * (lo + hi));
}

Prediction CombinePredictions(const std::vector<Prediction>& members) {
  SONICBOOM_DEMAND(!members.empty());
  const double k = static_cast<double>(members.size());
  bool uncertainty = true;
  double z = 0.0, c = 0.0, s = 0.0;
  for (const Prediction& p : members) {
    uncertainty = uncertainty && p.has_uncertainty();
    z += p.z_m / k;
  }
  // first circular moment of the mixture (of the point estimates without uncertainty)
  for (const Prediction& p : members) {
    const double a = uncertainty ? internal::VonMisesMeanResultant(p.theta_kappa) : 1.0;
    c += a * std::cos(p.theta_rad) / k;
    s += a * std::sin(p.theta_rad) / k;
  }
  Prediction out;
  out.z_m = z;
  out.theta_rad = std::atan2(s, c);
  if (!uncertainty) return out;
  double variance = 0.0;
  for (const Prediction& p : members) {
    variance += (p.z_std_m * p.z_std_m + (p.z_m - z) * (p.z_m - z)) / k;
  }
  out.z_std_m = std::sqrt(variance);
  // a resultant of 0 (members pointing every way) is a uniform angle: kappa 0 is no
  // distribution (has_uncertainty), so it is kept just above
  out.theta_kappa = std::max(VonMisesKappaForResultant(std::min(std::hypot(c, s), 1.0 - 1e-15)),
                             1e-9);
  return out;
}

UncertaintyCalibration FitUncertaintyCalibration(const std::vector<Prediction>& predictions,
                                                 const FeatureSet& truth) {
  if (static_cast<int64_t>(predictions.size()) != truth.size() ||
      truth.theta_rad.size() != truth.z_m.size()) {
    throw SchemaError("FitUncertaintyCalibration: predictions and labels differ in number");
  }
  constexpr double kMinScale = UncertaintyCalibration::kMinScale;
  constexpr double kMaxScale = UncertaintyCalibration::kMaxScale;
  // Standardized height errors and (kappa, angle error) pairs of the usable records.
  double z_squares = 0.0;
  std::vector<double> kappas, cosines;
  for (size_t i = 0; i < predictions.size(); ++i) {
    const Prediction& p = predictions[i];
    if (!p.has_uncertainty() || !std::isfinite(truth.z_m[i]) ||
        !std::isfinite(truth.theta_rad[i])) {
      continue;
    }
    const double u = (truth.z_m[i] - p.z_m) / p.z_std_m;
    z_squares += u * u;
    kappas.push_back(p.theta_kappa);
    cosines.push_back(std::cos(truth.theta_rad[i] - p.theta_rad));
  }
  UncertaintyCalibration calibration;
  const size_t n = kappas.size();
  if (n == 0) return calibration;
  // Gaussian: mean NLL = log s + u^2 / (2 s^2) + const, minimal at s^2 = mean(u^2).
  calibration.z_std_scale = std::clamp(std::sqrt(z_squares / double(n)), kMinScale, kMaxScale);
  // von Mises: mean NLL(c) = mean(-c kappa cos d + log I0(c kappa)) is convex in c; its
  // derivative mean(kappa (A(c kappa) - cos d)) rises with c, so bisect on log c for its root.
  auto derivative = [&](double c) {
    double sum = 0.0;
    for (size_t i = 0; i < n; ++i) {
      sum += kappas[i] * (internal::VonMisesMeanResultant(c * kappas[i]) - cosines[i]);
    }
    return sum / double(n);
  };
  double lo = std::log(kMinScale), hi = std::log(kMaxScale);
  if (derivative(std::exp(lo)) >= 0.0) {
    calibration.kappa_scale = kMinScale;
  } else if (derivative(std::exp(hi)) <= 0.0) {
    calibration.kappa_scale = kMaxScale;
  } else {
    for (int iteration = 0; iteration < 80; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      (derivative(std::exp(mid)) < 0.0 ? lo : hi) = mid;
    }
    calibration.kappa_scale = std::exp(0.5 * (lo + hi));
  }
  return calibration;
}

}  // namespace sonicboom::learning

namespace sonicboom::learning {

UncertaintyCalibration FitCoverageCalibration(const std::vector<Prediction>& predictions,
                                              const FeatureSet& truth, double level) {
  if (static_cast<int64_t>(predictions.size()) != truth.size() ||
      truth.theta_rad.size() != truth.z_m.size()) {
    throw SchemaError("FitCoverageCalibration: predictions and labels differ in number");
  }
  SONICBOOM_DEMAND(level > 0.0 && level < 1.0);
  constexpr double kMinScale = UncertaintyCalibration::kMinScale;
  constexpr double kMaxScale = UncertaintyCalibration::kMaxScale;
  // standardized height errors |u|, and (kappa, |angle error|) of the usable records
  std::vector<double> z_scores, kappas, angles;
  for (size_t i = 0; i < predictions.size(); ++i) {
    const Prediction& p = predictions[i];
    if (!p.has_uncertainty() || !std::isfinite(truth.z_m[i]) ||
        !std::isfinite(truth.theta_rad[i])) {
      continue;
    }
    z_scores.push_back(std::abs(truth.z_m[i] - p.z_m) / p.z_std_m);
    kappas.push_back(p.theta_kappa);
    angles.push_back(std::abs(std::remainder(truth.theta_rad[i] - p.theta_rad, 2.0 * kPi)));
  }
  UncertaintyCalibration calibration;
  const size_t n = z_scores.size();
  if (n == 0) return calibration;
  // the conformal quantile: the ceil(level (n + 1))-th smallest score (the largest when n is
  // small), so that a new record of the same family is covered with probability >= level
  const size_t rank = std::min(n, static_cast<size_t>(std::ceil(level * double(n + 1)))) - 1;
  std::nth_element(z_scores.begin(), z_scores.begin() + static_cast<std::ptrdiff_t>(rank),
                   z_scores.end());
  calibration.z_std_scale =
      std::clamp(z_scores[rank] / GaussianIntervalHalfWidth(level), kMinScale, kMaxScale);
  // theta: the share covered at concentration scale c, a falling step function of c
  const auto covered = [&](double c) {
    size_t inside = 0;
    for (size_t i = 0; i < n; ++i) inside += VonMisesCentralProbability(c * kappas[i], angles[i]) <= level;
    return double(inside) / double(n);
  };
  const double target = double(rank + 1) / double(n);
  double lo = std::log(kMinScale), hi = std::log(kMaxScale);
  if (covered(std::exp(hi)) >= target) {
    calibration.kappa_scale = kMaxScale;
  } else if (covered(std::exp(lo)) < target) {
    calibration.kappa_scale = kMinScale;
  } else {
    // the largest c that still covers the target share: the narrowest honest intervals
    for (int iteration = 0; iteration < 60; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      (covered(std::exp(mid)) >= target ? lo : hi) = mid;
    }
    calibration.kappa_scale = std::exp(lo);
  }
  return calibration;
}

}  // namespace sonicboom::learning
