// `map`: haptic mapping (paper §V-C). Each valid tap of a dataset (simulated guided taps, or
// captures brought in with `import`) is localized by a trained model; its (z, theta) is placed
// in the base frame with the tube pose the arm logged at the contact, and the points form a cloud
// of what the tube touched, scored against the true contact points placed the same way.
#include "sonicboom/experiments/haptic_map.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"
#include "sonicboom/sim/scene.h"

#include "internal/report.h"
#include "internal/subcommands.h"
#include "internal/unknown_fields.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

double RmsChamfer(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  if (from.cols() == 0 || to.cols() == 0) return std::numeric_limits<double>::quiet_NaN();
  double sum_sq = 0.0;
  for (Eigen::Index i = 0; i < from.cols(); ++i) {
    sum_sq += (to.colwise() - from.col(i)).colwise().squaredNorm().minCoeff();
  }
  return std::sqrt(sum_sq / static_cast<double>(from.cols()));
}

Eigen::Vector3d TubeSurfacePoint(const Eigen::Isometry3d& tube_pose, double z_m, double theta_rad,
                                 double radius_m) {
  return tube_pose *
         Eigen::Vector3d(radius_m * std::cos(theta_rad), radius_m * std::sin(theta_rad), z_m);
}

double SurfaceDistance(const std::vector<sim::ObjectSegment>& segments, const Eigen::Vector3d& p) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const sim::ObjectSegment& s : segments) {
    // the axis point nearest p, clamped to the segment
    const Eigen::Vector3d axis = s.p1 - s.p0;
    const double len_sq = axis.squaredNorm();
    const double t = len_sq > 0.0 ? std::clamp((p - s.p0).dot(axis) / len_sq, 0.0, 1.0) : 0.0;
    nearest = std::min(nearest, (p - (s.p0 + t * axis)).norm() - s.radius_m);
  }
  return segments.empty() ? std::numeric_limits<double>::quiet_NaN() : std::abs(nearest);
}

MapScores ScoreMap(const Eigen::Matrix3Xd& predicted_m, const Eigen::Matrix3Xd& true_m,
                   const std::vector<sim::ObjectSegment>& surface) {
  SONICBOOM_DEMAND(predicted_m.cols() == true_m.cols());
  MapScores s;
  s.taps = predicted_m.cols();
  s.med_cm = s.taps > 0 ? 100.0 * (predicted_m - true_m).colwise().norm().mean()
                        : std::numeric_limits<double>::quiet_NaN();
  s.chamfer_cm = 100.0 * RmsChamfer(predicted_m, true_m);
  s.reverse_chamfer_cm = 100.0 * RmsChamfer(true_m, predicted_m);
  if (surface.empty() || s.taps == 0) return s;
  // RMS over a cloud of each point's distance to the object's surface, cm
  const auto rms_to_surface = [&](const Eigen::Matrix3Xd& cloud) {
    double sum_sq = 0.0;
    for (Eigen::Index i = 0; i < cloud.cols(); ++i) {
      const double d = SurfaceDistance(surface, cloud.col(i));
      sum_sq += d * d;
    }
    return 100.0 * std::sqrt(sum_sq / static_cast<double>(cloud.cols()));
  };
  s.surface_cm = rms_to_surface(predicted_m);
  s.true_surface_cm = rms_to_surface(true_m);
  return s;
}

