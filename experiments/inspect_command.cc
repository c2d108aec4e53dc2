// `inspect`: a summary of any file or run directory SonicBoom wrote.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/array_file.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Figure-sized data (docs/cli.md, inspect): at most this many columns per waveform panel and
// time frames per spectrogram, whatever the record's length
constexpr int64_t kEnvelopeColumns = 1500;
constexpr int64_t kSpectrogramFrames = 300;
constexpr int64_t kSpectrogramMels = 64;
constexpr double kSpectrogramFloorDb = -80.0;  // below the strike's loudest bin: drawn as floor

// Envelope values are whole counts of full scale / kEnvelopeCounts (16-bit resolution).
constexpr double kEnvelopeCounts = 32767.0;

// One channel's min and max over each of `columns` equal stretches of x (the waveform as drawn),
// in counts of full scale / kEnvelopeCounts.
json Envelope(const std::vector<float>& x, int64_t columns) {
  const auto n = static_cast<int64_t>(x.size());
  columns = std::max<int64_t>(1, std::min(columns, n));
  std::vector<int> lo(columns), hi(columns);
  for (int64_t c = 0; c < columns; ++c) {
    const auto first = x.begin() + c * n / columns, last = x.begin() + (c + 1) * n / columns;
    const auto [mn, mx] = std::minmax_element(first, std::max(last, first + 1));
    lo[c] = static_cast<int>(std::lround(kEnvelopeCounts * *mn));
    hi[c] = static_cast<int>(std::lround(kEnvelopeCounts * *mx));
  }
  return {{"min", lo},
          {"max", hi},
          {"full_scale", kEnvelopeCounts},
          {"frames_per_column", static_cast<double>(n) / columns}};
}

// Power mel spectrograms of every channel in whole dB against the strike's loudest bin, floored
// at kSpectrogramFloorDb, max-pooled in time to at most kSpectrogramFrames: (mels x frames) each.
json Spectrograms(const std::vector<std::vector<float>>& channels, double sample_rate_hz) {
  const dsp::MelSpectrogram mel(512, 128, kSpectrogramMels, 0.0, 0.5 * sample_rate_hz,
                                sample_rate_hz);
  std::vector<Eigen::MatrixXf> power(channels.size());
  float peak = 0.0f;
  for (size_t c = 0; c < channels.size(); ++c) {
    mel.Compute(channels[c].data(), static_cast<int64_t>(channels[c].size()), &power[c]);
    peak = std::max(peak, power[c].maxCoeff());
  }
  const int64_t frames = power.empty() ? 0 : power[0].cols();
  const int64_t pool = std::max<int64_t>(1, (frames + kSpectrogramFrames - 1) / kSpectrogramFrames);
  json out = json::array();
  for (const Eigen::MatrixXf& p : power) {
    json rows = json::array();
    for (Eigen::Index m = 0; m < p.rows(); ++m) {
      std::vector<int> row;
      for (int64_t f = 0; f < frames; f += pool) {
        const float v = p.row(m).segment(f, std::min(pool, frames - f)).maxCoeff();
        const double db = 10.0 * std::log10(std::max(v, 1e-30f) / std::max(peak, 1e-30f));
        row.push_back(static_cast<int>(std::lround(std::max(db, kSpectrogramFloorDb))));
      }
      rows.push_back(row);
    }
    out.push_back(rows);
  }
  return {{"db", out},
          {"floor_db", kSpectrogramFloorDb},
          {"seconds_per_frame", 128.0 * pool / sample_rate_hz},
          {"f_max_hz", 0.5 * sample_rate_hz}};
}

