// `geometry-check`: labels from geometry against the simulator's own labels. Each MuJoCo strike's
// object (its cylinders as meshes, placed where the rollout put them) and its logged tube poses
// at the proprio rate are handed to the geometry labeller, as a recorded trial's would be.
#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/geometry.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;

// The object's cylinders as 24-sided capped prisms, in the base frame.
hardware::ObjectGeometry ObjectMesh(const sim::ObjectGeometry& object, const Eigen::Isometry3d& pose) {
  hardware::ObjectGeometry mesh;
  for (const sim::ObjectSegment& s : object.segments) {
    hardware::AppendCylinder(pose * s.p0, pose * s.p1, s.radius_m, 24, &mesh);
  }
  return mesh;
}

// The logged tube poses (proprio rows: position, quaternion w x y z).
std::vector<Eigen::Isometry3d> TubePoses(const Eigen::MatrixXf& proprio) {
  std::vector<Eigen::Isometry3d> poses;
  for (Eigen::Index r = 0; r < proprio.rows(); ++r) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.translation() = proprio.row(r).head<3>().transpose().cast<double>();
    t.linear() = Eigen::Quaterniond(proprio(r, 3), proprio(r, 4), proprio(r, 5), proprio(r, 6))
                     .normalized()
                     .toRotationMatrix();
    poses.push_back(t);
  }
  return poses;
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(std::lround(q * double(v.size() - 1)))];
}

}  // namespace

CommandResult RunGeometryCheck(const GlobalOptions& g, int64_t count, const std::string& out_md) {
  if (count < 1) throw ConfigError(fmt::format("--count {} must be >= 1", count));
  SonicBoomConfig config = ResolveConfig(g.sources);
  if (config.scene.mode != "strike" && config.scene.mode != "guided") {
    throw ConfigError(fmt::format("geometry-check needs scene.mode strike or guided (the arm "
                                  "meets a fixed object), not '{}'", config.scene.mode));
  }
  // the pose log covers the whole record, at the proprio rate
  config.strike.proprio_rows = static_cast<int64_t>(
      std::ceil(config.audio.record_duration_s * config.strike.proprio_rate_hz));
  const sim::StrikeRollout rollout(config.tube, config.audio, config.strike, config.scene, config.rollout);
  hardware::ContactRule rule;
  rule.outer_radius_m = config.tube.outer_radius_m;
  rule.length_m = config.tube.length_m;

  // every valid strike with a hard contact: the simulator's label against the geometry's
  std::vector<double> errors_mm, step_lag;
  int64_t strikes = 0, failures = 0;
  std::vector<std::string> failed;
  const auto start = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < count; ++i) {
    const sim::RolloutResult r = rollout.Run(static_cast<uint64_t>(i), SampleSeed(config.seed, uint64_t(i)));
    ContactEvent event;
    ContactLabel truth;
    if (!r.valid || !sim::FirstHardContact(r, config.scene, &event, &truth)) continue;
    ++strikes;
    const hardware::ObjectGeometry mesh =
        ObjectMesh(sim::BuildObjectGeometry(config.scene.objects[r.object], r.variant), r.object_pose);
    try {
      const hardware::GeometryLabel label = hardware::ContactLabeler(mesh, rule).Label(TubePoses(r.proprio));
      errors_mm.push_back(1e3 * SurfaceDistance(config.tube, label.z_m, label.theta_rad,
                                                truth.z_m, truth.theta_rad));
      step_lag.push_back(label.step / config.strike.proprio_rate_hz - truth.time_s);
    } catch (const IoError& e) {
      ++failures;
      failed.push_back(fmt::format("strike {}: {}", i, e.what()));
    }
  }
  if (errors_mm.empty()) throw NumericalError("geometry-check: no strike could be labelled");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double median = Percentile(errors_mm, 0.5), p95 = Percentile(errors_mm, 0.95);
  const double worst = *std::max_element(errors_mm.begin(), errors_mm.end());
  const json j = {{"strikes", strikes}, {"labelled", errors_mm.size()}, {"failures", failures},
                  {"median_mm", median}, {"p95_mm", p95}, {"worst_mm", worst},
                  {"median_pose_after_contact_s", Percentile(step_lag, 0.5)}, {"seconds", seconds},
                  {"failed", failed}};
  const std::string text = fmt::format(
      "{} strikes with a hard contact: geometry labels within {:.2f} mm (median), {:.2f} mm "
      "(p95), {:.2f} mm (worst) of the simulator's; {} failures; the contact pose is {:.1f} ms "
      "after the simulated touch (median); {:.1f} s\n",
      strikes, median, p95, worst, failures, 1e3 * Percentile(step_lag, 0.5), seconds);
  if (!out_md.empty()) WriteTextAtomic(out_md, text);
  return {j.dump(), text};
}

}  // namespace sonicboom::experiments