namespace {

// The tube's logged pose at time t_s of a record: its proprio row at or before t (the last row
// where the window ends earlier), (K x 10) rows of position, quaternion w x y z, velocity.
Eigen::Isometry3d LoggedTubePose(const Eigen::MatrixXf& proprio, double rate_hz, double t_s) {
  const auto last = static_cast<Eigen::Index>(proprio.rows() - 1);
  const auto k = std::clamp<Eigen::Index>(static_cast<Eigen::Index>(std::floor(t_s * rate_hz)), 0,
                                          last);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = proprio.row(k).head<3>().transpose().cast<double>();
  pose.linear() = Eigen::Quaterniond(proprio(k, 3), proprio(k, 4), proprio(k, 5), proprio(k, 6))
                      .normalized()
                      .toRotationMatrix();
  return pose;
}

// A valid tap the map can place: a known contact time within the arm's log, a rotation logged
// there, a known true point (no tap is placed at t = 0 or scored against NaN). SchemaError naming
// the file, the sample row and the column otherwise.
void CheckMappableTap(const std::string& file, int64_t row, const StrikeSample& meta,
                      double rate_hz, bool imported) {
  const std::string at = SampleRowOf(file, row, meta);
  const double t = KnownValue(meta.label.time_s, file, row, meta, "label/time_s",
                              "a map places each tap with the tube's pose logged at its contact "
                              "(a capture's contact time is labels.csv's time_s column)",
                              imported);
  const double log_end_s = static_cast<double>(meta.proprio.rows()) / rate_hz;
  if (t < 0.0) {
    throw SchemaError(fmt::format("{}: label/time_s is {} s, before the record starts", at, t));
  }
  if (t >= log_end_s) {
    throw SchemaError(fmt::format(
        "{} touches at {:.3f} s, after its proprioception log ends ({} rows at {} Hz = {:.3f} "
        "s): a map places each tap with the tube's pose at its contact; generate the taps with "
        "strike.proprio_rows covering the record (as configs/ts3.yaml does) or log the arm longer",
        at, t, meta.proprio.rows(), rate_hz, log_end_s));
  }
  const auto k = static_cast<Eigen::Index>(std::floor(t * rate_hz));
  const Eigen::Vector4f q = meta.proprio.row(k).segment<4>(3).transpose();
  if (!(std::abs(q.norm() - 1.0f) <= 0.1f)) {
    throw SchemaError(fmt::format(
        "{}: /proprio row {} holds the quaternion (w, x, y, z) = ({}, {}, {}, {}) of norm {:.3g}, "
        "not a rotation (within 10 % of 1): a map turns each tap by the tube's logged orientation",
        at, k, q[0], q[1], q[2], q[3], q.norm()));
  }
  const std::string need = "a map scores each tap against its true contact point";
  KnownValue(meta.label.z_m, file, row, meta, "label/z_m", need);
  KnownValue(meta.label.theta_rad, file, row, meta, "label/theta_rad", need);
  for (int j = 0; j < 3; ++j) {
    KnownValue(meta.label.point_m[j], file, row, meta, "label/point_m", need);
  }
}

}  // namespace