// The figure's data: every valid strike's label, and one strike's channels as drawn: waveform
// envelopes ((C) x columns, full scale) and mel spectrograms ((C) x mels x frames, dB).
json DatasetFigureJson(const std::string& path, int64_t strike_row) {
  const DatasetReader reader(path);
  if (reader.size() == 0) {
    throw IoError(fmt::format("{}: holds no strikes; there is none to draw", path));
  }
  if (strike_row < 0 || strike_row >= reader.size()) {
    throw ConfigError(fmt::format("--strike {}: {} holds rows 0 to {}", strike_row, path,
                                  reader.size() - 1));
  }
  json z = json::array(), theta = json::array();
  for (int64_t i = 0; i < reader.size(); ++i) {
    const StrikeSample meta = reader.ReadMeta(i);
    if (!meta.valid) continue;
    z.push_back(meta.label.z_m);
    theta.push_back(meta.label.theta_rad);
  }
  const StrikeSample strike = reader.Read(strike_row);
  const double rate_hz = reader.info().sample_rate_hz;
  std::vector<std::vector<float>> channels;
  json envelopes = json::array();
  for (int c = 0; c < strike.audio.rows(); ++c) {
    channels.emplace_back(strike.audio.row(c).begin(), strike.audio.row(c).end());
    envelopes.push_back(Envelope(channels.back(), kEnvelopeColumns));
  }
  return {{"kind", "inspect"},
          {"path", path},
          {"coverage", {{"z_m", z}, {"theta_rad", theta}}},
          {"strike",
           {{"row", strike_row},
            {"index", strike.index},
            {"valid", strike.valid},
            {"z_m", strike.label.z_m},
            {"theta_rad", strike.label.theta_rad},
            {"sample_rate_hz", rate_hz},
            {"frames", strike.audio.cols()},
            {"envelopes", envelopes},
            {"spectrograms", Spectrograms(channels, rate_hz)}}}};
}

// PNG.json, then the plot script draws PNG from it; both obey --force, and a figure that could
// not be drawn takes its data with it
void DrawDatasetFigure(const GlobalOptions& g, const std::string& path, const InspectOptions& o) {
  if (fs::path(o.png).extension() != ".png") {
    throw ConfigError(fmt::format("--png {}: the figure is a .png file", o.png));
  }
  const std::string data = o.png + ".json";
  CheckOutput(g, {o.png, "--png", o.force}, {{path, "inspect's path"}, {o.plot_script, "--plot"}});
  CheckOutput(g, {data, "the figure's data beside --png", o.force},
              {{path, "inspect's path"}, {o.plot_script, "--plot"}});
  if (!fs::is_regular_file(o.plot_script)) {
    throw IoError(fmt::format("--plot {}: no such script", o.plot_script));
  }
  const json figure = DatasetFigureJson(path, o.strike_row);
  // the figure is drawn to a name of its own and renamed once complete
  const std::string partial = o.png + ".partial.png";
  WriteTextAtomic(data, figure.dump() + "\n");
  try {
    DrawFigure(o.plot_script, "inspect", data, partial, "--plot names another script");
    fs::rename(partial, o.png);
  } catch (...) {
    std::error_code ec;
    fs::remove(partial, ec);
    fs::remove(data, ec);
    throw;
  }
}

}  // namespace

