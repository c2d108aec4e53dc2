// `localize`: the contact of one recorded strike, by a trained run or by first arrivals.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/statistics.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

namespace {

// localize's answer: a trained run's, or the training-free arrival locator's
enum class LocalizeMethod { kNetwork, kArrival };
constexpr EnumName<LocalizeMethod> kLocalizeMethodNames[] = {{LocalizeMethod::kNetwork, "network"},
                                                             {LocalizeMethod::kArrival, "arrival"}};
std::span<const EnumName<LocalizeMethod>> EnumNames(LocalizeMethod) {
  return kLocalizeMethodNames;
}

}  // namespace

namespace {

// A record with no strike in it (noise, hum, arm motion or a constant level alone, or one cut off
// at the end: dsp::CheckStrike's rule) is refused, not answered with a location
void RequireStrike(const Eigen::MatrixXf& audio, const SonicBoomConfig& config,
                   const std::string& wav) {
  const dsp::StrikeCheck check = dsp::CheckStrike(audio, config.audio.sample_rate_hz);
  if (!check.found) throw NumericalError(fmt::format("{}: {}", wav, check.reason));
}

// Stage times of repeated runs of the per-strike path: per run, the total and each stage (ms);
// medians over the runs
class StageTimes {
 public:
  explicit StageTimes(size_t stages) : ms_(stages + 1) {}
  using Clock = std::chrono::steady_clock;
  // one run, from its start and the instant each stage ended
  void Add(Clock::time_point start, const std::vector<Clock::time_point>& ends) {
    SONICBOOM_DEMAND(ends.size() + 1 == ms_.size());
    auto ms = [](auto from, auto to) {
      return std::chrono::duration<double, std::milli>(to - from).count();
    };
    ms_[0].push_back(ms(start, ends.back()));
    for (size_t i = 0; i < ends.size(); ++i)
      ms_[i + 1].push_back(ms(i ? ends[i - 1] : start, ends[i]));
  }
  // the total's median (index 0) or stage i's (1..stages)
  double MedianMs(size_t i) const { return Median(ms_[i]); }

 private:
  std::vector<std::vector<double>> ms_;  // (1 + stages) x runs
};

// a timing loop, not a workload: 10 000 runs give a stable median in well under an hour
void RequireRepeat(int64_t repeat) {
  constexpr int64_t kMaxRepeat = 10000;
  if (repeat < 1 || repeat > kMaxRepeat) {
    throw ConfigError(fmt::format("--repeat must be in [1, {}], got {}", kMaxRepeat, repeat));
  }
}

}  // namespace

CommandResult RunLocalizeByArrival(const GlobalOptions& g, const std::string& wav, int64_t repeat) {
  RequireRepeat(repeat);
  // set-up, once per process: the search grid's surface paths to every microphone
  const auto setup_start = StageTimes::Clock::now();
  const SonicBoomConfig config = Resolve(g);
  const acoustics::ArrivalLocator locator(TdoaGeometryOf(config), config.arrival,
                                          config.audio.sample_rate_hz);
  const double setup_ms = MillisecondsSince(setup_start);
  // per strike: WAV read -> onset and picks -> grid search; the median of `repeat` runs
  StageTimes times(3);
  acoustics::ArrivalEstimate e;
  int64_t onset = 0;
  for (int64_t r = 0; r < repeat; ++r) {
    const auto start = StageTimes::Clock::now();
    const hardware::Capture cap = hardware::LoadCapture(wav, "", CaptureChecksFor(config));
    if (r == 0) RequireStrike(cap.audio, config, wav);
    const auto read = StageTimes::Clock::now();
    onset = dsp::DetectOnset(cap.audio, config.audio.sample_rate_hz, config.features.onset_frame_s,
                             config.features.onset_threshold);
    std::vector<double> picks;
    try {
      picks = locator.PickArrivals(cap.audio, onset);
    } catch (const NumericalError& err) {
      throw NumericalError(fmt::format("{}: {}", wav, err.what()));
    }
    const auto picked = StageTimes::Clock::now();
    e = locator.Locate(picks);
    times.Add(start, {read, picked, StageTimes::Clock::now()});
  }
  const Eigen::Vector3d point = SurfacePoint(config.tube, e.z_m, e.theta_rad);
  const json j = {
      {"method", "arrival"},
      {"z_m", e.z_m},
      {"theta_rad", e.theta_rad},
      {"point_m", {point.x(), point.y(), point.z()}},
      {"frame", "tube"},
      {"onset_s", static_cast<double>(onset) / config.audio.sample_rate_hz},
      {"arrival_s", e.arrival_s},
      {"speed_m_s", e.speed_m_s},
      {"residual_s", e.residual_s},
      {"latency_ms", times.MedianMs(0)},
      {"setup_ms", setup_ms},
      {"latency_breakdown_ms",
       {{"read", times.MedianMs(1)}, {"picks", times.MedianMs(2)}, {"search", times.MedianMs(3)}}}};
  return {j.dump(),
          fmt::format("contact at z = {:.4f} m, theta = {:.4f} rad (arrival times, no model; "
                      "fitted speed {:.0f} m/s, residual {:.2f} ms)\nlatency {:.2f} ms from WAV "
                      "read to answer (median of {}: read {:.2f}, picks {:.2f}, search {:.2f}); "
                      "set-up {:.0f} ms\n",
                      e.z_m, e.theta_rad, e.speed_m_s, 1e3 * e.residual_s, times.MedianMs(0),
                      repeat, times.MedianMs(1), times.MedianMs(2), times.MedianMs(3), setup_ms)};
}

