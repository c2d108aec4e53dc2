#include "sonicboom/solid/gll.h"

#include <cmath>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {
namespace {

// Legendre polynomials P_n(x) and P_{n-1}(x) by the three-term recurrence
void Legendre(int n, double x, double* p_n, double* p_nm1) {
  double p0 = 1.0, p1 = x;
  if (n == 0) {
    *p_n = 1.0;
    *p_nm1 = 0.0;
    return;
  }
  for (int k = 2; k <= n; ++k) {
    const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  *p_n = p1;
  *p_nm1 = p0;
}

}  // namespace

GllRule MakeGllRule(int degree) {
  SONICBOOM_DEMAND(degree >= 1 && degree <= 16);
  const int n = degree;
  GllRule rule;
  rule.points.resize(n + 1);
  rule.weights.resize(n + 1);
  Eigen::VectorXd p_n(n + 1);
  for (int i = 0; i <= n; ++i) {
    // interior points are the roots of P_n'; Newton on (x P_n - P_{n-1}) from Chebyshev points
    double x = -std::cos(std::numbers::pi * i / n);
    if (i > 0 && i < n) {
      for (int it = 0; it < 100; ++it) {
        double pn, pnm1;
        Legendre(n, x, &pn, &pnm1);
        const double dx = (x * pn - pnm1) / ((n + 1) * pn);
        x -= dx;
        if (std::abs(dx) < 1e-16) break;
      }
    }
    double pn, pnm1;
    Legendre(n, x, &pn, &pnm1);
    rule.points(i) = x;
    p_n(i) = pn;
    rule.weights(i) = 2.0 / (n * (n + 1.0) * pn * pn);
  }
  // l_j'(x_i) = P_n(x_i) / (P_n(x_j) (x_i - x_j)), i != j; the corners +-n(n+1)/4
  rule.derivative = Eigen::MatrixXd::Zero(n + 1, n + 1);
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      if (i != j) {
        rule.derivative(i, j) = p_n(i) / (p_n(j) * (rule.points(i) - rule.points(j)));
      }
    }
  }
  rule.derivative(0, 0) = -0.25 * n * (n + 1.0);
  rule.derivative(n, n) = 0.25 * n * (n + 1.0);
  return rule;
}

void LagrangeBasis(const GllRule& rule, double x, Eigen::VectorXd* values,
                   Eigen::VectorXd* slopes) {
  const int m = static_cast<int>(rule.points.size());
  values->resize(m);
  slopes->resize(m);
  for (int j = 0; j < m; ++j) {
    // l_j(x) = prod_{k != j} (x - x_k) / (x_j - x_k); its slope by the product rule
    double value = 1.0, slope = 0.0;
    for (int k = 0; k < m; ++k) {
      if (k == j) continue;
      const double d = rule.points(j) - rule.points(k);
      slope = (slope * (x - rule.points(k)) + value) / d;
      value *= (x - rule.points(k)) / d;
    }
    (*values)(j) = value;
    (*slopes)(j) = slope;
  }
}

}  // namespace sonicboom::solid
