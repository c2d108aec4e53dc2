#include "sonicboom/experiments/commands.h"

#include "embedded_configs.h"
#include "internal/report.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/features.h"
#include "sonicboom/core/array_file.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/learning/baselines.h"
#include "sonicboom/learning/learning.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kPi = std::numbers::pi;

SonicBoomConfig Resolve(const GlobalOptions& g) { return ResolveConfig(g.sources); }

// the resolved config beside an output file
void WriteConfigBeside(const std::string& output, const SonicBoomConfig& config) {
  WriteTextAtomic(output + ".config.yaml", ConfigToYaml(config));
}

// the parent directory of an output must exist
void RequireParentDir(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent)) {
    throw IoError(fmt::format("{}: directory {} does not exist", path, parent.string()));
  }
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
                                 const learning::FineTune& fine_tune = {}) {
  std::vector<uint64_t> indices;
  const learning::FeatureSet all = ComputeDatasetFeatures(data, config, threads, !quiet, &indices);
  return TrainOnFeatures(config, all, indices, data, run_dir, resume, quiet, fine_tune);
}

std::string MetricsRow(const std::string& name, const learning::Metrics& m) {
  return fmt::format("| {:<28} | {:>13.2f} | {:>15.2f} | {:>15.1f} |\n", name, m.med_cm,
                     m.height_err_cm, m.angle_err_deg);
}

}  // namespace

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
  json j = {{"z_m", p.z_m}, {"theta_rad", p.theta_rad}, {"point_m", {point.x(), point.y(), point.z()}},
            {"frame", "tube"}};
  *text += fmt::format("contact at z = {:.4f} m, theta = {:.4f} rad; point ({:.4f}, {:.4f}, "
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
    *text += fmt::format("uncertainty: z std {:.4f} m (90 %: [{:.4f}, {:.4f}] m), theta circular "
                         "std {:.4f} rad (90 %: [{:.4f}, {:.4f}] rad, kappa {:.3g})\n",
                         p.z_std_m, p.z_m - z_half, p.z_m + z_half, theta_std,
                         p.theta_rad - theta_half, p.theta_rad + theta_half, p.theta_kappa);
  }
  return j;
}

const std::string& DemoConfigYaml() {
  // the transfer model on the default scene, where the arm moves: its proprioception joins the
  // audio (docs/transfer.md). Sized to finish in a few minutes on 2 cores.
  static const std::string yaml = R"(model:
  modalities: [audio, proprio]
demo:
  train_count: 3200
  test_count: 400
)";
  return yaml;
}

