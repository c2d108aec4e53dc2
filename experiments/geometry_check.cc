// `geometry-check`: labels from geometry against the simulator's own labels. Each MuJoCo strike's
// object (its cylinders as meshes, placed where the rollout put them) and its logged tube poses
// at the proprio rate are handed to the geometry labeller, as a recorded trial's would be.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/geometry.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;
constexpr double kPi = std::numbers::pi;

// The object's cylinders as 24-sided prisms with end caps, in the base frame.
hardware::ObjectGeometry ObjectMesh(const sim::ObjectGeometry& object, const Eigen::Isometry3d& pose) {
  constexpr int kSides = 24;
  std::vector<Eigen::Vector3f> v;
  std::vector<Eigen::Vector3i> f;
  for (const sim::ObjectSegment& s : object.segments) {
    const Eigen::Vector3d p0 = pose * s.p0, p1 = pose * s.p1, u = (p1 - p0).normalized();
    const Eigen::Vector3d a = u.unitOrthogonal(), b = u.cross(a);
    const int first = static_cast<int>(v.size());
    for (const Eigen::Vector3d& end : {p0, p1}) {
      for (int k = 0; k < kSides; ++k) {
        const double t = 2 * kPi * k / kSides;
        v.push_back((end + s.radius_m * (std::cos(t) * a + std::sin(t) * b)).cast<float>());
      }
      v.push_back(end.cast<float>());  // cap centre
    }
    for (int k = 0; k < kSides; ++k) {
      const int n = (k + 1) % kSides, top = first + kSides + 1;
      f.emplace_back(first + k, first + n, top + k);
      f.emplace_back(first + n, top + n, top + k);
      f.emplace_back(first + kSides, first + n, first + k);  // caps
      f.emplace_back(top + kSides, top + k, top + n);
    }
  }
  hardware::ObjectGeometry mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) mesh.vertices.col(static_cast<Eigen::Index>(i)) = v[i];
  mesh.triangles.resize(3, static_cast<Eigen::Index>(f.size()));
  for (size_t i = 0; i < f.size(); ++i) mesh.triangles.col(static_cast<Eigen::Index>(i)) = f[i];
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
      const double dtheta = std::remainder(label.theta_rad - truth.theta_rad, 2 * kPi);
      errors_mm.push_back(1e3 * std::hypot(label.z_m - truth.z_m, rule.outer_radius_m * dtheta));
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