CommandResult RunMap(const GlobalOptions& g, const MapOptions& o) {
  CheckOutput(g, {o.out, "--out", o.force}, {{o.model, "--model"}, {o.data, "--data"}});
  if (!o.plot_script.empty() && !fs::is_regular_file(o.plot_script)) {
    throw IoError(fmt::format("--plot {}: no such script (--plot \"\" draws no figure)",
                              o.plot_script));
  }
  // every row's metadata, read once, by sample index; each valid tap needs the tube's logged pose
  // at its contact (a log that ends before it would place the tap where the arm was)
  const DatasetReader reader(o.data);
  if (reader.info().proprio_rows < 1) {
    throw SchemaError(fmt::format(
        "{}: no proprioception rows: a map places each tap with the arm's logged tube pose",
        o.data));
  }
  const double rate_hz = reader.info().proprio_rate_hz;
  std::map<uint64_t, StrikeSample> meta_of;
  const bool imported = reader.info().source == "hardware";
  for (int64_t r = 0; r < reader.size(); ++r) {
    StrikeSample meta = reader.ReadMeta(r);
    if (meta.valid) CheckMappableTap(o.data, r, meta, rate_hz, imported);
    meta_of.emplace(meta.index, std::move(meta));
  }

  // the taps localized
  const SonicBoomConfig config = ResolveWithRun(g, o.model);
  learning::Localizer localizer(o.model);
  std::vector<uint64_t> indices;
  const learning::FeatureSet set =
      ComputeDatasetFeatures(o.data, config, g.threads, !g.quiet, &indices);
  const std::vector<learning::Prediction> predictions = localizer.Predict(set);
  const double radius_m = localizer.surface_radius_m();
  const auto n = static_cast<Eigen::Index>(indices.size());
  Eigen::Matrix3Xd predicted(3, n), truth(3, n);  // base frame, m
  json taps = json::array();
  for (Eigen::Index i = 0; i < n; ++i) {
    const StrikeSample& meta = meta_of.at(indices[static_cast<size_t>(i)]);
    const Eigen::Isometry3d pose = LoggedTubePose(meta.proprio, rate_hz, meta.label.time_s);
    predicted.col(i) = TubeSurfacePoint(pose, predictions[static_cast<size_t>(i)].z_m,
                                        predictions[static_cast<size_t>(i)].theta_rad, radius_m);
    truth.col(i) = pose * meta.label.point_m;
    taps.push_back({{"index", meta.index},
                    {"predicted_m", {predicted(0, i), predicted(1, i), predicted(2, i)}},
                    {"true_m", {truth(0, i), truth(1, i), truth(2, i)}}});
  }
  // the mapped object, where the taps were generated in a guided scene: its segments in the
  // base frame (a capture's or an older file's is unknown)
  const std::optional<SonicBoomConfig> made = SimulatedWith(reader.info(), o.data);
  const std::vector<sim::ObjectSegment> object =
      made ? sim::GuidedSegmentsInBase(made->scene) : std::vector<sim::ObjectSegment>{};
  json skeleton = json::array();
  for (const sim::ObjectSegment& seg : object) {
    skeleton.push_back({{"p0_m", {seg.p0.x(), seg.p0.y(), seg.p0.z()}},
                        {"p1_m", {seg.p1.x(), seg.p1.y(), seg.p1.z()}},
                        {"radius_m", seg.radius_m}});
  }
  const MapScores s = ScoreMap(predicted, truth, object);
  // NaN (no geometry) as null
  const auto or_null = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };

  // the map, its scores and its figure
  MakeDirectories(o.out);
  const json result = {{"kind", "map"},
                       {"model", o.model},
                       {"data", o.data},
                       {"taps", s.taps},
                       {"med_cm", s.med_cm},
                       {"chamfer_cm", s.chamfer_cm},
                       {"reverse_chamfer_cm", s.reverse_chamfer_cm},
                       {"surface_cm", or_null(s.surface_cm)},
                       {"true_surface_cm", or_null(s.true_surface_cm)},
                       {"skeleton", skeleton},
                       {"points", taps}};
  const std::string json_path = (fs::path(o.out) / "map.json").string();
  WriteTextAtomic(json_path, result.dump(1) + "\n");
  if (!o.plot_script.empty()) {
    DrawFigure(o.plot_script, "map", json_path, (fs::path(o.out) / "map.png").string(),
               "map.json is written; --plot \"\" skips the figure");
  }
  json summary = result;
  summary.erase("points");
  summary.erase("skeleton");
  const std::string surface =
      object.empty() ? std::string("; the mapped object's geometry is not in the file")
                     : fmt::format("; RMS distance to the object's surface {:.2f} cm (true "
                                   "points: {:.2f} cm)",
                                   s.surface_cm, s.true_surface_cm);
  return {summary.dump(),
          fmt::format("{} taps mapped into {}: MED {:.2f} cm, RMS Chamfer {:.2f} cm (predicted "
                      "to true), {:.2f} cm (true to predicted){}\n",
                      s.taps, o.out, s.med_cm, s.chamfer_cm, s.reverse_chamfer_cm, surface)};
}

void RegisterMap(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<MapOptions>();
  auto* cmd = app.add_subcommand(
      "map", "haptic mapping: localized taps placed with the arm's logged pose, scored");
  cmd->add_option("--model", o->model, "run directory")->required();
  cmd->add_option("--data", o->data, "taps (.h5: generated guided taps, or imported captures)")
      ->required();
  cmd->add_option("--out", o->out, "output directory (map.json, map.png)")->required();
  cmd->add_option("--plot", o->plot_script, "plotting script (\"\" draws no figure)");
  cmd->add_flag("--force", o->force, "replace an existing output directory's files");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunMap(g, *o); }; });
}

}  // namespace sonicboom::experiments