CommandResult RunDemo(const GlobalOptions& g, const std::string& out_dir_arg) {
  const auto start = std::chrono::steady_clock::now();
  ConfigSources sources = g.sources;
  // the demo trains the robust model a new user should start from: randomized structures,
  // strikers and sensor chains (configs/randomized.yaml) and the transfer model
  // (configs/transfer.yaml), then its own sizes
  sources.embedded_layers = {{"configs/randomized.yaml (embedded)", kEmbedded_randomized_yaml},
                             {"configs/transfer.yaml (embedded)", kEmbedded_transfer_yaml},
                             {"demo defaults", DemoConfigYaml()}};
  const SonicBoomConfig config = ResolveConfig(sources);

  // a fresh run directory; never overwrite a finished run
  const std::string run_dir = out_dir_arg.empty() ? "runs/demo-" + UtcTimestamp() : out_dir_arg;
  if (fs::exists(fs::path(run_dir) / "metrics.json")) {
    throw IoError(fmt::format("{}: holds a finished run; choose another --out", run_dir));
  }
  MakeDirectories(run_dir);
  WriteTextAtomic((fs::path(run_dir) / "config.yaml").string(), ConfigToYaml(config));
  spdlog::info("demo run directory: {}", run_dir);

  // data: training strikes and held-out strikes with disjoint sample indices
  const std::string train_path = (fs::path(run_dir) / "train.h5").string();
  const std::string test_path = (fs::path(run_dir) / "test.h5").string();
  spdlog::info("step 1/3: simulating {} training and {} held-out strikes", config.demo.train_count,
               config.demo.test_count);
  const GenerateResult gen_train = GenerateDataset(config, train_path, config.demo.train_count, 0,
                                                   0, 1, g.threads, !g.quiet);
  const GenerateResult gen_test = GenerateDataset(
      config, test_path, config.demo.test_count, config.demo.train_count, 0, 1, g.threads, !g.quiet);

  // training
  spdlog::info("step 2/3: training ({} epochs)", config.train.epochs);
  const std::string model_dir = (fs::path(run_dir) / "model").string();
  MakeDirectories(model_dir);
  WriteTextAtomic((fs::path(model_dir) / "config.yaml").string(), ConfigToYaml(config));
  const auto train_start = std::chrono::steady_clock::now();
  const learning::Metrics val = TrainOnDataset(config, train_path, model_dir, false, g.threads, g.quiet);
  const double train_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - train_start).count();

  // evaluation on held-out strikes, against a constant predictor (training mean z, mean angle)
  spdlog::info("step 3/3: evaluating on held-out strikes");
  const learning::FeatureSet test = ComputeDatasetFeatures(test_path, config, g.threads, !g.quiet);
  learning::Localizer localizer(model_dir);
  const learning::Metrics model_metrics =
      learning::ComputeMetrics(localizer.Predict(test), test, config.tube.outer_radius_m);
  DatasetReader train_reader(train_path);
  double z_sum = 0, c_sum = 0, s_sum = 0;
  int64_t n_valid = 0;
  for (int64_t i = 0; i < train_reader.size(); ++i) {
    const StrikeSample meta = train_reader.ReadMeta(i);
    if (!meta.valid) continue;
    z_sum += meta.label.z_m;
    c_sum += std::cos(meta.label.theta_rad);
    s_sum += std::sin(meta.label.theta_rad);
    ++n_valid;
  }
  const learning::Prediction constant{z_sum / n_valid, std::atan2(s_sum, c_sum)};
  const learning::Metrics baseline = learning::ComputeMetrics(
      std::vector<learning::Prediction>(test.size(), constant), test, config.tube.outer_radius_m);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // results: metrics.json is written last and marks the run finished
  json result = {{"run_dir", run_dir},
                 {"train_strikes", gen_train.written},
                 {"test_strikes", gen_test.written},
                 {"valid_train", gen_train.valid},
                 {"valid_test", gen_test.valid},
                 {"model", MetricsJson(model_metrics)},
                 {"validation", MetricsJson(val)},
                 {"constant_baseline", MetricsJson(baseline)},
                 {"generate_s", gen_train.wall_s + gen_test.wall_s},
                 {"train_s", train_s},
                 {"wall_s", wall_s}};
  WriteTextAtomic((fs::path(run_dir) / "metrics.json").string(), result.dump(2) + "\n");

  std::string text = fmt::format(
      "\nSonicBoom demo: {} held-out strikes (trained on {}, {} epochs, {} encoder, width {})\n\n",
      model_metrics.n, gen_train.valid, config.train.epochs, config.model.audio_encoder,
      config.model.width);
  text += "| method                       | 3-D MED (cm)  | height err (cm) | angle err (deg) |\n";
  text += "|------------------------------|---------------|-----------------|-----------------|\n";
  text += MetricsRow("multimodal transformer", model_metrics);
  text += MetricsRow("constant (train mean)", baseline);
  text += fmt::format("\nMED: mean 3-D distance between surface points (r = {} m). "
                      "Wall time {:.0f} s (simulate {:.0f} s, train {:.0f} s).\n"
                      "Run directory: {}\n",
                      config.tube.outer_radius_m, wall_s, gen_train.wall_s + gen_test.wall_s,
                      train_s, run_dir);
  return {result.dump(), text};
}

CommandResult RunGenerate(const GlobalOptions& g, const std::string& out, int64_t count,
                          int64_t first_index, int64_t shard, int64_t num_shards) {
  const SonicBoomConfig config = Resolve(g);
  RequireParentDir(out);
  const int64_t n = count > 0 ? count : config.dataset.count;
  if (count == 0 || count < -1) throw ConfigError(fmt::format("--count must be >= 1, got {}", count));
  const int64_t first = first_index >= 0 ? first_index : config.dataset.first_index;
  WriteConfigBeside(out, config);
  const GenerateResult r =
      GenerateDataset(config, out, n, first, shard, num_shards, g.threads, !g.quiet);
  json j = {{"path", r.path}, {"written", r.written}, {"valid", r.valid},
            {"clipped", r.clipped}, {"wall_s", r.wall_s},
            {"strikes_per_s", r.written / std::max(r.wall_s, 1e-9)}};
  return {j.dump(), fmt::format("wrote {} strikes ({} valid, {} clipped) to {} in {:.1f} s\n",
                                r.written, r.valid, r.clipped, r.path, r.wall_s)};
}

CommandResult RunMerge(const GlobalOptions& g, const std::string& out,
                       const std::vector<std::string>& shards) {
  RequireParentDir(out);
  MergeDatasets(shards, out);
  DatasetReader reader(out);
  WriteTextAtomic(out + ".config.yaml", reader.info().config_yaml);
  json j = {{"path", out}, {"num_samples", reader.size()}, {"shards", shards.size()}};
  return {j.dump(), fmt::format("merged {} shards into {} ({} samples)\n", shards.size(), out,
                                reader.size())};
}

