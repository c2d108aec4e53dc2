#pragma once
/// Gauss-Lobatto-Legendre (GLL) points and the Lagrange basis through them: the 1-D building block
/// of the spectral elements (nodes = quadrature points, so the mass matrix is diagonal).

#include <Eigen/Core>

namespace sonicboom::solid {

/// The GLL rule of a polynomial degree on [-1, 1]: degree + 1 points, ascending, ends included.
struct GllRule {
  Eigen::VectorXd points;      // (degree + 1) in [-1, 1]
  Eigen::VectorXd weights;     // (degree + 1) quadrature weights, sum 2
  Eigen::MatrixXd derivative;  // (degree + 1)^2: derivative(i, j) = l_j'(points(i))
  int degree() const { return static_cast<int>(points.size()) - 1; }
};

/// The rule of `degree` (1 to 16); exact for polynomials up to degree 2 degree - 1.
GllRule MakeGllRule(int degree);

/// The Lagrange basis through rule.points at x: values(j) = l_j(x), slopes(j) = l_j'(x).
void LagrangeBasis(const GllRule& rule, double x, Eigen::VectorXd* values, Eigen::VectorXd* slopes);

}  // namespace sonicboom::solid
