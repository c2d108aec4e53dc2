#pragma once
/// Real captures: a multichannel WAV from the DAQ plus an optional robot log, read into the
/// same form as simulated strikes so that features and models treat both alike.

#include <Eigen/Core>
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
/// short row or a non-numeric value.
Eigen::MatrixXf ReadProprioCsv(const std::string& path);

/// Writes the same format (for sim-to-real round trips and tests). Written atomically.
void WriteProprioCsv(const std::string& path, const Eigen::MatrixXf& proprio, double rate_hz);

/// Loads a capture; checks the channel count and sample rate against what the model expects
/// (IoError naming the file otherwise).
Capture LoadCapture(const std::string& wav_path, const std::string& proprio_csv_path,
                    int expected_channels, double expected_sample_rate_hz);

}  // namespace sonicboom::hardware