CommandResult RunSynth(const GlobalOptions& g, const std::string& out_wav, int64_t index) {
  const SonicBoomConfig config = Resolve(g);
  RequireParentDir(out_wav);
  if (index < 0) throw ConfigError(fmt::format("--index must be >= 0, got {}", index));
  StrikePipeline pipeline(config);
  const StrikeSample s = pipeline.Simulate(static_cast<uint64_t>(index));
  if (!s.valid) {
    throw NumericalError(fmt::format("strike {} (seed {}) is invalid: {}", index, config.seed,
                                     s.invalid_reason));
  }
  // label sidecar and config first, the WAV last: a WAV on disk means the set is complete
  const std::string stem = (fs::path(out_wav).parent_path() / fs::path(out_wav).stem()).string();
  json label = LabelJson(s.label);
  label["index"] = s.index;
  label["seed"] = s.seed;
  label["global_seed"] = config.seed;
  label["sample_rate_hz"] = config.audio.sample_rate_hz;
  label["clipped"] = s.clipped;
  label["frame"] = "tube";
  WriteTextAtomic(stem + ".json", label.dump(2) + "\n");
  WriteConfigBeside(out_wav, config);
  try {
    WriteWav(out_wav, AudioClip{s.audio, config.audio.sample_rate_hz}, true);
  } catch (...) {
    fs::remove(stem + ".json");
    throw;
  }
  json j = {{"wav", out_wav}, {"label", stem + ".json"}, {"z_m", s.label.z_m},
            {"theta_rad", s.label.theta_rad}, {"clipped", s.clipped},
            {"peak", s.audio.cwiseAbs().maxCoeff()}};
  return {j.dump(), fmt::format("wrote {} (6 channels, {} Hz) and {}: z = {:.4f} m, theta = "
                                "{:.4f} rad\n",
                                out_wav, config.audio.sample_rate_hz, stem + ".json", s.label.z_m,
                                s.label.theta_rad)};
}

CommandResult RunModes(const GlobalOptions& g, const std::string& boundary, bool ideal,
                       int64_t count) {
  SonicBoomConfig config = Resolve(g);
  if (count < 1 || count > 5000) throw ConfigError(fmt::format("--count must be in [1, 5000], got {}", count));
  if (boundary != "free" && boundary != "simply-supported") {
    throw ConfigError(fmt::format("--boundary '{}' must be free or simply-supported", boundary));
  }
  config.shell.ends = boundary;
  if (ideal) config.shell.ideal = true;
  const acoustics::ShellModel model(config.tube, config.material, config.shell);
  bool cached = false;
  const acoustics::ShellModes modes = acoustics::CachedShellModes(
      model, 0.0, count, false, acoustics::DefaultModeCacheDir(), &cached);
  spdlog::info("modes {} the cache ({})", cached ? "read from" : "computed and stored in",
               acoustics::DefaultModeCacheDir());
  std::vector<double> f(static_cast<size_t>(modes.omega_rad_s.size()));
  for (size_t k = 0; k < f.size(); ++k) f[k] = modes.omega_rad_s[static_cast<Eigen::Index>(k)] / (2.0 * std::numbers::pi);
  json j = {{"frequencies_hz", f},
            {"boundary", boundary},
            {"ideal", config.shell.ideal},
            {"model", "numerical shell: Sanders theory on a staggered (z, theta) grid (acoustics/shell.h)"},
            {"grid_points", {model.axial_points(), model.circumferential_points()}},
            {"dofs", model.dofs()},
            {"rigid_body_modes", modes.rigid_body_modes},
            {"from_cache", cached}};
  std::string text = fmt::format(
      "{} lowest elastic modes, {} ends, {} tube ({} x {} grid, {} DOFs; {} rigid-body modes not "
      "listed; pairs listed twice):\n",
      f.size(), boundary, config.shell.ideal ? "ideal" : "seamed", model.axial_points(),
      model.circumferential_points(), model.dofs(), modes.rigid_body_modes);
  for (size_t i = 0; i < f.size(); ++i) text += fmt::format("{:4d}  {:10.1f} Hz\n", i + 1, f[i]);
  return {j.dump(), text};
}

