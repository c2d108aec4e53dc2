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
///
/// Speed: a step is one fused pass over K's upper triangle (K is symmetric; row i gathers
/// K_ij v_j for j >= i and scatters K_ij v_i to the rows j > i) that writes u+ row by row, after a
/// pass forming v = u + beta (u - u-)/k; no allocation per step. Measured on one core of the
/// 2-core Xeon dev VM (shared; best of interleaved bursts), against the acceptance bound
/// min(triad bandwidth at the same working set / full-CSR bytes, peak flops / flops):
/// default grid (24k DOFs, 465k nonzeros, 6.6 MB/step, in L3) 2.7-2.9k steps/s = 0.84-0.85 of
/// the bound (was 1.4-1.7k, 0.45-0.53); 5 mm x 10 mm grid 11.9-12.4k steps/s = 0.70-0.75 (was
/// 0.48-0.51). Against the bytes of the upper triangle actually streamed (4.0 / 0.97 MB) it is
/// 0.46-0.48 / 0.27-0.29: the gather-scatter loop is core-bound (~3-4 cycles per stored entry),
/// not memory-bound. Command:
///   ./build-fd/bin/fd_bench --benchmark_filter=FdStep   (bench/fd_bench.cc)

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <span>
#include <vector>

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
  /// (dofs) what a step adds to each DOF's new displacement per N of nodal force on it, m/N
  /// (k^2 / (m (1 + alpha k / 2))): the wall's compliance within one step.
  const Eigen::VectorXd& force_gain() const { return c_force_; }

  ShellFdState Rest() const;
  /// One step with nodal force f (dofs, N), in place. Safe to call from several threads on
  /// separate states (the scratch is per thread).
  void Step(ShellFdState* state, const Eigen::VectorXd& force_n) const;
  /// Discrete energy between the last two steps, J.
  double Energy(const ShellFdState& state) const;

  /// Runs from rest: a radial force force_n (audio-rate samples, N; linear between them) applied
  /// through force_weights (dofs), and returns sensor_rows (outputs x dofs) applied to the state
  /// at every audio sample, (outputs x samples).
  Eigen::MatrixXd Run(const Eigen::VectorXd& force_weights, std::span<const double> force_n,
                      const Eigen::MatrixXd& sensor_rows, int64_t samples) const;

 private:
  /// One step with the nodal force force_scale * force (dofs, N): a fused pass over the rows.
  void StepScaled(ShellFdState* state, const double* force, double force_scale) const;

  const ShellModel& model_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness_;
  Eigen::VectorXd inv_mass_;
  double sample_rate_hz_{0.0};
  int64_t oversampling_{1};
  double k_s_{0.0}, k_max_s_{0.0}, omega_max_{0.0};
  double alpha_{0.0}, beta_{0.0};
  // the update u+ = c_u u - c_prev u- - c_force (K v - f), v = u + c_v (u - u-), divided out
  double c_u_{2.0}, c_prev_{1.0}, c_v_{0.0};
  Eigen::VectorXd c_force_;  // (dofs) k^2 / (m (1 + alpha k / 2)), m/N
  // K's upper triangle as CSR (N/m): row starts (dofs + 1), columns and values (diagonal first)
  std::vector<int32_t> upper_row_, upper_col_;
  std::vector<double> upper_val_;
};

}  // namespace sonicboom::acoustics
