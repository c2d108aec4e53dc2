// `inspect`: a summary of any file or run directory SonicBoom wrote.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <sstream>

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

CommandResult RunInspect(const GlobalOptions& g, const std::string& path) {
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
  }
  return {j.dump(), j.dump(2) + "\n"};
}

void RegisterInspect(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto path = std::make_shared<std::string>();
  auto* inspect =
      app.add_subcommand("inspect", "summarize a file or run directory SonicBoom wrote");
  inspect->add_option("path", *path, "dataset, features file, WAV, run directory or config")
      ->required();
  inspect->callback([&g, run, path] { *run = [&g, path] { return RunInspect(g, *path); }; });
}

}  // namespace sonicboom::experiments