CommandResult RunFeatures(const GlobalOptions& g, const std::string& in, const std::string& out,
                          const std::string& proprio_csv) {
  const SonicBoomConfig config = Resolve(g);
  RequireParentDir(out);
  std::vector<NamedArray> arrays;
  int64_t n = 1;
  learning::FeatureSet set;
  if (fs::path(in).extension() == ".h5") {
    // every valid sample of a dataset
    set = ComputeDatasetFeatures(in, config, g.threads, !g.quiet);
    n = set.size();
    arrays.push_back({"z_m", {n}, std::vector<float>(set.z_m.begin(), set.z_m.end())});
    arrays.push_back({"theta_rad", {n}, std::vector<float>(set.theta_rad.begin(), set.theta_rad.end())});
    arrays.push_back({"mel", {n, set.channels, set.mels, set.frames}, set.mel});
    arrays.push_back({"gcc", {n, set.gcc_pairs, set.gcc_lags}, set.gcc});
    arrays.push_back({"proprio", {n, set.proprio_rows, set.proprio_features}, set.proprio});
  } else {
    // one WAV (and optional robot log)
    const hardware::Capture cap =
        hardware::LoadCapture(in, proprio_csv, config.mics.count(), config.audio.sample_rate_hz);
    set = ComputeRecordFeatures(cap.audio, cap.sample_rate_hz, cap.proprio, config);
    arrays.push_back({"mel", {set.channels, set.mels, set.frames}, set.mel});
    arrays.push_back({"gcc", {set.gcc_pairs, set.gcc_lags}, set.gcc});
    if (cap.proprio.size() > 0) {
      arrays.push_back({"proprio", {set.proprio_rows, set.proprio_features}, set.proprio});
    }
  }
  WriteConfigBeside(out, config);
  WriteArrayFile(out, "sonicboom.features", arrays,
                 {{"source", in}, {"config_yaml", ConfigToYaml(config)},
                  {"mel_layout", fmt::format("power mel, n_fft {}, hop {}, {} HTK bands, {}",
                                             config.features.n_fft, config.features.hop,
                                             config.features.n_mels,
                                             config.features.log_mel ? "log10" : "no log")},
                  {"gcc_layout", "15 pairs in combinations order x lags -max..+max samples"}});
  json j = {{"path", out}, {"samples", n}, {"mel_shape", {set.channels, set.mels, set.frames}},
            {"gcc_shape", {set.gcc_pairs, set.gcc_lags}}};
  return {j.dump(), fmt::format("wrote {}: mel {} x {} x {}, GCC-PHAT {} x {} ({} sample{})\n", out,
                                set.channels, set.mels, set.frames, set.gcc_pairs, set.gcc_lags, n,
                                n == 1 ? "" : "s")};
}

CommandResult RunTrain(const GlobalOptions& g, const TrainOptions& o) {
  // a fine-tune starts from the pretrained run's config (its model and features), then the
  // user's layers; a fresh run from the defaults
  learning::FineTune fine_tune;
  fine_tune.init_from = o.init_from;
  fine_tune.freeze = learning::ParseFreeze(o.freeze);
  if (o.norm != "keep" && o.norm != "refit") {
    throw ConfigError(fmt::format("--norm '{}' must be keep or refit", o.norm));
  }
  fine_tune.refit_normalization = o.norm == "refit";
  if (o.init_from.empty() && (o.freeze != "none" || o.norm != "keep")) {
    throw ConfigError("--freeze and --norm apply to a fine-tune: give --init-from RUN");
  }
  if (!o.init_from.empty() && fs::absolute(o.init_from) == fs::absolute(o.out)) {
    throw ConfigError(fmt::format("--init-from {} is the output run; fine-tune into another directory", o.init_from));
  }
  const SonicBoomConfig config = o.init_from.empty() ? Resolve(g) : ResolveWithRun(g, o.init_from);
  if (!fs::exists(o.data)) throw IoError(fmt::format("{}: no such dataset", o.data));
  MakeDirectories(o.out);
  WriteTextAtomic((fs::path(o.out) / "config.yaml").string(), ConfigToYaml(config));
  if (!o.init_from.empty()) {
    const json init{{"init_from", o.init_from}, {"freeze", o.freeze}, {"norm", o.norm}};
    WriteTextAtomic((fs::path(o.out) / "fine_tune.json").string(), init.dump(2) + "\n");
  }
  const learning::Metrics m =
      TrainOnDataset(config, o.data, o.out, o.resume, g.threads, g.quiet, fine_tune);
  json j = MetricsJson(m);
  j["run_dir"] = o.out;
  return {j.dump(), fmt::format("trained {}: validation MED {:.2f} cm, height {:.2f} cm, angle "
                                "{:.1f} deg ({} strikes)\n",
                                o.out, m.med_cm, m.height_err_cm, m.angle_err_deg, m.n)};
}

CommandResult RunEval(const GlobalOptions& g, const std::string& model_dir,
                      const std::string& data) {
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  learning::Localizer localizer(model_dir);
  const learning::FeatureSet set = ComputeDatasetFeatures(data, config, g.threads, !g.quiet);
  const learning::Metrics m =
      learning::ComputeMetrics(localizer.Predict(set), set, localizer.surface_radius_m());
  std::string text = fmt::format("{} strikes: MED {:.2f} cm, height {:.2f} cm, angle {:.1f} deg "
                                 "(published-code MED {:.2f})\n",
                                 m.n, m.med_cm, m.height_err_cm, m.angle_err_deg,
                                 m.reference_med_cm);
  if (std::isfinite(m.nll)) {
    text += fmt::format("coverage of the 50 % / 90 % intervals: z {:.2f} / {:.2f}, theta {:.2f} / "
                        "{:.2f}; mean NLL {:.3f} (z in cm, theta in rad)\n",
                        m.z_coverage_50, m.z_coverage_90, m.theta_coverage_50,
                        m.theta_coverage_90, m.nll);
  }
  return {MetricsJson(m).dump(), text};
}

