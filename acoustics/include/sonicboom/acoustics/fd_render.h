#pragma once
/// Sensor signals of the FD solver (shell_fd.h): the cross-check rung of the fidelity ladder.
///
/// Two kinds of load. Prescribed forces (ForceInput: audio-rate sample means, placed mid-sample
/// and linear between samples at the FD substeps). Impacts (FdImpact) solved against the FD wall
/// itself, step by step: the Hertz spring between the striker (rigid mass plus beam modes) and
/// the wall point (the grid's own displacement there, plus the robot-side mass) is closed
/// implicitly in the force at every FD step (the force that makes the compression at the end of
/// the step consistent with it), so no contact stiffness can destabilize the explicit scheme. The
/// wall's response to the impact is then the FD grid's, not the modal wall's.
///
/// Output: the sensor rows applied at every FD substep, low-passed by a Blackman-windowed sinc
/// (cut-off 0.45 of the audio rate, 64 audio samples long, zero phase) and decimated to the
/// audio rate, so the grid's modes above the audio Nyquist frequency do not alias into the band.
/// The run stops (zeros after) once the loads are over and the energy decayed by decay_floor_db.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_fd.h"

namespace sonicboom::acoustics {

/// An impact on the FD wall: the striker approaching the tube at approach_speed_m_s, first touch
/// at time_s (from the record start) at (z, theta).
struct FdImpact {
  double time_s{0.0};
  double z_m{0.0};
  double theta_rad{0.0};
  double approach_speed_m_s{0.0};
  double tube_side_kg{0.0};  // robot-side rigid mass of the tube; inf or <= 0 = held
  DrivingPoint striker;      // rigid mass plus modes at the contact (contact.h)
  double stiffness_n_m15{0.0};
};

/// An FD run: the sensor signals and, per impact, its force on the wall as SolveContact reports
/// it (audio-rate sample means, positive inward; duration, touches, peak, impulse).
struct FdRun {
  Eigen::MatrixXd strain;  // (outputs x samples)
  std::vector<ContactForce> impacts;
};

/// sensor_rows (outputs x dofs) applied to the FD state, from rest, for `samples` audio samples.
/// contact: the Hertz damping, separation window and time limit of the impacts (ContactConfig);
/// throws NumericalError naming acoustics.contact.max_duration_s when an impact is still closed
/// after it.
FdRun FdRender(const ShellModel& model, const ShellFd& fd, std::span<const ForceInput> forces,
               std::span<const FdImpact> impacts, const ContactConfig& contact,
               const Eigen::MatrixXd& sensor_rows, int64_t samples, double decay_floor_db);

/// Prescribed forces only.
Eigen::MatrixXd FdRender(const ShellModel& model, const ShellFd& fd,
                         std::span<const ForceInput> forces, const Eigen::MatrixXd& sensor_rows,
                         int64_t samples, double decay_floor_db);

}  // namespace sonicboom::acoustics
