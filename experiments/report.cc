// Set-up and output shared by the subcommands: config resolution with a run or a dataset as the
// base layer, outputs beside their config, and the JSON forms of labels, metrics and predictions.
#include "internal/report.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iterator>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/process.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

SonicBoomConfig Resolve(const GlobalOptions& g) {
  return ResolveConfig(g.sources);
}

// the resolved config beside an output file
void WriteConfigBeside(const std::string& output, const SonicBoomConfig& config) {
  WriteTextAtomic(output + ".config.yaml", ConfigToYaml(config));
}

// a sidecar is replaced with the output it describes: one beside no output is another run's file
void CheckConfigSidecar(const Output& out) {
  const std::string sidecar = out.path + ".config.yaml";
  if (!out.force && !fs::exists(out.path) && fs::exists(sidecar)) {
    throw IoError(fmt::format(
        "{}: exists (a config sidecar beside no {} {}); --force replaces it", sidecar,
        out.option, out.path));
  }
}

// the parent directory of an output must exist
void RequireParentDir(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent)) {
    throw IoError(fmt::format("{}: directory {} does not exist", path, parent.string()));
  }
}

namespace {

// the same existing file under another name (a hard link), or the same resolved path
bool SameFile(const std::string& a, const fs::path& resolved_a, const std::string& b,
              const fs::path& resolved_b) {
  std::error_code ec;
  if (fs::exists(a) && fs::exists(b) && fs::equivalent(a, b, ec)) return true;
  return resolved_a == resolved_b;
}

void RefuseWritingOver(const Output& out, const ReadPath& in) {
  if (in.path.empty()) return;
  const fs::path input = ResolvedPath(in.path);
  const std::string input_sidecar = in.path + ".config.yaml";
  for (const std::string& target : {out.path, out.path + ".config.yaml"}) {
    const fs::path t = ResolvedPath(target);
    const std::string what = target == out.path ? out.option : "the output's config sidecar";
    if (SameFile(target, t, in.path, input)) {
      throw IoError(fmt::format("{}: {} is an input ({} {}); writing it would destroy it", target,
                                what, in.option, in.path));
    }
    if (SameFile(target, t, input_sidecar, ResolvedPath(input_sidecar))) {
      throw IoError(
          fmt::format("{}: {} is an input's config sidecar ({} {}); writing it would "
                      "destroy it",
                      target, what, in.option, in.path));
    }
    if (IsWithin(t, input)) {
      throw IoError(fmt::format("{}: {} lies inside an input ({} {}), which this command reads",
                                target, what, in.option, in.path));
    }
  }
  if (IsWithin(input, ResolvedPath(out.path))) {
    throw IoError(fmt::format("{}: {} holds an input ({} {}); replacing it would destroy it",
                              out.path, out.option, in.option, in.path));
  }
}

}  // namespace

void RefuseWritingOverInputs(const GlobalOptions& g, const Output& out,
                             std::vector<ReadPath> reads) {
  for (const std::string& file : g.sources.files) reads.push_back({file, "--config"});
  for (const ReadPath& in : reads) RefuseWritingOver(out, in);
}

void DrawFigure(const std::string& script, const std::string& kind, const std::string& data,
                const std::string& png, const std::string& advice) {
  // an argument vector: the paths reach the script as bytes, never through a shell
  ProcessRequest request;
  request.argv = {std::string(kPlotPython), script, kind, data, png};
  ProcessResult result;
  try {
    result = RunProcess(request);
  } catch (const IoError& e) {
    throw IoError(fmt::format("{}: the plot script {} could not run ({}; it needs {} with "
                              "python3-matplotlib; {})",
                              png, script, e.what(), kPlotPython, advice));
  }
  if (result.exited_zero() && fs::is_regular_file(png)) return;
  const std::string last = result.LastErrLine();
  const bool no_matplotlib = result.err.find("No module named 'matplotlib'") != std::string::npos;
  const std::string why =
      no_matplotlib ? fmt::format("{} has no matplotlib: install python3-matplotlib", kPlotPython)
      : result.exited_zero() ? "it exited 0 but wrote no figure"
      : last.empty()         ? result.Ending()
                             : fmt::format("{}: {}", result.Ending(), last);
  throw IoError(
      fmt::format("{}: the plot script {} failed on {} ({}; {})", png, script, data, why, advice));
}

void CheckOutput(const GlobalOptions& g, const Output& out, std::vector<ReadPath> reads) {
  RequireParentDir(out.path);
  RefuseWritingOverInputs(g, out, std::move(reads));
  if (fs::exists(out.path) && !out.force) {
    throw IoError(
        fmt::format("{}: exists; --force replaces it once the new one is complete", out.path));
  }
}

hardware::CaptureChecks CaptureChecksFor(const SonicBoomConfig& config) {
  hardware::CaptureChecks checks;
  checks.channels = config.mics.count();
  checks.sample_rate_hz = config.audio.sample_rate_hz;
  const auto window_frames =
      static_cast<int64_t>(std::llround(config.features.window_s * config.audio.sample_rate_hz));
  checks.min_frames = std::max<int64_t>(1, std::min(config.audio.num_samples(), window_frames));
  return checks;
}