CommandResult RunLocalizeByArrival(const GlobalOptions& g, const std::string& wav) {
  const SonicBoomConfig config = Resolve(g);
  const auto start = std::chrono::steady_clock::now();
  const hardware::Capture cap =
      hardware::LoadCapture(wav, "", config.mics.count(), config.audio.sample_rate_hz);
  const acoustics::ArrivalLocator locator(TdoaGeometryOf(config), config.arrival,
                                          config.audio.sample_rate_hz);
  const int64_t onset = acoustics::DetectOnset(cap.audio, config.audio.sample_rate_hz,
                                               config.features.onset_frame_s,
                                               config.features.onset_threshold);
  acoustics::ArrivalEstimate e;
  try {
    e = locator.Locate(cap.audio, onset);
  } catch (const NumericalError& err) {
    throw NumericalError(fmt::format("{}: {}", wav, err.what()));
  }
  const double ms = MillisecondsSince(start);
  const Eigen::Vector3d point = SurfacePoint(config.tube, e.z_m, e.theta_rad);
  const json j = {{"method", "arrival"}, {"z_m", e.z_m}, {"theta_rad", e.theta_rad},
                  {"point_m", {point.x(), point.y(), point.z()}}, {"frame", "tube"},
                  {"onset_s", static_cast<double>(onset) / config.audio.sample_rate_hz},
                  {"arrival_s", e.arrival_s}, {"speed_m_s", e.speed_m_s},
                  {"residual_s", e.residual_s}, {"latency_ms", ms}};
  return {j.dump(), fmt::format("contact at z = {:.4f} m, theta = {:.4f} rad (arrival times, no "
                                "model; fitted speed {:.0f} m/s, residual {:.2f} ms)\n",
                                e.z_m, e.theta_rad, e.speed_m_s, 1e3 * e.residual_s)};
}

CommandResult RunLocalize(const GlobalOptions& g, const std::string& model_dir,
                          const std::string& wav, const std::string& proprio_csv, int64_t repeat) {
  if (repeat < 1) throw ConfigError(fmt::format("--repeat must be >= 1, got {}", repeat));
  // set-up, once per process: the model, the gate's reference clip, FFT plans
  const auto setup_start = std::chrono::steady_clock::now();
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  learning::Localizer localizer(model_dir);
  // only what the model reads: its modalities, and of the spectrogram only its crop
  const RecordFeaturizer featurizer(config, config.audio.sample_rate_hz, config.mics.count(),
                                    localizer.needs());
  const double setup_ms = MillisecondsSince(setup_start);
  // per strike: WAV (and robot log) read -> features -> network -> answer; the median of
  // `repeat` runs is the latency
  // per run: total, read, features, network (ms)
  std::array<std::vector<double>, 4> stage_ms;
  learning::Prediction p;
  for (int64_t r = 0; r < repeat; ++r) {
    const auto start = std::chrono::steady_clock::now();
    const hardware::Capture cap =
        hardware::LoadCapture(wav, proprio_csv, config.mics.count(), config.audio.sample_rate_hz);
    const auto read = std::chrono::steady_clock::now();
    const learning::FeatureSet features = featurizer.Compute(cap.audio, cap.proprio);
    const auto featured = std::chrono::steady_clock::now();
    p = localizer.Predict(features).front();
    const auto done = std::chrono::steady_clock::now();
    auto ms = [](auto from, auto to) {
      return std::chrono::duration<double, std::milli>(to - from).count();
    };
    stage_ms[0].push_back(ms(start, done));
    stage_ms[1].push_back(ms(start, read));
    stage_ms[2].push_back(ms(read, featured));
    stage_ms[3].push_back(ms(featured, done));
  }
  // medians over the runs, each stage on its own (the mean of the middle two for an even count)
  std::array<double, 4> median{};
  for (size_t i = 0; i < stage_ms.size(); ++i) {
    std::vector<double>& v = stage_ms[i];
    const auto upper = v.begin() + repeat / 2;
    std::nth_element(v.begin(), upper, v.end());
    median[i] = repeat % 2 == 1 ? *upper : 0.5 * (*upper + *std::max_element(v.begin(), upper));
  }
  const double median_ms = median[0];
  std::string text;
  json j = PredictionJson(p, config.tube, &text);
  j["latency_ms"] = median_ms;
  j["setup_ms"] = setup_ms;
  j["latency_breakdown_ms"] = {{"read", median[1]}, {"features", median[2]}, {"network", median[3]}};
  text += fmt::format("latency {:.1f} ms from WAV read to answer (median of {}: read {:.1f}, "
                      "features {:.1f}, network {:.1f}); set-up {:.0f} ms\n",
                      median_ms, repeat, median[1], median[2], median[3], setup_ms);
  return {j.dump(), text};
}

