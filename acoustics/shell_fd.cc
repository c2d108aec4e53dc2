#include "sonicboom/acoustics/shell_fd.h"

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymEigsSolver.h>
#include <algorithm>
#include <cmath>
#include <vector>

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
  Spectra::SymEigsSolver<Spectra::SparseSymMatProd<double>> solver(op, 1,
                                                                   std::min<Eigen::Index>(n, 40));
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
  const int64_t smallest =
      static_cast<int64_t>(std::ceil(1.0 / (sample_rate_hz * k_max_s_ * kAutoMargin)));
  if (oversampling == 0) {
    oversampling_ = std::max<int64_t>(smallest, 1);
  } else {
    oversampling_ = oversampling;
    const double k = 1.0 / (sample_rate_hz * static_cast<double>(oversampling));
    if (k > k_max_s_) {
      throw ConfigError(fmt::format(
          "fd.oversampling = {} gives a timestep of {:.4g} us, above the scheme's stability limit "
          "of {:.4g} us (2/w_max (sqrt(1 + z^2) - z), w_max = {:.4g} rad/s from the grid, z = "
          "{:.3g}); "
          "use fd.oversampling >= {} or a coarser shell.grid_spacing_m",
          oversampling, 1e6 * k, 1e6 * k_max_s_, omega_max_, zeta,
          static_cast<int64_t>(std::ceil(1.0 / (sample_rate_hz * k_max_s_)))));
    }
  }
  k_s_ = 1.0 / (sample_rate_hz * static_cast<double>(oversampling_));
  // the step's combined coefficients: u+ = c_u u - c_prev u- - c_force (K v - f)
  const double a = 0.5 * alpha_ * k_s_;
  c_u_ = 2.0 / (1.0 + a);
  c_prev_ = (1.0 - a) / (1.0 + a);
  c_v_ = beta_ / k_s_;
  c_force_ = ((k_s_ * k_s_) / (1.0 + a)) * inv_mass_;
  // K's upper triangle by rows, the diagonal first in each row (K is symmetric: this halves the
  // bytes a step streams; the assembled K is symmetric to 1 ulp, the upper one exactly)
  stiffness_.makeCompressed();
  const Eigen::Index n = stiffness_.rows();
  upper_row_.assign(1, 0);
  upper_col_.clear();
  upper_val_.clear();
  for (Eigen::Index i = 0; i < n; ++i) {
    upper_col_.push_back(static_cast<int32_t>(i));
    upper_val_.push_back(stiffness_.coeff(i, i));
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(stiffness_, i); it; ++it) {
      if (it.col() > i) {
        upper_col_.push_back(static_cast<int32_t>(it.col()));
        upper_val_.push_back(it.value());
      }
    }
    upper_row_.push_back(static_cast<int32_t>(upper_col_.size()));
  }
}

ShellFdState ShellFd::Rest() const {
  return {Eigen::VectorXd::Zero(model_.dofs()), Eigen::VectorXd::Zero(model_.dofs())};
}

void ShellFd::Step(ShellFdState* state, const Eigen::VectorXd& force_n) const {
  SONICBOOM_DEMAND(force_n.size() == model_.dofs());
  StepScaled(state, force_n.data(), 1.0);
}

void ShellFd::StepScaled(ShellFdState* state, const double* force, double force_scale) const {
  const Eigen::Index n = model_.dofs();
  SONICBOOM_DEMAND(state->current.size() == n && state->previous.size() == n);
  double* const u_prev = state->previous.data();
  const double* const u = state->current.data();
  // per-thread buffers reused across steps: v = u + beta (u - u-)/k (dofs, m) and the part of
  // (K v)_i scattered from the rows above i (dofs, N)
  thread_local std::vector<double> v_buffer, lower_buffer;
  v_buffer.resize(static_cast<size_t>(n));
  lower_buffer.resize(static_cast<size_t>(n));
  double* const v = v_buffer.data();
  double* const lower = lower_buffer.data();
  // coefficients in locals: the scatter's stores could otherwise alias the members
  const double c_v = c_v_, c_u = c_u_, c_prev = c_prev_;
  for (Eigen::Index i = 0; i < n; ++i) {
    v[i] = u[i] + c_v * (u[i] - u_prev[i]);
    lower[i] = 0.0;
  }
  // one pass over the upper triangle: row i gathers K_ij v_j (j >= i) and scatters K_ij v_i to
  // row j > i, so (K v)_i is complete at row i and u+_i goes straight into u-'s storage
  const int32_t* const row = upper_row_.data();
  const int32_t* const col = upper_col_.data();
  const double* const val = upper_val_.data();
  const double* const c_force = c_force_.data();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double v_i = v[i];
    const int32_t end = row[i + 1];
    int32_t p = row[i];
    double upper = val[p] * v_i;  // the diagonal leads each row
    for (++p; p < end; ++p) {
      const int32_t j = col[p];
      upper += val[p] * v[j];
      lower[j] += val[p] * v_i;
    }
    const double kv = lower[i] + upper;
    u_prev[i] = c_u * u[i] - c_prev * u_prev[i] - c_force[i] * (kv - force_scale * force[i]);
  }
  state->current.swap(state->previous);
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
  const auto force_at = [&](int64_t sample, double frac) {
    const auto at = [&](int64_t s) {
      return s >= 0 && s < static_cast<int64_t>(force_n.size()) ? force_n[static_cast<size_t>(s)]
                                                                : 0.0;
    };
    return (1.0 - frac) * at(sample) + frac * at(sample + 1);
  };
  for (int64_t s = 0; s < samples; ++s) {
    out.col(s).noalias() = sensor_rows * state.current;
    for (int64_t sub = 0; sub < oversampling_; ++sub) {
      const double frac = static_cast<double>(sub) / static_cast<double>(oversampling_);
      StepScaled(&state, force_weights.data(), force_at(s, frac));
    }
  }
  return out;
}

}  // namespace sonicboom::acoustics