CommandResult RunInspect(const GlobalOptions& g, const std::string& path,
                         const InspectOptions& o) {
  if (!fs::exists(path)) throw IoError(fmt::format("{}: no such file or directory", path));
  json j;
  if (fs::is_directory(path)) {
    // a run directory: its config, model card and metrics
    j = {{"kind", "run"}, {"path", path}};
    for (const char* name : {"model.json", "metrics.json"}) {
      const fs::path p = fs::path(path) / name;
      if (fs::exists(p))
        j[fs::path(name).stem().string()] = json::parse(ReadText(p.string()), nullptr, false);
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
    // a run still being written (or killed) lives in RUN.partial until it replaces RUN
    const bool unfinished = fs::path(path).filename().string().ends_with(".partial") ||
                            fs::path(path).extension() == ".partial";
    const bool ensemble = fs::exists(fs::path(path) / "ensemble.json");
    j["complete"] = !unfinished && (fs::exists(fs::path(path) / "model.json") ||
                                    fs::exists(fs::path(path) / "metrics.json") || ensemble);
    if (unfinished) {
      j["note"] = "an unfinished run: train --resume continues it; it replaces its run when done";
    }
    // trainable parameters per part of a finished model
    if ((fs::exists(fs::path(path) / "model.json") && fs::exists(fs::path(path) / "model.pt")) ||
        ensemble) {
      const learning::Localizer localizer(path);
      if (ensemble) j["ensemble_members"] = localizer.members();
      json parameters;
      int64_t total = 0;
      for (const auto& [part, count] : localizer.ParameterCounts()) {
        parameters[part] = count;
        total += count;
      }
      parameters["total"] = total;
      j["parameters"] = parameters;
      // the interval scales and what fitted them (the validation split, or `calibrate`'s data)
      if (localizer.has_uncertainty()) {
        const learning::UncertaintyCalibration& c = localizer.calibration();
        const json card = json::parse(
            ReadText((fs::path(path) / (ensemble ? "ensemble.json" : "model.json")).string()),
            nullptr, false);
        std::string source = "validation split";
        if (card.is_object() && card.contains("uncertainty") &&
            card["uncertainty"].is_object()) {
          source = card["uncertainty"].value("calibrated_on", source);
        }
        j["calibration"] = {{"z_std_scale", c.z_std_scale},
                            {"kappa_scale", c.kappa_scale},
                            {"calibrated_on", source}};
      }
    }
  } else if (fs::path(path).extension() == ".wav") {
    // a WAV and its label sidecar
    const AudioClip clip = ReadWav(path);
    j = {{"kind", "wav"},
         {"path", path},
         {"channels", clip.channels()},
         {"frames", clip.frames()},
         {"sample_rate_hz", clip.sample_rate_hz},
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
    j = {{"kind", "robot_log"},
         {"path", path},
         {"rows", proprio.rows()},
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
    j = {{"kind", "config"},
         {"path", path},
         {"valid", true},
         {"resolved_yaml", ConfigToYaml(config)}};
  } else {
    // HDF5: a dataset or any other file we write
    std::string schema;
    try {
      schema = ReadStringAttr(path, "schema");
    } catch (const Error&) {
      schema.clear();
    }
    j = json::parse(schema == kDatasetSchema ? SummarizeDatasetJson(path) : SummarizeH5Json(path));
    if (!o.png.empty()) {
      if (schema != kDatasetSchema) {
        throw ConfigError(fmt::format("--png draws a dataset; {} is not one", path));
      }
      DrawDatasetFigure(g, path, o);
      j["png"] = o.png;
    }
  }
  if (!o.png.empty() && !j.contains("png")) {
    throw ConfigError(fmt::format("--png draws a dataset; {} is not one", path));
  }
  return {j.dump(), j.dump(2) + "\n"};
}

void RegisterInspect(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto path = std::make_shared<std::string>();
  auto o = std::make_shared<InspectOptions>();
  auto* inspect =
      app.add_subcommand("inspect", "summarize a file or run directory SonicBoom wrote");
  inspect->add_option("path", *path, "dataset, features file, WAV, run directory or config")
      ->required();
  inspect->add_option("--png", o->png,
                      "a dataset's figure: (z, theta) coverage and one strike's channels with "
                      "spectrograms (data beside it as PNG.json)");
  inspect->add_option("--strike", o->strike_row, "row of the strike drawn by --png (default 0)");
  inspect->add_option("--plot", o->plot_script, "the plotting script (/usr/bin/python3)");
  inspect->add_flag("--force", o->force, "replace an existing --png figure and its data");
  inspect->callback(
      [&g, run, path, o] { *run = [&g, path, o] { return RunInspect(g, *path, *o); }; });
}

}  // namespace sonicboom::experiments