CommandResult RunFk(const GlobalOptions& g, const std::string& joints) {
  const SonicBoomConfig config = Resolve(g);
  // seven comma-separated angles inside the joint limits
  std::vector<double> q_list;
  std::stringstream ss(joints);
  for (std::string cell; std::getline(ss, cell, ',');) {
    try {
      size_t used = 0;
      q_list.push_back(std::stod(cell, &used));
      if (used != cell.size()) throw std::invalid_argument(cell);
    } catch (const std::exception&) {
      throw ConfigError(fmt::format("--joints: '{}' is not a number", cell));
    }
  }
  if (q_list.size() != sim::kPandaJoints) {
    throw ConfigError(fmt::format("--joints needs {} values, got {}", sim::kPandaJoints, q_list.size()));
  }
  sim::JointVector q;
  const sim::JointVector lo = sim::PandaLowerLimits(), hi = sim::PandaUpperLimits();
  for (int i = 0; i < sim::kPandaJoints; ++i) {
    q[i] = q_list[i];
    if (!std::isfinite(q[i]) || q[i] < lo[i] || q[i] > hi[i]) {
      throw ConfigError(fmt::format("--joints: joint {} = {} rad is outside its limits [{}, {}]",
                                    i + 1, q[i], lo[i], hi[i]));
    }
  }
  const sim::PandaPoses poses = sim::PandaForwardKinematics(q, config.tube.center_from_flange_m);
  auto quat = [](const Eigen::Isometry3d& t) {
    const Eigen::Quaterniond qt(t.linear());
    return std::vector<double>{qt.w(), qt.x(), qt.y(), qt.z()};
  };
  auto pos = [](const Eigen::Isometry3d& t) {
    return std::vector<double>{t.translation().x(), t.translation().y(), t.translation().z()};
  };
  json j = {{"flange_pos_m", pos(poses.flange)},
            {"flange_quat_wxyz", quat(poses.flange)},
            {"tube_center_pos_m", pos(poses.tube)},
            {"tube_quat_wxyz", quat(poses.tube)}};
  const auto fp = pos(poses.flange), tp = pos(poses.tube);
  return {j.dump(), fmt::format("flange at ({:.4f}, {:.4f}, {:.4f}) m, tube centre at ({:.4f}, "
                                "{:.4f}, {:.4f}) m (robot base frame)\n",
                                fp[0], fp[1], fp[2], tp[0], tp[1], tp[2])};
}

