#pragma once
/// Modal synthesis on the numerical modes of the discretized shell (shell_modes.h): each mode is
/// integrated exactly for a force that is linear between audio samples (the same input the FD
/// solver sees), and the modes left out above the band are restored by their static (residual
/// flexibility) part, (K^-1 - sum_n phi_n phi_n^T / w_n^2) f. The reference against which the FD
/// solver is checked, and the modal rung's accurate path.

#include <Eigen/Core>
#include <cstdint>
#include <span>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"

namespace sonicboom::acoustics {

/// Sensor signals (outputs x samples) of the structure from rest under the radial force force_n
/// (audio-rate samples, N; linear between them) applied through force_weights (dofs), with
/// sensor_rows (outputs x dofs). residual = true adds the static part of the missing modes (needs
/// a structure without rigid-body modes). Modal damping: model.DampingRatio(omega_n).
Eigen::MatrixXd ModalRun(const ShellModel& model, const ShellModes& modes,
                         const Eigen::VectorXd& force_weights, std::span<const double> force_n,
                         const Eigen::MatrixXd& sensor_rows, int64_t samples, double sample_rate_hz,
                         bool residual);

}  // namespace sonicboom::acoustics
