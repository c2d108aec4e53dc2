#include "sonicboom/hardware/capture.h"

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::hardware {
namespace {

const char* kProprioHeader = "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s";

}  // namespace

Eigen::MatrixXf ReadProprioCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open robot log", path));
  std::string line;
  if (!std::getline(in, line)) throw IoError(fmt::format("{}: empty robot log", path));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line != kProprioHeader) {
    throw IoError(
        fmt::format("{}:1: expected header '{}', found '{}'", path, kProprioHeader, line));
  }
  // rows of 11 numbers; the time column is checked, then dropped
  std::vector<std::array<float, 10>> rows;
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
  std::filesystem::rename(partial, path);
}

Capture LoadCapture(const std::string& wav_path, const std::string& proprio_csv_path,
                    int expected_channels, double expected_sample_rate_hz) {
  Capture capture;
  const AudioClip clip = ReadWav(wav_path, expected_channels);
  if (std::abs(clip.sample_rate_hz - expected_sample_rate_hz) > 1e-6) {
    throw IoError(fmt::format("{}: sample rate {} Hz, the model expects {} Hz", wav_path,
                              clip.sample_rate_hz, expected_sample_rate_hz));
  }
  capture.audio = clip.samples;
  capture.sample_rate_hz = clip.sample_rate_hz;
  if (!proprio_csv_path.empty()) capture.proprio = ReadProprioCsv(proprio_csv_path);
  return capture;
}

}  // namespace sonicboom::hardware
