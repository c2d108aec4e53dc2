// `geometry-check`: labels from geometry against the simulator's own labels. Each MuJoCo strike's
// scene is exported as a recorded trial's would be (its object's cylinders as a PLY mesh placed
// where the rollout put them, the arm's joint log at the proprio rate as q_t.npy), read back, and
// labelled by the same path as `import --object`: forward kinematics of the joint log, then the
// geometry labeller.
#include <CLI/CLI.hpp>

#include <unistd.h>
#include <memory>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/geometry.h"
#include "sonicboom/hardware/import.h"
#include "sonicboom/hardware/npy.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;

// The object's cylinders as 24-sided capped prisms, in the base frame.
hardware::ObjectGeometry ObjectMesh(const sim::ObjectGeometry& object,
                                    const Eigen::Isometry3d& pose) {
  hardware::ObjectGeometry mesh;
  for (const sim::ObjectSegment& s : object.segments) {
    hardware::AppendCylinder(pose * s.p0, pose * s.p1, s.radius_m, 24, &mesh);
  }
  return mesh;
}

// A strike's scene as files: DIR/object.ply (base frame) and DIR/q_t.npy (rows x 7, rad).
void ExportScene(const std::filesystem::path& dir, const hardware::ObjectGeometry& mesh,
                 const Eigen::MatrixXd& joints) {
  std::filesystem::create_directories(dir);
  hardware::WriteObjectPly((dir / "object.ply").string(), mesh);
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = joints;
  hardware::WriteNpy((dir / "q_t.npy").string(), {rows.rows(), rows.cols()},
                     std::vector<double>(rows.data(), rows.data() + rows.size()));
}

// Largest distance (m) between the logged tube origins (proprio rows) and the poses from FK.
double KinematicsGap(const Eigen::MatrixXf& proprio, const std::vector<Eigen::Isometry3d>& poses) {
  double gap = 0.0;
  for (size_t r = 0; r < poses.size(); ++r) {
    const Eigen::Vector3d logged =
        proprio.row(Eigen::Index(r)).head<3>().transpose().cast<double>();
    gap = std::max(gap, (logged - poses[r].translation()).norm());
  }
  return gap;
}

// The system's temporary directory where std::filesystem looks for it (TMPDIR, TMP, TEMP,
// TEMPDIR, else /tmp), refused naming the variable and its value when it is not a directory.
std::filesystem::path TemporaryDirectory() {
  for (const char* name : {"TMPDIR", "TMP", "TEMP", "TEMPDIR"}) {
    const char* value = std::getenv(name);
    if (value == nullptr || *value == '\0') continue;
    std::error_code ec;
    if (!std::filesystem::is_directory(value, ec)) {
      throw IoError(fmt::format(
          "{}={}: not a directory (the temporary directory for the scenes); set {} to one, or "
          "give --scenes DIR",
          name, value, name));
    }
    return value;
  }
  return "/tmp";
}

// The scenes' directory: the user's, kept; or a temporary one, removed on the way out.
class SceneDirectory {
 public:
  explicit SceneDirectory(const std::string& user) : keep_(!user.empty()) {
    namespace fs = std::filesystem;
    path_ = keep_ ? fs::path(user)
                  : TemporaryDirectory() / fmt::format("sonicboom-geometry-check-{}", getpid());
    if (fs::exists(path_) && !(fs::is_directory(path_) && fs::is_empty(path_))) {
      throw IoError(
          fmt::format("{}: exists and is not an empty directory (--scenes)", path_.string()));
    }
  }
  ~SceneDirectory() {
    std::error_code ec;
    if (!keep_) std::filesystem::remove_all(path_, ec);
  }
  SceneDirectory(const SceneDirectory&) = delete;
  SceneDirectory& operator=(const SceneDirectory&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  bool keep_;
  std::filesystem::path path_;
};

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(std::lround(q * double(v.size() - 1)))];
}

}  // namespace