hardware::TubePoseFromJoints PandaTubePose(double tube_center_from_flange_m) {
  return [tube_center_from_flange_m](const std::array<double, 7>& q) {
    return sim::PandaForwardKinematics(sim::JointVector(q.data()), tube_center_from_flange_m).tube;
  };
}

// NaN (no labelled strike, or a model without predictive uncertainty) prints as null
json LabelJson(const ContactLabel& l) {
  return {{"z_m", l.z_m},
          {"theta_rad", l.theta_rad},
          {"point_m", {l.point_m.x(), l.point_m.y(), l.point_m.z()}},
          {"normal", {l.normal.x(), l.normal.y(), l.normal.z()}},
          {"impulse_Ns", l.impulse_Ns},
          {"time_s", l.time_s},
          {"normal_speed_m_s", l.normal_speed_m_s},
          {"duration_s", l.duration_s}};
}

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// features -> train/val split -> training, writing into run_dir
learning::Metrics TrainOnDataset(const SonicBoomConfig& config, const std::string& data,
                                 const std::string& run_dir, bool resume, int threads, bool quiet,
                                 const learning::FineTune& fine_tune) {
  std::vector<uint64_t> indices;
  learning::FeatureSet all = ComputeDatasetFeatures(data, config, threads, !quiet, &indices);
  return TrainOnFeatures(config, std::move(all), indices, data, run_dir, resume, quiet, fine_tune);
}

SonicBoomConfig ResolveWithRun(const GlobalOptions& g, const std::string& run_dir) {
  ConfigSources sources = g.sources;
  const std::string path = (fs::path(run_dir) / "config.yaml").string();
  if (!fs::is_directory(run_dir)) throw IoError(fmt::format("{}: no such run directory", run_dir));
  sources.embedded_yaml = ReadText(path);
  sources.embedded_name = path;
  return ResolveConfig(sources);
}

json MetricsJson(const learning::Metrics& m) {
  return {{"n", m.n},
          {"med_cm", m.med_cm},
          {"height_err_cm", m.height_err_cm},
          {"angle_err_deg", m.angle_err_deg},
          {"reference_med_cm", m.reference_med_cm},
          {"z_coverage_50", m.z_coverage_50},
          {"z_coverage_90", m.z_coverage_90},
          {"theta_coverage_50", m.theta_coverage_50},
          {"theta_coverage_90", m.theta_coverage_90},
          {"nll", m.nll}};
}

json PredictionJson(const learning::Prediction& p, const TubeConfig& tube, std::string* text) {
  const Eigen::Vector3d point = SurfacePoint(tube, p.z_m, p.theta_rad);
  json j = {{"z_m", p.z_m},
            {"theta_rad", p.theta_rad},
            {"point_m", {point.x(), point.y(), point.z()}},
            {"frame", "tube"}};
  *text += fmt::format(
      "contact at z = {:.4f} m, theta = {:.4f} rad; point ({:.4f}, {:.4f}, "
      "{:.4f}) m in the tube frame\n",
      p.z_m, p.theta_rad, point.x(), point.y(), point.z());
  // the predictive distribution (null for a model without one); the theta interval is
  // [theta - h, theta + h], not wrapped, so lo < hi also across +-pi
  j["z_std_m"] = j["theta_std_rad"] = j["theta_kappa"] = nullptr;
  j["z_interval_90_m"] = j["theta_interval_90_rad"] = nullptr;
  if (p.has_uncertainty()) {
    const double z_half = learning::GaussianIntervalHalfWidth(0.9) * p.z_std_m;
    const double theta_half = learning::VonMisesIntervalHalfWidth(p.theta_kappa, 0.9);
    const double theta_std = learning::VonMisesCircularStd(p.theta_kappa);
    j["z_std_m"] = p.z_std_m;
    j["theta_std_rad"] = theta_std;
    j["theta_kappa"] = p.theta_kappa;
    j["z_interval_90_m"] = {p.z_m - z_half, p.z_m + z_half};
    j["theta_interval_90_rad"] = {p.theta_rad - theta_half, p.theta_rad + theta_half};
    *text += fmt::format(
        "uncertainty: z std {:.4f} m (90 %: [{:.4f}, {:.4f}] m), theta circular "
        "std {:.4f} rad (90 %: [{:.4f}, {:.4f}] rad, kappa {:.3g})\n",
        p.z_std_m, p.z_m - z_half, p.z_m + z_half, theta_std, p.theta_rad - theta_half,
        p.theta_rad + theta_half, p.theta_kappa);
  }
  return j;
}

// the test dataset's own config as the base layer, then --config files and --set overrides
SonicBoomConfig ResolveWithDataset(const GlobalOptions& g, const std::string& data) {
  ConfigSources sources = g.sources;
  const DatasetInfo info = DatasetReader(data).info();
  if (!info.config_yaml.empty()) {
    sources.embedded_yaml = info.config_yaml;
    sources.embedded_name = data + " (its config)";
  }
  return ResolveConfig(sources);
}

}  // namespace sonicboom::experiments
