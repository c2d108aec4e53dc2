// `inspect`: a summary of any file or run directory SonicBoom wrote.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

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
#include "sonicboom/hardware/capture.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The figure's data: every valid strike's label, and one strike's channels ((C x T) full scale).
json DatasetFigureJson(const std::string& path, int64_t strike_row) {
  const DatasetReader reader(path);
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
  json channels = json::array();
  for (int c = 0; c < strike.audio.rows(); ++c) {
    channels.push_back(std::vector<float>(strike.audio.row(c).begin(), strike.audio.row(c).end()));
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
            {"sample_rate_hz", reader.info().sample_rate_hz},
            {"channels", channels}}}};
}

// PNG.json, then the plot script draws PNG from it
void DrawDatasetFigure(const GlobalOptions& g, const std::string& path, const InspectOptions& o) {
  if (fs::path(o.png).extension() != ".png") {
    throw ConfigError(fmt::format("--png {}: the figure is a .png file", o.png));
  }
  if (!fs::is_regular_file(o.plot_script)) {
    throw IoError(fmt::format("--plot {}: no such script", o.plot_script));
  }
  const std::string data = o.png + ".json";
  CheckOutput(g, {o.png, "--png", true}, {{path, "inspect's path"}});
  CheckOutput(g, {data, "the figure's data beside --png", true}, {{path, "inspect's path"}});
  WriteTextAtomic(data, DatasetFigureJson(path, o.strike_row).dump() + "\n");
  DrawFigure(o.plot_script, "inspect", data, o.png,
             "needs /usr/bin/python3 with python3-matplotlib");
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
  inspect->callback(
      [&g, run, path, o] { *run = [&g, path, o] { return RunInspect(g, *path, *o); }; });
}

}  // namespace sonicboom::experiments