CommandResult RunGeometryCheck(const GlobalOptions& g, int64_t count, const std::string& out_md,
                               const std::string& scenes_dir) {
  if (count < 1) throw ConfigError(fmt::format("--count {} must be >= 1", count));
  if (!out_md.empty()) RefuseWritingOverInputs(g, {out_md}, {{scenes_dir, "--scenes"}});
  SonicBoomConfig config = ResolveConfig(g.sources);
  if (config.scene.mode != sim::SceneMode::kStrike &&
      config.scene.mode != sim::SceneMode::kGuided) {
    throw ConfigError(
        fmt::format("geometry-check needs scene.mode strike or guided (the arm "
                    "meets a fixed object), not '{}'",
                    NameOf(config.scene.mode)));
  }
  // the pose log covers the whole record, at the proprio rate
  config.strike.proprio_rows = static_cast<int64_t>(
      std::ceil(config.audio.record_duration_s * config.strike.proprio_rate_hz));
  const sim::StrikeRollout rollout(config.tube, config.audio, config.strike, config.scene,
                                   config.rollout);
  hardware::ContactRule rule;
  rule.outer_radius_m = config.tube.outer_radius_m;
  rule.length_m = config.tube.length_m;

  // every valid strike with a hard contact: the simulator's label against the geometry's
  const SceneDirectory scenes(scenes_dir);
  std::vector<double> errors_mm, step_lag;
  double kinematics_gap_m = 0.0;
  int64_t strikes = 0, failures = 0;
  std::vector<std::string> failed;
  const auto start = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < count; ++i) {
    const sim::RolloutResult r =
        rollout.Run(static_cast<uint64_t>(i), SampleSeed(config.seed, uint64_t(i)));
    ContactEvent event;
    ContactLabel truth;
    if (!r.valid || !sim::FirstHardContact(r, config.scene, &event, &truth)) continue;
    ++strikes;
    // the scene out to files and back, as a recorded trial comes in
    const std::filesystem::path dir = scenes.path() / fmt::format("strike{:06d}", i);
    ExportScene(dir,
                ObjectMesh(sim::BuildObjectGeometry(config.scene.objects[r.object], r.variant),
                           r.object_pose),
                r.joints);
    const hardware::ObjectGeometry mesh =
        hardware::ReadObjectGeometry((dir / "object.ply").string());
    const std::vector<Eigen::Isometry3d> poses = hardware::TubePosesFromJointLog(
        (dir / "q_t.npy").string(), PandaTubePose(config.tube.center_from_flange_m));
    kinematics_gap_m = std::max(kinematics_gap_m, KinematicsGap(r.proprio, poses));
    try {
      const hardware::GeometryLabel label = hardware::ContactLabeler(mesh, rule).Label(poses);
      errors_mm.push_back(1e3 * SurfaceDistance(config.tube, label.z_m, label.theta_rad, truth.z_m,
                                                truth.theta_rad));
      step_lag.push_back(label.step / config.strike.proprio_rate_hz - truth.time_s);
    } catch (const IoError& e) {
      ++failures;
      failed.push_back(fmt::format("strike {}: {}", i, e.what()));
    }
  }
  if (errors_mm.empty()) throw NumericalError("geometry-check: no strike could be labelled");
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double median = Percentile(errors_mm, 0.5), p95 = Percentile(errors_mm, 0.95);
  const double worst = *std::max_element(errors_mm.begin(), errors_mm.end());
  const json j = {{"strikes", strikes},
                  {"labelled", errors_mm.size()},
                  {"failures", failures},
                  {"median_mm", median},
                  {"p95_mm", p95},
                  {"worst_mm", worst},
                  {"median_pose_after_contact_s", Percentile(step_lag, 0.5)},
                  {"seconds", seconds},
                  {"kinematics_gap_max_mm", 1e3 * kinematics_gap_m},
                  {"scenes", scenes_dir.empty() ? json(nullptr) : json(scenes_dir)},
                  {"failed", failed}};
  const double lag_ms = 1e3 * Percentile(step_lag, 0.5);
  const std::string text = fmt::format(
      "{} strikes with a hard contact: geometry labels within {:.2f} mm (median), {:.2f} mm "
      "(p95), {:.2f} mm (worst) of the simulator's; {} failures; the contact pose is {:.1f} ms "
      "{} the simulated touch (median); forward kinematics of the joint logs within {:.3f} mm "
      "of the logged tube poses; {:.1f} s\n",
      strikes, median, p95, worst, failures, std::abs(lag_ms), lag_ms < 0.0 ? "before" : "after",
      1e3 * kinematics_gap_m, seconds);
  if (!out_md.empty()) WriteTextAtomic(out_md, text);
  return {j.dump(), text};
}

void RegisterGeometryCheck(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    int64_t count = 100;
    std::string out, scenes;
  };
  auto o = std::make_shared<Options>();
  auto* check = app.add_subcommand(
      "geometry-check", "labels from geometry against the simulator's labels on MuJoCo strikes");
  check->add_option("--count", o->count, "strikes (default 100)");
  check->add_option("--out", o->out, "write the result line to this file");
  check->add_option("--scenes", o->scenes,
                    "keep each strike's exported scene here (object.ply, q_t.npy); "
                    "default: a temporary directory, removed");
  check->callback([&g, run, o] {
    *run = [&g, o] { return RunGeometryCheck(g, o->count, o->out, o->scenes); };
  });
}

}  // namespace sonicboom::experiments
