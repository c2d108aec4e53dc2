// Unlabelled adaptation: a trained run's input and BatchNorm statistics re-estimated on strikes
// of another structure (learning.h, AdaptToUnlabelled).

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <torch/torch.h>

#include "internal/data.h"
#include "internal/loaded_run.h"
#include "internal/network.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The BatchNorm layers of a network, whatever their dimension.
std::vector<torch::nn::Module*> BatchNormLayersOf(internal::NetworkImpl& network) {
  std::vector<torch::nn::Module*> layers;
  for (const auto& module : network.modules(/*include_self=*/false)) {
    if (module->as<torch::nn::BatchNorm1d>() || module->as<torch::nn::BatchNorm2d>()) {
      layers.push_back(module.get());
    }
  }
  return layers;
}

// Running statistics reset, then accumulated as a plain average over every target batch.
template <typename Norm>
bool StartAveraging(torch::nn::Module* layer) {
  auto* norm = layer->as<Norm>();
  if (norm == nullptr) return false;
  norm->reset_running_stats();
  norm->options.momentum(c10::nullopt);
  norm->train();
  return true;
}

void RefitBatchNorm(internal::NetworkImpl& network, const FeatureSet& target, int64_t crop) {
  network.eval();
  for (torch::nn::Module* layer : BatchNormLayersOf(network)) {
    StartAveraging<torch::nn::BatchNorm1dImpl>(layer) ||
        StartAveraging<torch::nn::BatchNorm2dImpl>(layer);
  }
  torch::NoGradGuard no_grad;
  const std::vector<float> fill = network.MelMean();
  for (int64_t first = 0; first < target.size(); first += internal::kPredictBatch) {
    std::vector<int64_t> records;
    for (int64_t r = first; r < std::min(target.size(), first + internal::kPredictBatch); ++r) {
      records.push_back(r);
    }
    network.forward(
        internal::AssembleBatch(target, records, network.modalities(), crop, nullptr, fill));
  }
  network.eval();
}

// One network: statistics refitted, weights and model.json (with "adapted") written.
int64_t AdaptOne(const std::string& run_dir, const FeatureSet& target, const std::string& out_dir,
                 const AdaptOptions& options) {
  internal::LoadedRun run = internal::LoadRun(run_dir);
  internal::NetworkImpl& network = *run.network;
  internal::CheckFeaturesFor(run, target, "features to adapt to");
  std::vector<int64_t> all(target.size());
  for (int64_t r = 0; r < target.size(); ++r) all[r] = r;
  if (options.mel_statistics && network.modalities().audio) {
    const internal::MelStats stats = internal::ComputeMelStats(target, all);
    network.SetNormalization(stats.mean, stats.std);
  }
  const int64_t layers = static_cast<int64_t>(BatchNormLayersOf(network).size());
  if (options.batch_norm) RefitBatchNorm(network, target, run.file.model_config.crop_frames);
  fs::create_directories(out_dir);
  internal::SaveModuleAtomically(network, (fs::path(out_dir) / "model.pt").string());
  json j = internal::ReadJsonFile((fs::path(run_dir) / "model.json").string());
  j["adapted"] = json{{"from", fs::absolute(run_dir).lexically_normal().string()},
                      {"records", target.size()},
                      {"batch_norm", options.batch_norm},
                      {"mel_statistics", options.mel_statistics},
                      {"labels", "not read"}};
  WriteTextAtomic((fs::path(out_dir) / "model.json").string(), j.dump(2) + "\n");
  return layers;
}

}  // namespace

AdaptReport AdaptToUnlabelled(const std::string& run_dir, const FeatureSet& target,
                              const std::string& out_dir, const AdaptOptions& options) {
  if (target.size() < kMinFitRecords) {
    throw ConfigError(fmt::format(
        "adapt: the target holds {} strike(s); re-estimating the input and BatchNorm statistics "
        "needs at least {}",
        target.size(), kMinFitRecords));
  }
  if (fs::exists(out_dir) && !fs::is_empty(out_dir)) {
    throw ConfigError(fmt::format("{}: exists and is not empty; adapt writes a new run", out_dir));
  }
  AdaptReport report;
  report.records = target.size();
  const std::vector<std::string> members = EnsembleMembers(run_dir);
  if (members.empty()) {
    report.members = 1;
    report.batch_norm_layers = AdaptOne(run_dir, target, out_dir, options);
    return report;
  }
  // members first, the ensemble file that names them last
  for (const std::string& member : members) {
    const std::string name = fs::path(member).filename().string();
    report.batch_norm_layers =
        AdaptOne(member, target, (fs::path(out_dir) / name).string(), options);
    ++report.members;
  }
  const std::string ensemble = (fs::path(run_dir) / "ensemble.json").string();
  json j = internal::ReadJsonFile(ensemble);
  j["adapted"] = json{{"from", fs::absolute(run_dir).lexically_normal().string()},
                      {"records", target.size()}};
  WriteTextAtomic((fs::path(out_dir) / "ensemble.json").string(), j.dump(2) + "\n");
  return report;
}

}  // namespace sonicboom::learning
