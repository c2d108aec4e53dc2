#pragma once
/// Sensor signals of the FD solver (shell_fd.h) under point forces: the reference rung of the
/// fidelity ladder. Forces are audio-rate sample means, placed mid-sample and linear between
/// samples at the FD substeps; the run stops (zeros after) once the forces are over and the
/// structure's energy has decayed by decay_floor_db.

#include <Eigen/Core>
#include <cstdint>
#include <span>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_fd.h"

namespace sonicboom::acoustics {

/// (outputs x samples) of sensor_rows (outputs x dofs) applied to the FD state at every audio
/// sample, from rest.
Eigen::MatrixXd FdRender(const ShellModel& model, const ShellFd& fd,
                         std::span<const ForceInput> forces, const Eigen::MatrixXd& sensor_rows,
                         int64_t samples, double decay_floor_db);

}  // namespace sonicboom::acoustics