CommandResult RunInspect(const GlobalOptions& g, const std::string& path) {
  if (!fs::exists(path)) throw IoError(fmt::format("{}: no such file or directory", path));
  json j;
  if (fs::is_directory(path)) {
    // a run directory: its config, model card and metrics
    j = {{"kind", "run"}, {"path", path}};
    for (const char* name : {"model.json", "metrics.json"}) {
      const fs::path p = fs::path(path) / name;
      if (fs::exists(p)) j[fs::path(name).stem().string()] = json::parse(ReadText(p.string()), nullptr, false);
    }
    const fs::path metrics_lines = fs::path(path) / "metrics.jsonl";
    if (fs::exists(metrics_lines)) {
      std::stringstream ss(ReadText(metrics_lines.string()));
      int64_t epochs = 0;
      std::string last;
      for (std::string line; std::getline(ss, line);) {
        if (!line.empty()) {
          ++epochs;
          last = line;
        }
      }
      j["epochs_logged"] = epochs;
      if (!last.empty()) j["last_epoch"] = json::parse(last, nullptr, false);
    }
    j["complete"] = fs::exists(fs::path(path) / "model.json") || fs::exists(fs::path(path) / "metrics.json");
    // trainable parameters per part of a finished model
    if (fs::exists(fs::path(path) / "model.json") && fs::exists(fs::path(path) / "model.pt")) {
      const learning::Localizer localizer(path);
      json parameters;
      int64_t total = 0;
      for (const auto& [part, count] : localizer.ParameterCounts()) {
        parameters[part] = count;
        total += count;
      }
      parameters["total"] = total;
      j["parameters"] = parameters;
    }
  } else if (fs::path(path).extension() == ".wav") {
    // a WAV and its label sidecar
    const AudioClip clip = ReadWav(path);
    j = {{"kind", "wav"}, {"path", path}, {"channels", clip.channels()},
         {"frames", clip.frames()}, {"sample_rate_hz", clip.sample_rate_hz},
         {"duration_s", clip.frames() / clip.sample_rate_hz},
         {"peak", clip.samples.cwiseAbs().maxCoeff()},
         {"finite", clip.samples.allFinite()}};
    std::vector<double> rms;
    for (int c = 0; c < clip.channels(); ++c) {
      rms.push_back(std::sqrt(clip.samples.row(c).cast<double>().squaredNorm() / clip.frames()));
    }
    j["rms"] = rms;
    const std::string sidecar =
        (fs::path(path).parent_path() / fs::path(path).stem()).string() + ".json";
    if (fs::exists(sidecar)) j["label"] = json::parse(ReadText(sidecar), nullptr, false);
  } else if (fs::path(path).extension() == ".json") {
    // a label sidecar, model card or metrics file
    const json parsed = json::parse(ReadText(path), nullptr, false);
    if (parsed.is_discarded()) throw IoError(fmt::format("{}: not valid JSON", path));
    j = {{"kind", "json"}, {"path", path}, {"content", parsed}};
  } else if (fs::path(path).extension() == ".jsonl") {
    // per-epoch metrics: count and last line
    std::stringstream ss(ReadText(path));
    int64_t lines = 0;
    json last;
    for (std::string line; std::getline(ss, line);) {
      if (line.empty()) continue;
      ++lines;
      last = json::parse(line, nullptr, false);
      if (last.is_discarded()) throw IoError(fmt::format("{}:{}: not valid JSON", path, lines));
    }
    j = {{"kind", "jsonl"}, {"path", path}, {"lines", lines}, {"last", last}};
  } else if (fs::path(path).extension() == ".csv") {
    // a robot log
    const Eigen::MatrixXf proprio = hardware::ReadProprioCsv(path);
    j = {{"kind", "robot_log"}, {"path", path}, {"rows", proprio.rows()},
         {"finite", proprio.allFinite()}};
  } else if (fs::path(path).extension() == ".pt") {
    // torch weights: the model card beside them describes them
    j = {{"kind", "torch_weights"}, {"path", path}, {"bytes", fs::file_size(path)}};
    const fs::path card = fs::path(path).parent_path() / "model.json";
    if (fs::exists(card)) j["model"] = json::parse(ReadText(card.string()), nullptr, false);
  } else if (fs::path(path).extension() == ".yaml" || fs::path(path).extension() == ".yml") {
    // a config: resolve and validate it
    GlobalOptions with_file = g;
    with_file.sources.files.insert(with_file.sources.files.begin(), path);
    const SonicBoomConfig config = Resolve(with_file);
    j = {{"kind", "config"}, {"path", path}, {"valid", true}, {"resolved_yaml", ConfigToYaml(config)}};
  } else {
    // HDF5: a dataset or any other file we write
    std::string schema;
    try {
      schema = ReadStringAttr(path, "schema");
    } catch (const Error&) {
      schema.clear();
    }
    j = json::parse(schema == kDatasetSchema ? SummarizeDatasetJson(path) : SummarizeH5Json(path));
  }
  return {j.dump(), j.dump(2) + "\n"};
}

namespace {

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

}  // namespace

