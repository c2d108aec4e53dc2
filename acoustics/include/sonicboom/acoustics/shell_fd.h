#pragma once
/// Finite-difference time-domain solver of the discretized shell (shell.h): central differences
/// in time on M u'' + C u' + K u = f, C = alpha M + beta K, with the alpha term centred and the
/// beta term backward (explicit, since M is diagonal):
///   M (u+ - 2u + u-)/k^2 + alpha M (u+ - u-)/(2k) + beta K (u - u-)/k + K u = f.
/// Stability (von Neumann on every mode): k <= (2/w_max)(sqrt(1 + z^2) - z), z = beta w_max / 2,
/// where w_max^2 is the largest eigenvalue of M^-1 K, computed from the assembled operator
/// (Lanczos). Without loss the scheme conserves the discrete energy
///   H = 1/2 ((u+ - u)/k)^T M ((u+ - u)/k) + 1/2 u+^T K u
/// to round-off. Space is second order (shell.h), time second order without loss.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <span>

#include "sonicboom/acoustics/shell.h"

namespace sonicboom::acoustics {

/// Solver state: displacements at the last two steps (dofs each), m.
struct ShellFdState {
  Eigen::VectorXd previous;
  Eigen::VectorXd current;
};

class ShellFd {
 public:
  /// Steps `oversampling` times per audio sample; 0 = the smallest stable integer (with 2 %
  /// margin). A stated oversampling whose step exceeds the stability limit throws ConfigError
  /// naming the limit and the smallest stable oversampling.
  ShellFd(const ShellModel& model, double sample_rate_hz, int64_t oversampling);

  double timestep_s() const { return k_s_; }
  double stability_limit_s() const { return k_max_s_; }
  double omega_max_rad_s() const { return omega_max_; }
  int64_t oversampling() const { return oversampling_; }

  ShellFdState Rest() const;
  /// One step with nodal force f (dofs, N), in place.
  void Step(ShellFdState* state, const Eigen::VectorXd& force_n) const;
  /// Discrete energy between the last two steps, J.
  double Energy(const ShellFdState& state) const;

  /// Runs from rest: a radial force force_n (audio-rate samples, N; linear between them) applied
  /// through force_weights (dofs), and returns sensor_rows (outputs x dofs) applied to the state
  /// at every audio sample, (outputs x samples).
  Eigen::MatrixXd Run(const Eigen::VectorXd& force_weights, std::span<const double> force_n,
                      const Eigen::MatrixXd& sensor_rows, int64_t samples) const;

 private:
  const ShellModel& model_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness_;
  Eigen::VectorXd inv_mass_;
  double sample_rate_hz_{0.0};
  int64_t oversampling_{1};
  double k_s_{0.0}, k_max_s_{0.0}, omega_max_{0.0};
  double alpha_{0.0}, beta_{0.0};
};

}  // namespace sonicboom::acoustics
