// The published trial layout: trial{N}/mic2.wav, gt_label.npy, x_t.npy, xdot_t.npy, q_t.npy.
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "internal/import_common.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/geometry.h"
#include "sonicboom/hardware/import.h"
#include "sonicboom/hardware/npy.h"

namespace fs = std::filesystem;

namespace sonicboom::hardware {
namespace {


// A (rows x cols) array with at least `min_rows` rows and one of the allowed column counts.
NpyArray ReadTable(const fs::path& file, int64_t min_rows, std::initializer_list<int64_t> cols) {
  NpyArray a = ReadNpy(file.string());
  const bool cols_ok = std::find(cols.begin(), cols.end(), a.cols()) != cols.end();
  if (a.shape.size() != 2 || !cols_ok || a.rows() < min_rows) {
    std::string shape;
    for (int64_t d : a.shape) shape += (shape.empty() ? "" : ", ") + std::to_string(d);
    std::string allowed;
    for (int64_t c : cols) allowed += (allowed.empty() ? "" : " or ") + std::to_string(c);
    throw IoError(fmt::format("{}: shape ({}), expected (rows >= {}, {})", file.string(), shape,
                              min_rows, allowed));
  }
  return a;
}

// The tube pose (base frame) at row r of a joint log q (rows x 7).
Eigen::Isometry3d TubePoseAt(const NpyArray& q, int64_t r, const TubePoseFromJoints& tube_pose) {
  std::array<double, 7> joints;
  std::copy_n(&q.data[r * 7], 7, joints.begin());
  return tube_pose(joints);
}

// Rows of the published pose logs as proprio rows: position, quaternion w x y z, velocity.
Eigen::MatrixXf TrialProprio(const fs::path& dir, const ImportSettings& s) {
  const int64_t k = s.proprio_rows;
  const NpyArray x = ReadTable(dir / "x_t.npy", k, {3, 7});
  const NpyArray v = ReadTable(dir / "xdot_t.npy", k, {3});
  Eigen::MatrixXf p(k, kProprioFeatures);
  // orientation: x_t's own quaternion (x y z w), or forward kinematics of q_t
  std::optional<NpyArray> q;
  if (x.cols() == 3) {
    if (!fs::exists(dir / "q_t.npy") || !s.tube_pose_from_joints) {
      throw IoError(
          fmt::format("{}: x_t.npy has no orientation (3 columns) and there is no "
                      "q_t.npy to compute it",
                      dir.string()));
    }
    q = ReadTable(dir / "q_t.npy", k, {7});
  }
  for (int64_t r = 0; r < k; ++r) {
    const double* xr = &x.data[r * x.cols()];
    Eigen::Quaterniond quat;
    if (q) {
      quat = Eigen::Quaterniond(TubePoseAt(*q, r, s.tube_pose_from_joints).linear());
    } else {
      quat = Eigen::Quaterniond(xr[6], xr[3], xr[4], xr[5]);
      const double norm = quat.norm();
      if (std::abs(norm - 1.0) > 0.05) {
        throw IoError(fmt::format("{}: row {} has a quaternion of norm {:.3f}, not a rotation",
                                  (dir / "x_t.npy").string(), r, norm));
      }
      if (std::abs(norm - 1.0) > 1e-6) quat.normalize();  // a stored unit quaternion stays as is
    }
    p.row(r) << xr[0], xr[1], xr[2], quat.w(), quat.x(), quat.y(), quat.z(), v.data[r * 3],
        v.data[r * 3 + 1], v.data[r * 3 + 2];
  }
  return p;
}

// The label where the tube, placed by the joint log, first meets the object.
void LabelFromGeometry(const fs::path& dir, const ImportSettings& s, StrikeSample* sample) {
  const fs::path q_file = dir / "q_t.npy";
  if (!fs::exists(q_file) || !s.tube_pose_from_joints) {
    throw IoError(
        fmt::format("{}: missing; labels from geometry need the joint log", q_file.string()));
  }
  const std::vector<Eigen::Isometry3d> poses =
      TubePosesFromJointLog(q_file.string(), s.tube_pose_from_joints);
  try {
    const GeometryLabel label = s.labeler->Label(poses);
    internal::SetLabel(label.z_m, label.theta_rad, s, q_file.string(), sample);
  } catch (const IoError& e) {
    throw IoError(fmt::format("{}: {}", q_file.string(), e.what()));
  }
}

StrikeSample LoadTrial(const fs::path& dir, const ImportSettings& s, internal::LoadNotes* notes) {
  StrikeSample sample;
  sample.audio = internal::CheckedRecord((dir / "mic2.wav").string(), s, notes);
  sample.proprio = TrialProprio(dir, s);
  if (s.labeler) {
    LabelFromGeometry(dir, s, &sample);
    return sample;
  }
  const fs::path label_file = dir / "gt_label.npy";
  const NpyArray label = ReadNpy(label_file.string());
  if (label.data.size() != 2) {
    throw IoError(fmt::format("{}: {} values, expected 2 ([h_m, theta_rad])", label_file.string(),
                              label.data.size()));
  }
  if (std::abs(label.data[1]) > kPi + 1e-6) {
    throw IoError(
        fmt::format("{}: angle {} rad is outside [-pi, pi]", label_file.string(), label.data[1]));
  }
  internal::SetLabel(label.data[0], TubeAngleFrom(label.data[1], s.angle), s, label_file.string(),
                     &sample);
  return sample;
}

}  // namespace

std::vector<Eigen::Isometry3d> TubePosesFromJointLog(const std::string& path,
                                                     const TubePoseFromJoints& tube_pose) {
  const NpyArray q = ReadTable(path, 1, {7});
  std::vector<Eigen::Isometry3d> poses;
  for (int64_t r = 0; r < q.rows(); ++r) poses.push_back(TubePoseAt(q, r, tube_pose));
  return poses;
}

namespace {

// Every valid sample's (z, θ) known: a NaN would be written as gt_label.npy = [nan, nan], which
// no import reads back (SchemaError naming the file, the row and the column).
void RequireKnownLabels(const DatasetReader& reader, const std::string& path) {
  for (int64_t i = 0; i < reader.size(); ++i) {
    const StrikeSample meta = reader.ReadMeta(i);
    if (!meta.valid) continue;
    for (const auto& [name, value] : {std::pair{"label/z_m", meta.label.z_m},
                                      std::pair{"label/theta_rad", meta.label.theta_rad}}) {
      if (std::isnan(value)) {
        throw SchemaError(fmt::format(
            "{}: sample row {} (index {}): {} is NaN (not known), and a trial's gt_label.npy "
            "holds two finite numbers: nothing exported",
            path, i, meta.index, name));
      }
    }
  }
}

}  // namespace

namespace internal {

std::vector<ImportEntry> ListTrials(const std::string& dir) {
  std::vector<std::pair<uint64_t, fs::path>> trials;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (!e.is_directory() || name.rfind("trial", 0) != 0 || name.size() == 5 || name.size() > 24 ||
        name.find_first_not_of("0123456789", 5) != std::string::npos) {
      continue;
    }
    trials.emplace_back(std::stoull(name.substr(5)), e.path());
  }
  std::sort(trials.begin(), trials.end());
  // trial0 and trial00 would both be sample 0: refused before anything is written
  for (size_t k = 1; k < trials.size(); ++k) {
    if (trials[k].first == trials[k - 1].first) {
      throw IoError(
          fmt::format("{} and {}: both are trial {} (the number is the sample index; rename one)",
                      trials[k - 1].second.string(), trials[k].second.string(), trials[k].first));
    }
  }
  std::vector<ImportEntry> entries;
  for (const auto& [n, path] : trials) {
    entries.push_back(
        {(path / "mic2.wav").string(), n, [path = path](const ImportSettings& s, LoadNotes* notes) {
           return LoadTrial(path, s, notes);
         }});
  }
  return entries;
}

}  // namespace internal

