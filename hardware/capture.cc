#include "sonicboom/hardware/capture.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"

namespace sonicboom::hardware {
namespace {

const char* kProprioHeader = "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s";

// Limits no Panda log exceeds (its reach is under 1 m, its flange under 2 m/s): beyond them a
// value is in other units or damage, and would turn into non-finite features.
constexpr double kMaxPositionM = 10.0;
constexpr double kMaxSpeedMS = 10.0;
constexpr double kQuaternionNormTolerance = 0.1;

// One log row (t, x, y, z, qw, qx, qy, qz, vx, vy, vz) against those limits; times increase.
void CheckPlausibleRow(const std::string& path, int line_no, const std::array<double, 11>& v,
                       const double* previous_time_s) {
  if (previous_time_s != nullptr && !(v[0] > *previous_time_s)) {
    throw IoError(fmt::format("{}:{}: t_s = {} does not follow the previous row's {}", path,
                              line_no, v[0], *previous_time_s));
  }
  const double position_m = std::sqrt(v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
  if (position_m > kMaxPositionM) {
    throw IoError(
        fmt::format("{}:{}: the tube lies {:.3g} m from the robot base (at most {} m; "
                    "positions are in metres)",
                    path, line_no, position_m, kMaxPositionM));
  }
  const double norm = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw IoError(
        fmt::format("{}:{}: the orientation quaternion (qw, qx, qy, qz) has norm {:.4g}, "
                    "not 1",
                    path, line_no, norm));
  }
  const double speed_m_s = std::sqrt(v[8] * v[8] + v[9] * v[9] + v[10] * v[10]);
  if (speed_m_s > kMaxSpeedMS) {
    throw IoError(
        fmt::format("{}:{}: the tube moves at {:.3g} m/s (at most {} m/s; velocities "
                    "are in m/s)",
                    path, line_no, speed_m_s, kMaxSpeedMS));
  }
}

}  // namespace

Eigen::MatrixXf ReadProprioCsv(const std::string& path) {
  RequireReadableFile(path);
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open robot log", path));
  std::string line;
  if (!std::getline(in, line)) throw IoError(fmt::format("{}: empty robot log", path));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line != kProprioHeader) {
    // a header-like line is shown; anything else (another kind of file) is not echoed
    const bool header_like =
        line.size() <= 200 && std::all_of(line.begin(), line.end(), [](char c) {
          return std::islower(static_cast<unsigned char>(c)) ||
                 std::isdigit(static_cast<unsigned char>(c)) || c == '_' || c == ',';
        });
    throw IoError(fmt::format("{}:1: expected header '{}', found {}", path, kProprioHeader,
                              header_like ? "'" + line + "'"
                                          : fmt::format("a line of {} characters that is not a "
                                                        "CSV header (not a robot log?)",
                                                        line.size())));
  }
  // rows of 11 numbers; the time column is checked, then dropped
  std::vector<std::array<float, 10>> rows;
  double last_time_s = 0.0;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    std::stringstream ss(line);
    std::string cell;
    std::array<double, 11> values{};
    int col = 0;
    while (std::getline(ss, cell, ',')) {
      if (col >= 11) throw IoError(fmt::format("{}:{}: more than 11 columns", path, line_no));
      try {
        size_t used = 0;
        values[col] = std::stod(cell, &used);
        if (used != cell.size() && cell.substr(used) != "\r") throw std::invalid_argument(cell);
      } catch (const std::exception&) {
        throw IoError(
            fmt::format("{}:{}: column {} is not a number: '{}'", path, line_no, col + 1, cell));
      }
      if (!std::isfinite(values[col])) {
        throw IoError(fmt::format("{}:{}: column {} is not finite", path, line_no, col + 1));
      }
      ++col;
    }
    if (col != 11)
      throw IoError(fmt::format("{}:{}: expected 11 columns, found {}", path, line_no, col));
    CheckPlausibleRow(path, line_no, values, rows.empty() ? nullptr : &last_time_s);
    last_time_s = values[0];
    std::array<float, 10> row;
    for (int j = 0; j < 10; ++j) row[j] = static_cast<float>(values[j + 1]);
    rows.push_back(row);
  }
  if (rows.empty()) throw IoError(fmt::format("{}: robot log has no rows", path));
  Eigen::MatrixXf proprio(rows.size(), 10);
  for (size_t r = 0; r < rows.size(); ++r) {
    for (int j = 0; j < 10; ++j) proprio(r, j) = rows[r][j];
  }
  return proprio;
}

void WriteProprioCsv(const std::string& path, const Eigen::MatrixXf& proprio, double rate_hz) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial);
    if (!out) throw IoError(fmt::format("{}: cannot write robot log", path));
    out << kProprioHeader << "\n";
    for (int64_t r = 0; r < proprio.rows(); ++r) {
      out << fmt::format("{}", r / rate_hz);
      for (int64_t j = 0; j < proprio.cols(); ++j) out << fmt::format(",{}", proprio(r, j));
      out << "\n";
    }
    if (!out) throw IoError(fmt::format("{}: write failed", path));
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec)
    throw IoError(fmt::format("{}: cannot rename {} into place: {}", path, partial, ec.message()));
}

Capture LoadCapture(const std::string& wav_path, const std::string& proprio_csv_path,
                    const CaptureChecks& checks) {
  Capture capture;
  const AudioClip clip = ReadWav(wav_path, checks.channels);
  if (std::abs(clip.sample_rate_hz - checks.sample_rate_hz) > 1e-6) {
    throw IoError(fmt::format("{}: sample rate {} Hz, the model expects {} Hz", wav_path,
                              clip.sample_rate_hz, checks.sample_rate_hz));
  }
  if (clip.frames() < checks.min_frames) {
    throw IoError(
        fmt::format("{}: {} frames ({:.4f} s), shorter than the {} frames ({:.4f} s) "
                    "a strike record needs",
                    wav_path, clip.frames(), clip.frames() / clip.sample_rate_hz, checks.min_frames,
                    checks.min_frames / clip.sample_rate_hz));
  }
  // within full scale (ReadWav refused non-finite samples), no dead channel
  Eigen::Index channel = 0, frame = 0;
  const float peak = clip.samples.cwiseAbs().maxCoeff(&channel, &frame);
  if (peak > 1.0f + 1e-6f) {
    throw IoError(
        fmt::format("{}: sample {:.4g} at frame {} of channel {} lies beyond full scale "
                    "(|x| <= 1; is the WAV in volts or converter counts?)",
                    wav_path, clip.samples(channel, frame), frame, channel));
  }
  for (int c = 0; c < clip.channels(); ++c) {
    if (clip.samples.row(c).cwiseAbs().maxCoeff() == 0.0f) {
      throw IoError(
          fmt::format("{}: channel {} is silent (every sample is zero): a dead "
                      "microphone or cable",
                      wav_path, c));
    }
  }
  capture.audio = clip.samples;
  capture.sample_rate_hz = clip.sample_rate_hz;
  if (!proprio_csv_path.empty()) capture.proprio = ReadProprioCsv(proprio_csv_path);
  return capture;
}

}  // namespace sonicboom::hardware
