// `listen`: live localization from a sound device, or a WAV file read as one (docs/captures.md).
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/hardware/stream.h"
#include "sonicboom/hardware/trigger.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

// A session directory in the capture layout: each record as a WAV, a labels.csv row to fill in
// with the measured position, the model's answer, and the rig (the run's config).
class SessionWriter {
 public:
  SessionWriter(const std::string& dir, const SonicBoomConfig& config) : dir_(dir) {
    if (dir_.empty()) return;
    // a session goes into a new or empty directory: nothing of the user's is written over
    std::error_code ec;
    if (fs::exists(dir_) && !(fs::is_directory(dir_) && fs::is_empty(dir_, ec) && !ec)) {
      throw IoError(fmt::format("{}: {}; save into a new or empty directory", dir_,
                                fs::exists(fs::path(dir_) / "labels.csv")
                                    ? "already holds a session (labels.csv)"
                                    : fs::is_directory(dir_) ? "is not empty" : "is a file"));
    }
    MakeDirectories(dir_);
    WriteTextAtomic((fs::path(dir_) / "capture.yaml").string(), ConfigToYaml(config));
    labels_.open(fs::path(dir_) / "labels.csv");
    labels_ << "file,z_m,theta_rad\n" << std::flush;
    predictions_.open(fs::path(dir_) / "predictions.jsonl");
  }
  // the capture's file name ("" when not saving)
  std::string Save(int64_t event, const Eigen::MatrixXf& audio, double rate, const json& answer) {
    if (dir_.empty()) return {};
    const std::string name = fmt::format("capture_{:05}.wav", event);
    WriteWav((fs::path(dir_) / name).string(), AudioClip{audio, rate});
    labels_ << name << ",,\n" << std::flush;  // z_m and theta_rad: measured, filled in later
    json line = answer;
    line["file"] = name;
    predictions_ << line.dump() << "\n" << std::flush;
    if (!labels_ || !predictions_)
      throw IoError(fmt::format("{}: cannot write the session files", dir_));
    return name;
  }

 private:
  std::string dir_;
  std::ofstream labels_, predictions_;
};

}  // namespace

CommandResult RunListen(const GlobalOptions& g, const ListenOptions& o) {
  if (o.model.empty()) throw ConfigError("listen needs --model RUN");
  if (o.max_events < 0)
    throw ConfigError(fmt::format("--max-events {} must be >= 0", o.max_events));
  if (!o.save.empty()) {
    RefuseWritingOverInputs(g, {o.save, "--save"}, {{o.model, "--model"}, {o.wav, "--wav"}});
  }
  const SonicBoomConfig config = ResolveWithRun(g, o.model);
  const double rate = config.audio.sample_rate_hz;
  const int channels = config.mics.count();

  // the stream: a WAV file read as a device, or the device itself
  const std::unique_ptr<hardware::AudioSource> source =
      o.wav.empty() ? hardware::OpenDeviceSource(o.device, channels, rate)
                    : hardware::OpenWavSource(o.wav, o.realtime);
  if (source->channels() != channels || std::abs(source->sample_rate_hz() - rate) > 1e-6) {
    throw IoError(fmt::format("{}: {} channels at {} Hz; the model takes {} at {} Hz",
                              source->name(), source->channels(), source->sample_rate_hz(),
                              channels, rate));
  }

  // records cut like the dataset's: audio.onset_time_s before the onset, record_duration_s long
  hardware::TriggerConfig trigger_config;
  trigger_config.sample_rate_hz = rate;
  trigger_config.channels = channels;
  trigger_config.record_frames = config.audio.num_samples();
  trigger_config.pre_trigger_frames = std::llround(config.audio.onset_time_s * rate);
  trigger_config.threshold_db = o.threshold_db;
  hardware::OnsetTrigger trigger(trigger_config);
  learning::Localizer localizer(o.model);
  const RecordFeaturizer featurizer(config, rate, channels, localizer.needs());
  const Eigen::MatrixXf
      no_log;  // no robot log: the model's proprio input is absent, as in localize
  SessionWriter session(o.save, config);

  // stream -> trigger -> features -> network -> one JSON line per strike, as it happens
  Eigen::MatrixXf block(channels, 1024);  // 23 ms at 44.1 kHz
  std::vector<hardware::TriggeredRecord> records;
  int64_t events = 0;
  bool more = true;
  while (more && (o.max_events == 0 || events < o.max_events)) {
    const int64_t n = source->Read(&block);
    if (n < block.cols()) {
      if (n > 0) trigger.Push(block.leftCols(n), &records);
      trigger.Flush(&records);
      more = false;
    } else {
      trigger.Push(block, &records);
    }
    for (const hardware::TriggeredRecord& r : records) {
      if (o.max_events > 0 && events >= o.max_events) break;
      // a trigger on something that is no strike (noise, hum, arm motion, a level step) gets no
      // line
      const dsp::StrikeCheck check = dsp::CheckStrike(r.audio, rate);
      if (!check.found) {
        spdlog::info("listen: trigger at {:.3f} s skipped: {}", r.onset_frame / rate,
                     check.reason);
        continue;
      }
      const auto start = Clock::now();
      const learning::Prediction p = localizer.Predict(featurizer.Compute(r.audio, no_log)).front();
      const auto done = Clock::now();
      std::string text;
      json line = PredictionJson(p, config.tube, &text);
      line["event"] = events;
      line["onset_s"] = r.onset_frame / rate;
      line["latency_ms"] = Ms(r.onset_seen, done);  // onset heard -> answer
      line["compute_ms"] = Ms(start, done);         // features and network
      const std::string file = session.Save(events, r.audio, rate, line);
      if (!file.empty()) line["file"] = file;
      std::cout << (g.json ? line.dump() + "\n"
                           : fmt::format("[{}] onset {:.3f} s: {}", events, r.onset_frame / rate,
                                         text));
      std::cout.flush();
      ++events;
    }
    records.clear();
  }
  const double seconds = trigger.frames_seen() / rate;
  const json summary = {{"summary", true},     {"events", events},
                        {"stream_s", seconds}, {"source", source->name()},
                        {"saved_to", o.save},  {"input_overflows", source->overflows()}};
  return {summary.dump(), fmt::format("{} strikes in {:.1f} s of {}{}{}\n", events, seconds,
                                      source->name(), o.save.empty() ? "" : ", saved to " + o.save,
                                      source->overflows() == 0
                                          ? ""
                                          : fmt::format("; input overflowed {} times (frames lost)",
                                                        source->overflows()))};
}

void RegisterListen(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<ListenOptions>();
  auto* listen = app.add_subcommand("listen",
                                    "live localization: strikes from a sound device (or "
                                    "a WAV read as one), one JSON line each");
  listen->add_option("--model", o->model, "run directory")->required();
  listen->add_option("--device", o->device,
                     "input device, part of its name (ALSA, e.g. hw:1,0); default input if empty");
  listen->add_option("--wav", o->wav, "read this WAV as the device stream");
  listen->add_flag("--realtime", o->realtime, "pace the WAV at its sample rate");
  listen->add_option("--save", o->save, "session directory (capture layout)");
  listen->add_option("--max-events", o->max_events, "stop after N strikes (0: never)");
  listen->add_option("--threshold-db", o->threshold_db,
                     "onset threshold above the noise floor (default 20)");
  listen->callback([&g, run, o] { *run = [&g, o] { return RunListen(g, *o); }; });
}

}  // namespace sonicboom::experiments