int64_t ExportTrials(const std::string& dataset_path, const std::string& out_dir,
                     AngleConvention angle) {
  if (fs::exists(out_dir)) {
    throw IoError(fmt::format("{}: already exists; export writes a new directory", out_dir));
  }
  DatasetReader reader(dataset_path);
  const DatasetInfo& info = reader.info();
  RequireKnownLabels(reader, dataset_path);
  const std::string partial = out_dir + ".partial";
  std::error_code ignored;
  fs::remove_all(partial, ignored);
  fs::create_directories(partial);

  // one trial directory per valid sample, in file order
  int64_t written = 0;
  for (int64_t i = 0; i < reader.size(); ++i) {
    const StrikeSample s = reader.Read(i);
    if (!s.valid) continue;
    const fs::path trial = fs::path(partial) / fmt::format("trial{}", written++);
    fs::create_directory(trial);
    AudioClip clip;
    clip.samples = s.audio;
    clip.sample_rate_hz = info.sample_rate_hz;
    WriteWav((trial / "mic2.wav").string(), clip, /*pcm16=*/true);
    WriteNpy((trial / "gt_label.npy").string(), {2},
             {s.label.z_m, StoredAngleFrom(s.label.theta_rad, angle)});
    // x_t: position, quaternion x y z w; xdot_t: velocity
    const int64_t k = s.proprio.rows();
    std::vector<double> x(k * 7), v(k * 3);
    for (int64_t r = 0; r < k; ++r) {
      const auto row = s.proprio.row(r);
      const int order[7] = {0, 1, 2, 4, 5, 6, 3};
      for (int j = 0; j < 7; ++j) x[r * 7 + j] = row(order[j]);
      for (int j = 0; j < 3; ++j) v[r * 3 + j] = row(7 + j);
    }
    WriteNpy((trial / "x_t.npy").string(), {k, 7}, x);
    WriteNpy((trial / "xdot_t.npy").string(), {k, 3}, v);
  }
  if (written == 0) {
    fs::remove_all(partial, ignored);
    throw IoError(fmt::format("{}: no valid sample to export", dataset_path));
  }
  fs::rename(partial, out_dir);
  return written;
}

}  // namespace sonicboom::hardware
