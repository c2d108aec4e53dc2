// Ensembles: several networks trained alike from their own initializations, one directory that
// the Localizer loads as one model (ensemble.json naming the member run directories).

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "internal/data.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;

namespace {

// ensemble.json: the member directories and the mixture's calibration (how it came about)
void WriteEnsembleFile(const std::string& run_dir, const nlohmann::json& names,
                       const CalibrationFit& calibration) {
  nlohmann::json u = {{"z_std_scale", calibration.scales.z_std_scale},
                      {"kappa_scale", calibration.scales.kappa_scale}};
  if (!calibration.method.empty()) {
    u["method"] = calibration.method;
    u["records"] = calibration.records;
  }
  const nlohmann::json j = {{"members", names}, {"uncertainty", u}};
  WriteTextAtomic((fs::path(run_dir) / "ensemble.json").string(), j.dump(2) + "\n");
}

// Each member once: one named twice, or a link to another, would count twice in the mixture
// (its spread and its calibration).
void RefuseRepeatedMember(const std::string& path, const std::vector<std::string>& members) {
  const std::string& last = members.back();
  for (size_t k = 0; k + 1 < members.size(); ++k) {
    std::error_code ec;
    if (members[k] != last && !fs::equivalent(members[k], last, ec)) continue;
    const std::string name = fs::path(last).filename().string();
    const std::string first = fs::path(members[k]).filename().string();
    throw SchemaError(fmt::format(
        "{}: member \"{}\" {} (entries {} and {}); each network counts once in the mixture",
        path, name,
        name == first ? "is named twice" : fmt::format("is the directory of member \"{}\"", first),
        k + 1, members.size()));
  }
}

}  // namespace

UncertaintyCalibration EnsembleCalibration(const std::string& run_dir) {
  const fs::path path = fs::path(run_dir) / "ensemble.json";
  if (!fs::exists(path)) return {};
  const nlohmann::json j = internal::ReadJsonFile(path.string());
  if (!j.is_object() || !j.contains("uncertainty")) return {};
  return internal::CalibrationFromJson(j["uncertainty"], path.string());
}

std::vector<std::string> EnsembleMembers(const std::string& run_dir) {
  const fs::path path = fs::path(run_dir) / "ensemble.json";
  if (!fs::exists(path)) return {};
  const nlohmann::json j = internal::ReadJsonFile(path.string());
  if (!j.is_object() || !j.contains("members") || !j["members"].is_array() ||
      j["members"].empty()) {
    throw SchemaError(fmt::format("{}: expected {{\"members\": [member directories]}}",
                                  path.string()));
  }
  std::vector<std::string> members;
  for (const nlohmann::json& m : j["members"]) {
    // names inside the ensemble directory only
    if (!m.is_string() || m.get<std::string>().empty() ||
        fs::path(m.get<std::string>()).has_parent_path() || m.get<std::string>() == "..") {
      throw SchemaError(fmt::format("{}: member {} is not a directory name inside {}",
                                    path.string(), m.dump(), run_dir));
    }
    members.push_back((fs::path(run_dir) / m.get<std::string>()).string());
    RefuseRepeatedMember(path.string(), members);
  }
  return members;
}

Metrics TrainEnsemble(const FeatureSet& train, const FeatureSet& val,
                      const ModelConfig& model_config, const TrainConfig& train_config,
                      double surface_radius_m, uint64_t seed, const std::string& run_dir,
                      bool resume, bool show_progress, const FineTune& fine_tune,
                      const DataParallel& parallel) {
  const int64_t count = train_config.ensemble_members;
  // a fine-tune keeps the pretrained run's member count: member k starts from member k
  const std::vector<std::string> pretrained =
      fine_tune.init_from.empty() ? std::vector<std::string>{} : EnsembleMembers(fine_tune.init_from);
  const int64_t pretrained_count = std::max<int64_t>(1, static_cast<int64_t>(pretrained.size()));
  if (!fine_tune.init_from.empty() && pretrained_count != count) {
    throw ConfigError(fmt::format(
        "config key 'train.ensemble_members' = {}: the pretrained run {} has {} member(s), and "
        "a fine-tune keeps that count",
        count, fine_tune.init_from, pretrained_count));
  }
  if (count == 1) {
    return Train(train, val, model_config, train_config, surface_radius_m, seed, run_dir, resume,
                 show_progress, fine_tune, parallel);
  }
  nlohmann::json names = nlohmann::json::array();
  for (int64_t k = 0; k < count; ++k) {
    const std::string name = fmt::format("member{}", k);
    names.push_back(name);
    const std::string dir = (fs::path(run_dir) / name).string();
    if (parallel.rank == 0) fs::create_directories(dir);
    FineTune member_tune = fine_tune;
    if (!pretrained.empty()) member_tune.init_from = pretrained[k];
    const uint64_t member_seed = k == 0 ? seed : SampleSeed(seed, static_cast<uint64_t>(k));
    spdlog::info("ensemble member {} of {} ({})", k + 1, count, dir);
    Train(train, val, model_config, train_config, surface_radius_m, member_seed, dir, resume,
          show_progress, member_tune, parallel);
  }
  if (parallel.rank != 0) return {};
  // the mixture of calibrated members is wider than any member where they disagree: its own two
  // scales are fitted on the validation split, as a single network's are
  WriteEnsembleFile(run_dir, names, CalibrationFit{});
  std::vector<Prediction> predictions = Localizer(run_dir).Predict(val);
  CalibrationFit calibration;
  if (predictions.front().has_uncertainty()) {
    // too few validation strikes: a fine-tune keeps the pretrained mixture's scales
    const bool tuned = !fine_tune.init_from.empty();
    const UncertaintyCalibration kept =
        tuned ? EnsembleCalibration(fine_tune.init_from) : UncertaintyCalibration{};
    const std::string kept_what =
        tuned ? fmt::format("the pretrained scales of {}/ensemble.json", fine_tune.init_from)
              : "scales 1";
    calibration = fine_tune.calibration == FineTune::Calibration::kKeepPretrained
                      ? KeptCalibrationFit(kept, kept_what)
                      : FitOrKeepCalibration(predictions, val, kept, kept_what);
  }
  WriteEnsembleFile(run_dir, names, calibration);
  for (Prediction& p : predictions) p = ApplyCalibration(p, calibration.scales);
  return ComputeMetrics(predictions, val, surface_radius_m);
}

}  // namespace sonicboom::learning