CommandResult RunBaseline(const GlobalOptions& g, const BaselineOptions& o) {
  if (o.method != "knn" && o.method != "tdoa" && o.method != "constant" && o.method != "arrival") {
    throw ConfigError(fmt::format("--method '{}' must be knn, tdoa, arrival or constant", o.method));
  }
  if ((o.method == "knn" || o.method == "constant") && o.train.empty()) {
    throw ConfigError(fmt::format("--method {} needs --train TRAIN.h5", o.method));
  }
  for (const std::string& path : {o.data, o.train}) {
    if (!path.empty() && !fs::exists(path)) throw IoError(fmt::format("{}: no such dataset", path));
  }
  const SonicBoomConfig config = ResolveWithDataset(g, o.data);
  const double radius = config.tube.outer_radius_m;
  std::vector<learning::Prediction> predictions;
  learning::FeatureSet truth;
  json extra;
  std::string detail;

  if (o.method == "constant") {
    // mean height and circular mean angle of the training labels
    const learning::FeatureSet train = DatasetLabels(o.train);
    const learning::Prediction p = learning::ConstantPrediction(train.z_m, train.theta_rad);
    truth = DatasetLabels(o.data);
    predictions.assign(static_cast<size_t>(truth.size()), p);
    extra = {{"train_n", train.size()}, {"z_m", p.z_m}, {"theta_rad", p.theta_rad}};
  } else if (o.method == "arrival") {
    // first arrivals per channel, fitted by surface paths and one free wave speed; no training
    const double fs = DatasetReader(o.data).info().sample_rate_hz;
    const acoustics::ArrivalLocator locator(TdoaGeometryOf(config), config.arrival, fs);
    std::vector<acoustics::ArrivalEstimate> estimates;
    predictions = LocateByArrival(o.data, config, locator, g.threads, !g.quiet, &truth, &estimates);
    std::vector<double> speeds;
    for (const acoustics::ArrivalEstimate& e : estimates) speeds.push_back(e.speed_m_s);
    std::sort(speeds.begin(), speeds.end());
    const double median_speed = speeds.empty() ? 0.0 : speeds[speeds.size() / 2];
    extra = {{"median_speed_m_s", median_speed}};
    detail = fmt::format(" (no training; median fitted speed {:.0f} m/s)", median_speed);
  } else if (o.method == "knn") {
    // pooled log-mel (+ GCC lags) of the training strikes, k nearest by standardized distance
    const learning::FeatureSet train = ComputeDatasetFeatures(o.train, config, g.threads, !g.quiet);
    truth = ComputeDatasetFeatures(o.data, config, g.threads, !g.quiet);
    learning::KnnConfig knn_config;
    knn_config.k = o.k;
    knn_config.crop_frames = config.model.crop_frames;
    knn_config.mel_is_log = config.features.log_mel;
    knn_config.gcc_lags = o.knn_gcc_lags;
    knn_config.threads = g.threads;
    const learning::KnnBaseline knn(train, knn_config);
    predictions = knn.Predict(truth);
    extra = {{"train_n", knn.size()}, {"k", o.k}, {"dimensions", knn.dimensions()},
             {"gcc_lags", o.knn_gcc_lags}};
    detail = fmt::format(" (k = {}, {} training strikes, {} dimensions)", o.k, knn.size(),
                         knn.dimensions());
  } else {
    // steered response of band GCC-PHAT envelopes over the contact region
    acoustics::TdoaConfig tdoa_config;
    tdoa_config.dispersive = !o.non_dispersive;
    if (!o.bands_hz.empty()) tdoa_config.band_edges_hz = o.bands_hz;
    const double fs = DatasetReader(o.data).info().sample_rate_hz;
    const acoustics::TdoaLocator locator(TdoaGeometryOf(config), tdoa_config, fs);
    std::vector<double> speeds;
    for (int b = 0; b < locator.bands(); ++b) speeds.push_back(locator.BandSpeed(b));
    double scale = 1.0;
    extra = {{"dispersive", tdoa_config.dispersive}, {"band_edges_hz", tdoa_config.band_edges_hz},
             {"band_speeds_m_s", speeds}, {"seamed", !TdoaGeometryOf(config).seam_theta_rad.empty()}};
    if (!o.train.empty() && !o.no_fit) {
      // one global speed scale, fitted on (at most fit_strikes) training strikes; the range
      // holds the simulated tube's best scale (about 0.5, docs/baselines.md) with room
      constexpr double kFitLo = 0.3, kFitHi = 1.5;
      learning::FeatureSet fit_labels;
      const std::vector<acoustics::TdoaCorrelations> fit = CorrelateDataset(
          o.train, config, locator, g.threads, !g.quiet, o.fit_strikes, &fit_labels);
      double fit_med_m = 0.0;
      scale = acoustics::FitSpeedScale(locator, fit, fit_labels.z_m, fit_labels.theta_rad, radius,
                                       kFitLo, kFitHi, g.threads, &fit_med_m);
      extra["fit_strikes"] = fit_labels.size();
      extra["fit_med_cm"] = 100.0 * fit_med_m;
    }
    const std::vector<acoustics::TdoaCorrelations> test =
        CorrelateDataset(o.data, config, locator, g.threads, !g.quiet, 0, &truth);
    predictions = LocateAll(locator, test, scale, g.threads);
    extra["speed_scale"] = scale;
    detail = fmt::format(" ({}, speed scale {:.3f})",
                         tdoa_config.dispersive ? "per-band group velocity" : "one speed", scale);
    if (scale != 1.0) {
      // the pure analytic figure beside the fitted one
      const learning::Metrics analytic =
          learning::ComputeMetrics(LocateAll(locator, test, 1.0, g.threads), truth, radius);
      extra["analytic"] = MetricsJson(analytic);
      detail += fmt::format("; analytic speeds: MED {:.2f} cm", analytic.med_cm);
    }
  }

  const learning::Metrics m = learning::ComputeMetrics(predictions, truth, radius);
  json j = MetricsJson(m);
  j["method"] = o.method;
  j.update(extra);
  return {j.dump(), fmt::format("{} baseline, {} strikes: MED {:.2f} cm, height {:.2f} cm, angle "
                                "{:.1f} deg (published-code MED {:.2f}){}\n",
                                o.method, m.n, m.med_cm, m.height_err_cm, m.angle_err_deg,
                                m.reference_med_cm, detail)};
}

}  // namespace sonicboom::experiments
