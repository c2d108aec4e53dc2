#include "sonicboom/acoustics/shell_synth.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <unsupported/Eigen/MatrixFunctions>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {

Eigen::MatrixXd ModalRun(const ShellModel& model, const ShellModes& modes,
                         const Eigen::VectorXd& force_weights, std::span<const double> force_n,
                         const Eigen::MatrixXd& sensor_rows, int64_t samples, double sample_rate_hz,
                         bool residual) {
  SONICBOOM_DEMAND(modes.shapes.rows() == model.dofs() && force_weights.size() == model.dofs() &&
                   sensor_rows.cols() == model.dofs());
  const Eigen::Index n_modes = modes.omega_rad_s.size();
  const double T = 1.0 / sample_rate_hz;
  // modal input b_n = phi_n^T w and sensor gains c_in = S_i phi_n
  const Eigen::VectorXd input = modes.shapes.transpose() * force_weights;  // (modes)
  const Eigen::MatrixXd gain = sensor_rows * modes.shapes;                 // (outputs x modes)

  // exact one-step maps for a force linear over the step: augmented state (q, q', F, F')
  Eigen::MatrixXd phi11(n_modes, 4), gam(n_modes, 4);  // rows: [E11 (2x2) | E12 (2x2)] flattened
  for (Eigen::Index k = 0; k < n_modes; ++k) {
    const double w = modes.omega_rad_s[k];
    const double zeta = model.DampingRatio(w);
    Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
    a(0, 1) = 1.0;
    a(1, 0) = -w * w;
    a(1, 1) = -2.0 * zeta * w;
    a(1, 2) = input[k];
    a(2, 3) = 1.0;
    const Eigen::Matrix4d e = (a * T).exp();
    phi11.row(k) << e(0, 0), e(0, 1), e(1, 0), e(1, 1);
    gam.row(k) << e(0, 2), e(0, 3), e(1, 2), e(1, 3);
  }

  // static part of the missing modes at the sensors: S (K^-1 w - sum phi b / w^2)
  Eigen::VectorXd static_gain = Eigen::VectorXd::Zero(sensor_rows.rows());
  if (residual) {
    if (modes.rigid_body_modes > 0) {
      throw ConfigError(
          "the residual correction needs a structure without rigid-body modes (add "
          "mounts or supported ends)");
    }
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(model.stiffness());
    SONICBOOM_DEMAND(ldlt.info() == Eigen::Success);
    Eigen::VectorXd flex = ldlt.solve(force_weights);
    for (Eigen::Index k = 0; k < n_modes; ++k) {
      flex -= modes.shapes.col(k) * (input[k] / (modes.omega_rad_s[k] * modes.omega_rad_s[k]));
    }
    static_gain = sensor_rows * flex;
  }

  auto force = [&](int64_t s) {
    return s >= 0 && s < static_cast<int64_t>(force_n.size()) ? force_n[static_cast<size_t>(s)]
                                                              : 0.0;
  };
  Eigen::MatrixXd out(sensor_rows.rows(), samples);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(n_modes), qd = Eigen::VectorXd::Zero(n_modes);
  for (int64_t s = 0; s < samples; ++s) {
    out.col(s) = gain * q + static_gain * force(s);
    const double f0 = force(s), slope = (force(s + 1) - f0) / T;
    for (Eigen::Index k = 0; k < n_modes; ++k) {
      const double qn =
          phi11(k, 0) * q[k] + phi11(k, 1) * qd[k] + gam(k, 0) * f0 + gam(k, 1) * slope;
      const double qdn =
          phi11(k, 2) * q[k] + phi11(k, 3) * qd[k] + gam(k, 2) * f0 + gam(k, 3) * slope;
      q[k] = qn;
      qd[k] = qdn;
    }
  }
  return out;
}

}  // namespace sonicboom::acoustics
