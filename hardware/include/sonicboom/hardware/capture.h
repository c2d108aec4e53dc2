#pragma once
/// Real captures: a multichannel WAV from the DAQ plus an optional robot log, read into the
/// same form as simulated strikes so that features and models treat both alike.

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace sonicboom::hardware {

/// One recorded strike.
struct Capture {
  Eigen::MatrixXf audio;  // (channels x T), full scale 1
  double sample_rate_hz{0.0};
  Eigen::MatrixXf proprio;  // (K x 10) pos m, quat wxyz, vel m/s in the base frame; empty if none
};

/// Reads a robot log CSV: a header line naming the columns, then one row per 100 Hz tick with
/// columns t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s (tube frame in the robot base
/// frame). Throws IoError naming the file and line for a missing file, a wrong header, a
/// short row, a non-numeric or non-finite value, or one no arm produces: a position beyond
/// 10 m, a quaternion whose norm is not within 10 % of one, a speed above 10 m/s, times that
/// do not increase.
Eigen::MatrixXf ReadProprioCsv(const std::string& path);

/// Writes the same format (for sim-to-real round trips and tests). Written atomically.
void WriteProprioCsv(const std::string& path, const Eigen::MatrixXf& proprio, double rate_hz);

/// What a recorded strike must be to be analysed like a simulated one.
struct CaptureChecks {
  int channels{6};                 // one per mic
  double sample_rate_hz{44100.0};  // the rig's
  int64_t min_frames{1};           // shorter records hold no strike the model could read
};

/// Loads a capture. IoError naming the file (and the frame or channel) unless it has the rig's
/// channels and rate, at least min_frames frames, finite samples within full scale (|x| <= 1: a
/// float WAV scaled in volts or counts is refused) and no silent (all-zero) channel; the robot
/// log as ReadProprioCsv checks it.
Capture LoadCapture(const std::string& wav_path, const std::string& proprio_csv_path,
                    const CaptureChecks& checks);

}  // namespace sonicboom::hardware