CommandResult RunLocalize(const GlobalOptions& g, const std::string& model_dir,
                          const std::string& wav, const std::string& proprio_csv, int64_t repeat) {
  RequireRepeat(repeat);
  // set-up, once per process: the model, the gate's reference clip, FFT plans
  const auto setup_start = StageTimes::Clock::now();
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  learning::Localizer localizer(model_dir);
  // only what the model reads: its modalities, and of the spectrogram only its crop
  const RecordFeaturizer featurizer(config, config.audio.sample_rate_hz, config.mics.count(),
                                    localizer.needs());
  const double setup_ms = MillisecondsSince(setup_start);
  // per strike: WAV (and robot log) read -> features -> network -> answer; the median of
  // `repeat` runs is the latency
  StageTimes times(3);
  learning::Prediction p;
  for (int64_t r = 0; r < repeat; ++r) {
    const auto start = StageTimes::Clock::now();
    const hardware::Capture cap = hardware::LoadCapture(wav, proprio_csv, CaptureChecksFor(config));
    if (r == 0) RequireStrike(cap.audio, config, wav);
    const auto read = StageTimes::Clock::now();
    const learning::FeatureSet features = featurizer.Compute(cap.audio, cap.proprio);
    const auto featured = StageTimes::Clock::now();
    p = localizer.Predict(features).front();
    times.Add(start, {read, featured, StageTimes::Clock::now()});
  }
  std::string text;
  json j = PredictionJson(p, config.tube, &text);
  j["latency_ms"] = times.MedianMs(0);
  j["setup_ms"] = setup_ms;
  j["latency_breakdown_ms"] = {
      {"read", times.MedianMs(1)}, {"features", times.MedianMs(2)}, {"network", times.MedianMs(3)}};
  text += fmt::format(
      "latency {:.1f} ms from WAV read to answer (median of {}: read {:.1f}, "
      "features {:.1f}, network {:.1f}); set-up {:.0f} ms\n",
      times.MedianMs(0), repeat, times.MedianMs(1), times.MedianMs(2), times.MedianMs(3), setup_ms);
  return {j.dump(), text};
}

void RegisterLocalize(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    LocalizeMethod method = LocalizeMethod::kNetwork;
    std::string model, wav, proprio;
    int64_t repeat = 1;
  };
  auto o = std::make_shared<Options>();
  auto* localize = app.add_subcommand("localize", "locate the contact of one recorded strike");
  AddEnumOption(localize, "--method", &o->method,
                "network (a trained run, --model) | arrival (no training: first arrivals)");
  localize->add_option("--model", o->model, "run directory (--method network)");
  localize->add_option("--wav", o->wav, "6-channel WAV")->required();
  localize->add_option("--proprio", o->proprio, "robot log CSV");
  localize->add_option("--repeat", o->repeat,
                       "time the WAV-read-to-answer path this many times (median reported)");
  localize->callback([&g, run, o] {
    *run = [&g, o] {
      if (o->method == LocalizeMethod::kArrival) {
        if (!o->model.empty()) throw ConfigError("localize --method arrival uses no --model");
        return RunLocalizeByArrival(g, o->wav, o->repeat);
      }
      if (o->model.empty()) throw ConfigError("localize --method network needs --model RUN");
      return RunLocalize(g, o->model, o->wav, o->proprio, o->repeat);
    };
  });
}

}  // namespace sonicboom::experiments
