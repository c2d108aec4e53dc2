#include "sonicboom/acoustics/shell_fd.h"

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymEigsSolver.h>
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// the largest eigenvalue is taken this much larger than Lanczos reports (its residual bound)
constexpr double kLambdaMargin = 1e-6;
// an automatic oversampling keeps the step this far inside the limit
constexpr double kAutoMargin = 0.98;

// Largest eigenvalue of M^-1 K (rad^2/s^2), from M^-1/2 K M^-1/2 by Lanczos
double LargestEigenvalue(const ShellModel& model) {
  const Eigen::SparseMatrix<double> a = model.MassScaledStiffness();
  Spectra::SparseSymMatProd<double> op(a);
  const Eigen::Index n = a.rows();
  Spectra::SymEigsSolver<Spectra::SparseSymMatProd<double>> solver(op, 1, std::min<Eigen::Index>(n, 40));
  solver.init();
  solver.compute(Spectra::SortRule::LargestAlge, 5000, 1e-12);
  if (solver.info() != Spectra::CompInfo::Successful) {
    throw Error("shell FD: the largest eigenvalue of the stiffness did not converge");
  }
  return solver.eigenvalues()[0] * (1.0 + kLambdaMargin);
}

}  // namespace

ShellFd::ShellFd(const ShellModel& model, double sample_rate_hz, int64_t oversampling)
    : model_(model), stiffness_(model.stiffness()), sample_rate_hz_(sample_rate_hz) {
  if (!(sample_rate_hz > 0.0)) {
    throw ConfigError(fmt::format("audio.sample_rate_hz = {} must be positive", sample_rate_hz));
  }
  if (oversampling < 0) {
    throw ConfigError(fmt::format("fd.oversampling = {} must be >= 0 (0 = derived)", oversampling));
  }
  inv_mass_ = model.mass_kg().cwiseInverse();
  alpha_ = model.rayleigh_alpha_1_s();
  beta_ = model.rayleigh_beta_s();
  omega_max_ = std::sqrt(LargestEigenvalue(model));
  const double zeta = 0.5 * beta_ * omega_max_;
  k_max_s_ = (2.0 / omega_max_) * (std::sqrt(1.0 + zeta * zeta) - zeta);
  const int64_t smallest = static_cast<int64_t>(std::ceil(1.0 / (sample_rate_hz * k_max_s_ * kAutoMargin)));
  if (oversampling == 0) {
    oversampling_ = std::max<int64_t>(smallest, 1);
  } else {
    oversampling_ = oversampling;
    const double k = 1.0 / (sample_rate_hz * static_cast<double>(oversampling));
    if (k > k_max_s_) {
      throw ConfigError(fmt::format(
          "fd.oversampling = {} gives a timestep of {:.4g} us, above the scheme's stability limit "
          "of {:.4g} us (2/w_max (sqrt(1 + z^2) - z), w_max = {:.4g} rad/s from the grid, z = {:.3g}); "
          "use fd.oversampling >= {} or a coarser shell.grid_spacing_m",
          oversampling, 1e6 * k, 1e6 * k_max_s_, omega_max_, zeta,
          static_cast<int64_t>(std::ceil(1.0 / (sample_rate_hz * k_max_s_)))));
    }
  }
  k_s_ = 1.0 / (sample_rate_hz * static_cast<double>(oversampling_));
}

ShellFdState ShellFd::Rest() const {
  return {Eigen::VectorXd::Zero(model_.dofs()), Eigen::VectorXd::Zero(model_.dofs())};
}

void ShellFd::Step(ShellFdState* state, const Eigen::VectorXd& force_n) const {
  const double k = k_s_;
  Eigen::VectorXd& u_prev = state->previous;
  Eigen::VectorXd& u = state->current;
  // K (u + beta (u - u-)/k), then u+ into u_prev's storage
  const Eigen::VectorXd ku = stiffness_ * (u + (beta_ / k) * (u - u_prev));
  const double a = 0.5 * alpha_ * k;
  u_prev = ((2.0 * u - (1.0 - a) * u_prev -
             (k * k) * inv_mass_.cwiseProduct(ku - force_n)) / (1.0 + a)).eval();
  u.swap(u_prev);
}

double ShellFd::Energy(const ShellFdState& state) const {
  const Eigen::VectorXd velocity = (state.current - state.previous) / k_s_;
  const double kinetic = 0.5 * velocity.dot(model_.mass_kg().cwiseProduct(velocity));
  const double potential = 0.5 * state.current.dot(stiffness_ * state.previous);
  return kinetic + potential;
}

Eigen::MatrixXd ShellFd::Run(const Eigen::VectorXd& force_weights, std::span<const double> force_n,
                             const Eigen::MatrixXd& sensor_rows, int64_t samples) const {
  SONICBOOM_DEMAND(force_weights.size() == model_.dofs() && sensor_rows.cols() == model_.dofs());
  Eigen::MatrixXd out(sensor_rows.rows(), samples);
  ShellFdState state = Rest();
  Eigen::VectorXd f(model_.dofs());
  const auto force_at = [&](int64_t sample, double frac) {
    const auto at = [&](int64_t s) {
      return s >= 0 && s < static_cast<int64_t>(force_n.size()) ? force_n[static_cast<size_t>(s)] : 0.0;
    };
    return (1.0 - frac) * at(sample) + frac * at(sample + 1);
  };
  for (int64_t s = 0; s < samples; ++s) {
    out.col(s) = sensor_rows * state.current;
    for (int64_t sub = 0; sub < oversampling_; ++sub) {
      const double frac = static_cast<double>(sub) / static_cast<double>(oversampling_);
      f = force_at(s, frac) * force_weights;
      Step(&state, f);
    }
  }
  return out;
}

}  // namespace sonicboom::acoustics
