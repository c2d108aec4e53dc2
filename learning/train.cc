// Training: deterministic batches and augmentation, Adam with a step schedule, per-epoch
// validation, metrics.jsonl, resumable checkpoints and the final model files.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <numeric>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <torch/optim.h>
#include <torch/serialize.h>
#include <torch/special.h>

#include "internal/data.h"
#include "internal/data_parallel.h"
#include "internal/json_archive.h"
#include "internal/network.h"
#include "internal/train_step.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Files of a run directory.
struct RunFiles {
  std::string model_pt, model_json, checkpoint_pt, checkpoint_json, metrics;
  explicit RunFiles(const fs::path& dir)
      : model_pt((dir / "model.pt").string()),
        model_json((dir / "model.json").string()),
        checkpoint_pt((dir / "checkpoint.pt").string()),
        checkpoint_json((dir / "checkpoint.json").string()),
        metrics((dir / "metrics.jsonl").string()),
        best_pt((dir / "best.pt").string()),
        best_json((dir / "best.json").string()) {}
  std::string best_pt, best_json;  // train.keep_best: the best epoch so far and its loss
};

// Fisher-Yates shuffle of `order` driven by the epoch's own generator.
void Shuffle(std::vector<int64_t>* order, uint64_t seed, int64_t epoch) {
  Rng rng(SampleSeed(SplitMix64(seed ^ 0x53485546464C45ULL), static_cast<uint64_t>(epoch)),
          Stream::kTrain);
  for (size_t i = order->size(); i > 1; --i) {
    const size_t j = static_cast<size_t>(rng.UniformInt(i));
    std::swap((*order)[i - 1], (*order)[j]);
  }
}

// Splits `order` into batches; a trailing batch smaller than min_size joins the previous batch
// (BatchNorm cannot train on a single record).
std::vector<std::vector<int64_t>> MakeBatches(const std::vector<int64_t>& order, int64_t size,
                                              int64_t min_size = 2) {
  std::vector<std::vector<int64_t>> batches;
  for (size_t first = 0; first < order.size(); first += size) {
    const size_t last = std::min(order.size(), first + static_cast<size_t>(size));
    batches.emplace_back(order.begin() + first, order.begin() + last);
  }
  // (data parallel: every process's part of a batch holds at least two records)
  if (batches.size() > 1 && static_cast<int64_t>(batches.back().size()) < min_size) {
    std::vector<int64_t>& previous = batches[batches.size() - 2];
    previous.insert(previous.end(), batches.back().begin(), batches.back().end());
    batches.pop_back();
  }
  return batches;
}

// Process `rank`'s contiguous part of a batch split among `world` processes.
std::vector<int64_t> PartOf(const std::vector<int64_t>& batch, int rank, int world) {
  const size_t n = batch.size();
  return {batch.begin() + static_cast<std::ptrdiff_t>(n * rank / world),
          batch.begin() + static_cast<std::ptrdiff_t>(n * (rank + 1) / world)};
}

// The same loss in double precision from predictions (for validation).
double PredictionLoss(const std::vector<Prediction>& predictions, const FeatureSet& truth,
                      const TrainConfig& c) {
  double sum = 0.0;
  int64_t n = 0;
  for (size_t i = 0; i < predictions.size(); ++i) {
    if (!std::isfinite(truth.z_m[i]) || !std::isfinite(truth.theta_rad[i])) continue;
    const double dz = 100.0 * (predictions[i].z_m - truth.z_m[i]);
    const double dc = std::cos(predictions[i].theta_rad) - std::cos(truth.theta_rad[i]);
    const double ds = std::sin(predictions[i].theta_rad) - std::sin(truth.theta_rad[i]);
    sum += c.loss_weight_z * dz * dz + c.loss_weight_cos * dc * dc + c.loss_weight_sin * ds * ds;
    ++n;
  }
  return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

void SetLearningRate(torch::optim::Adam* optimizer, double lr) {
  for (auto& group : optimizer->param_groups()) {
    static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
  }
}

// Saves the optimizer state, the completed epoch count and, with `network`, the weights in one
// archive. A finished run's checkpoint holds no weights: they are its model.pt's.
void SaveCheckpoint(internal::NetworkImpl* network, torch::optim::Adam& optimizer,
                    int64_t epochs_done, const std::string& path) {
  torch::serialize::OutputArchive root, model, optim;
  if (network) {
    network->save(model);
    root.write("model", model);
  }
  optimizer.save(optim);
  root.write("optimizer", optim);
  root.write("epochs_done", torch::tensor(epochs_done, torch::kInt64));
  internal::WriteArchiveAtomically(root, path);
}

// Weights saved by SaveModuleAtomically (model.pt, best.pt) into `network`, shapes checked.
void LoadWeights(internal::NetworkImpl* network, const std::string& path) {
  RequireReadableFile(path);
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {
    throw SchemaError(fmt::format("{}: unreadable: {}", path, e.what_without_backtrace()));
  }
  internal::LoadModuleChecked(*network, archive, path);
}

// Loads a checkpoint, the weights from `model_pt` when it holds none (a finished run's); returns
// the number of completed epochs.
int64_t LoadCheckpoint(internal::NetworkImpl* network, torch::optim::Adam* optimizer,
                       const std::string& path, const std::string& model_pt) {
  RequireReadableFile(path);
  bool weights_inside = false;
  try {
    torch::serialize::InputArchive root, model, optim;
    root.load_from(path);
    weights_inside = root.try_read("model", model);
    root.read("optimizer", optim);
    torch::Tensor epochs_done;
    root.read("epochs_done", epochs_done);
    if (weights_inside) internal::LoadModuleChecked(*network, model, path);
    if (!weights_inside && !fs::exists(model_pt)) {
      throw SchemaError(fmt::format(
          "{}: a finished run's checkpoint (the weights are its model.pt), but {} is missing",
          path, model_pt));
    }
    if (!weights_inside) LoadWeights(network, model_pt);
    optimizer->load(optim);
    return epochs_done.item<int64_t>();
  } catch (const c10::Error& e) {
    throw SchemaError(fmt::format("{}: unreadable or written for another model: {}", path,
                                  e.what_without_backtrace()));
  }
}

// Identity of a run, stored in checkpoint.json and compared on resume. The uncertainty head is
// named only when present, so runs without it keep the identity they had before it existed.
json RunIdentity(const ModelConfig& model_config, const FeatureSet& shapes, uint64_t seed,
                 bool uncertainty_head, const FineTune& fine_tune) {
  json identity{{"model", internal::ConfigToJson(model_config)},
                {"shapes", internal::ShapesToJson(shapes)},
                {"seed", seed}};
  if (uncertainty_head) identity["uncertainty_head"] = true;
  if (!fine_tune.init_from.empty()) {
    identity["init_from"] = fs::absolute(fine_tune.init_from).lexically_normal().string();
    identity["freeze"] = static_cast<int>(fine_tune.freeze);
    identity["refit_normalization"] = fine_tune.refit_normalization;
  }
  return identity;
}

// Whether a top-level part of the network (its child module name) stays as pretrained.
bool IsFrozen(const std::string& part, FineTune::Freeze freeze) {
  switch (freeze) {
    case FineTune::Freeze::kNone:
      return false;
    case FineTune::Freeze::kEncoders:
      return internal::IsEncoder(part);
    case FineTune::Freeze::kAllButHead:
      return part != "head" && part != "uncertainty_head";
  }
  return false;
}

// Loads the pretrained weights of `fine_tune.init_from` into `network` and fixes the frozen
// parts; returns the parameters left to train.
std::vector<torch::Tensor> StartFromPretrained(internal::NetworkImpl* network,
                                               const FineTune& fine_tune) {
  const std::string weights = (fs::path(fine_tune.init_from) / "model.pt").string();
  if (!fs::exists(weights)) {
    throw IoError(fmt::format("{}: missing; --init-from needs a trained run directory", weights));
  }
  LoadWeights(network, weights);
  // parameters of frozen parts stop learning; parameters directly on the network (CLS token,
  // modality embeddings) train unless only the heads do
  std::vector<torch::Tensor> trainable;
  for (const auto& item : network->named_parameters()) {
    const std::string& name = item.key();
    const std::string part = name.substr(0, name.find('.'));
    const bool frozen = name.find('.') == std::string::npos
                            ? fine_tune.freeze == FineTune::Freeze::kAllButHead
                            : IsFrozen(part, fine_tune.freeze);
    item.value().set_requires_grad(!frozen);
    if (!frozen) trainable.push_back(item.value());
  }
  return trainable;
}

// Puts the frozen parts in eval mode (fixed BatchNorm statistics, no dropout) after train().
void HoldFrozenParts(internal::NetworkImpl* network, FineTune::Freeze freeze) {
  for (const auto& child : network->named_children()) {
    if (IsFrozen(child.key(), freeze)) child.value()->eval();
  }
}

// Keeps the metrics lines of epochs 1..epochs_done (a crash may have left later ones).
void TrimMetrics(const std::string& path, int64_t epochs_done) {
  std::ifstream in(path);
  if (!in) return;
  std::string line, kept;
  while (std::getline(in, line)) {
    const json j = json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (j.is_object() && j.contains("epoch") && j["epoch"].is_number_integer() &&
        j["epoch"].get<int64_t>() <= epochs_done) {
      kept += line + "\n";
    }
  }
  in.close();
  WriteTextAtomic(path, kept);
}

void AppendLine(const std::string& path, const std::string& line) {
  std::ofstream out(path, std::ios::app);
  out << line << "\n";
  out.flush();
  if (!out) throw IoError(fmt::format("{}: cannot append", path));
}

// Checks the configs and features before anything is written; returns the training records
// (those with both labels).
std::vector<int64_t> CheckedTrainingRecords(const FeatureSet& train, const FeatureSet& val,
                                            const ModelConfig& model_config,
                                            const TrainConfig& train_config,
                                            double surface_radius_m, int world) {
  model_config.Validate();
  train_config.Validate();
  if (!std::isfinite(surface_radius_m) || surface_radius_m <= 0.0) {
    throw ConfigError(fmt::format("surface_radius_m = {}: must be positive", surface_radius_m));
  }
  const internal::ModalitySet use = internal::SelectedModalities(model_config);
  internal::CheckFeatureSet(train, use, "training features");
  internal::CheckFeatureSet(val, use, "validation features");
  internal::CheckSameShapes(train, val, use, "validation features");
  if (use.audio && model_config.crop_frames > train.frames) {
    throw ConfigError(fmt::format(
        "config key 'model.crop_frames' = {}: exceeds the {} mel frames of the features",
        model_config.crop_frames, train.frames));
  }
  // a frequency mask as wide as all rows would blank the whole input (a waveform has one row)
  if (use.audio && train_config.augment && train_config.freq_mask_bands >= train.mels) {
    throw ConfigError(fmt::format(
        "config key 'train.freq_mask_bands' = {}: must be below the {} row(s) of the audio "
        "features (0 for features.audio_representation = waveform)",
        train_config.freq_mask_bands, train.mels));
  }
  // a sign belongs to a waveform (one sample per frame), not to a log-mel image
  if (use.audio && train_config.augment && train_config.polarity_flip &&
      train.frame_hop_samples != 1) {
    throw ConfigError(
        "config key 'train.polarity_flip' = true: needs features.audio_representation = "
        "waveform (a log-mel image has no sign)");
  }
  // a stretch in time belongs to a waveform: a mel frame's spectrum would need its own stretch
  if (use.audio && train_config.augment && train_config.time_stretch > 0.0 &&
      train.frame_hop_samples != 1) {
    throw ConfigError(fmt::format(
        "config key 'train.time_stretch' = {}: needs features.audio_representation = waveform "
        "(a mel frame's frequencies would have to stretch too)",
        train_config.time_stretch));
  }
  // a turned record must be audio alone, in rings of three
  for (const auto& [key, on] : {std::pair{"train.rotate_rings", train_config.rotate_rings},
                                std::pair{"train.mirror_rings", train_config.mirror_rings}}) {
    if (train_config.augment && on && !internal::TurnsByRings(use, train.channels)) {
      throw ConfigError(fmt::format(
          "config key '{}' = true: needs model.modalities = [audio] (a GCC pair or an arm pose "
          "would have to turn too) and channels in rings of {} (got {})",
          key, internal::kRingDiscs, train.channels));
    }
  }
  // picks are times of samples, which a mel frame does not keep
  if (use.arrivals && train.frame_hop_samples != 1) {
    throw ConfigError(fmt::format(
        "config key 'model.arrival_picks' = {}: needs features.audio_representation = waveform "
        "(the picks are read off the window's samples)",
        NameOf(model_config.arrival_picks)));
  }
  // data parallel: every process's part of a batch needs two records
  if (world > 1 && train_config.batch_size < 2 * world) {
    throw ConfigError(fmt::format(
        "config key 'train.batch_size' = {}: with {} data-parallel processes each part of a "
        "batch needs two records (BatchNorm); use at least {}",
        train_config.batch_size, world, 2 * world));
  }
  std::vector<int64_t> records;
  for (int64_t i = 0; i < train.size(); ++i) {
    if (std::isfinite(train.z_m[i]) && std::isfinite(train.theta_rad[i])) records.push_back(i);
  }
  if (records.empty()) throw SchemaError("training features: no record has a finite label");
  return records;
}

// train.keep_best: the epoch (1-based; 0 = none yet) with the lowest validation loss so far.
struct BestEpoch {
  double loss{std::numeric_limits<double>::infinity()};
  int64_t epoch{0};
};

// Resume: weights, optimizer state and epoch count from the checkpoint of the same run, and
// the best epoch so far; without one (or without resume) the stale files of an earlier run
// are removed (by rank 0, `writes`). Returns the completed epoch count.
int64_t ResumeOrClear(const RunFiles& files, const json& identity, bool resume, bool writes,
                      const TrainConfig& train_config, internal::NetworkImpl* network,
                      torch::optim::Adam* optimizer, BestEpoch* best) {
  if (!resume || !fs::exists(files.checkpoint_pt)) {
    std::error_code ec;
    if (writes) {
      for (const std::string& stale : {files.checkpoint_pt, files.checkpoint_json, files.metrics,
                                       files.best_pt, files.best_json}) {
        fs::remove(stale, ec);
      }
    }
    return 0;
  }
  const json saved = internal::ReadJsonFile(files.checkpoint_json);
  if (!saved.contains("run") || saved["run"] != identity) {
    throw SchemaError(fmt::format(
        "{}: the checkpoint was written for a different model config, feature shapes or "
        "seed; train without resume or use another run directory",
        files.checkpoint_json));
  }
  const int64_t epochs_done =
      LoadCheckpoint(network, optimizer, files.checkpoint_pt, files.model_pt);
  if (writes) TrimMetrics(files.metrics, epochs_done);
  if (train_config.keep_best && epochs_done > 0 && fs::exists(files.best_json)) {
    const json saved_best = internal::ReadJsonFile(files.best_json);
    best->loss = saved_best.at("val_loss").get<double>();
    best->epoch = saved_best.at("epoch").get<int64_t>();
  }
  return epochs_done;
}

// One epoch's mean training losses (point loss, uncertainty NLL) over `records`.
struct EpochLoss {
  double point{0.0}, nll{0.0};
};

// One epoch of optimizer steps over the shuffled records, this process's part of each batch
// (with `group`, the gradients are summed over the processes before each step).
EpochLoss TrainEpoch(internal::NetworkImpl& network, torch::optim::Adam& optimizer,
                     const FeatureSet& train, const std::vector<int64_t>& records,
                     const ModelConfig& model_config, const TrainConfig& train_config,
                     uint64_t seed, int64_t epoch, const FineTune& fine_tune,
                     const std::vector<torch::Tensor>& trainable, internal::ProcessGroup* group,
                     const DataParallel& parallel) {
  const internal::ModalitySet use = internal::SelectedModalities(model_config);
  const int world = parallel.world_size;
  // dropout draws from a stream of this epoch, so a resume continues exactly
  torch::manual_seed(SampleSeed(SplitMix64(seed ^ 0x44524F504F5554ULL), uint64_t(epoch)));
  std::vector<int64_t> order = records;
  Shuffle(&order, seed, epoch);

  // after each process's backward pass: the whole batch's gradient and loss on every process
  double part_weight = 1.0;  // this process's share of the current batch
  std::function<void(internal::StepLoss*)> sum_over_processes = [&](internal::StepLoss* loss) {
    std::vector<double> scalars{loss->point * part_weight, loss->nll * part_weight};
    group->SumGradients(trainable, part_weight, &scalars);
    *loss = {scalars[0], scalars[1]};
  };

  network.train();
  HoldFrozenParts(&network, fine_tune.freeze);
  const std::vector<float> fill = network.MelMean();
  EpochLoss sum;
  for (const std::vector<int64_t>& batch_records :
       MakeBatches(order, train_config.batch_size, 2 * world)) {
    const std::vector<int64_t> part =
        world > 1 ? PartOf(batch_records, parallel.rank, world) : batch_records;
    part_weight = static_cast<double>(part.size()) / static_cast<double>(batch_records.size());
    const internal::StepLoss step =
        internal::TrainStep(network, optimizer, train, part, use, model_config, train_config, seed,
                            epoch, fill, group ? &sum_over_processes : nullptr);
    const double weight = static_cast<double>(batch_records.size());
    sum.point += step.point * weight;
    sum.nll += step.nll * weight;
  }
  // one set of BatchNorm running statistics: the mean of every process's
  if (group) group->AverageBuffers(network.buffers());
  const double n = static_cast<double>(records.size());
  return {sum.point / n, sum.nll / n};
}

// The end of an epoch on rank 0: its metrics.jsonl line, best.pt when it is the best so far,
// then the checkpoint: checkpoint.json (run identity) before checkpoint.pt, whose own epoch
// count is the one a resume trusts.
void RecordEpoch(const RunFiles& files, internal::NetworkImpl& network,
                 torch::optim::Adam& optimizer, const json& identity,
                 const TrainConfig& train_config, int64_t epoch, double lr, const EpochLoss& loss,
                 bool uncertainty_head, double val_loss, const Metrics& val_metrics, double seconds,
                 BestEpoch* best) {
  auto number = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json line{{"epoch", epoch + 1},
            {"lr", lr},
            {"train_loss", loss.point},
            {"val_loss", number(val_loss)},
            {"val", internal::MetricsToJson(val_metrics)},
            {"epoch_seconds", seconds}};
  if (uncertainty_head) line["train_nll"] = loss.nll;
  AppendLine(files.metrics, line.dump());
  if (train_config.keep_best && std::isfinite(val_loss) && val_loss < best->loss) {
    best->loss = val_loss;
    best->epoch = epoch + 1;
    internal::SaveModuleAtomically(network, files.best_pt);
    WriteTextAtomic(
        files.best_json, json{{"epoch", best->epoch}, {"val_loss", best->loss}}.dump() + "\n");
  }
  WriteTextAtomic(files.checkpoint_json,
                                json{{"epoch", epoch + 1}, {"run", identity}}.dump(2) + "\n");
  SaveCheckpoint(&network, optimizer, epoch + 1, files.checkpoint_pt);
}

// The scales a run keeps when its validation split is too small to fit them (with the words
// model.json says them in): a fine-tune's pretrained ones, 1 and 1 from scratch.
std::pair<UncertaintyCalibration, std::string> KeptCalibration(const FineTune& fine_tune) {
  if (fine_tune.init_from.empty()) return {UncertaintyCalibration{}, "scales 1"};
  const std::string path = (fs::path(fine_tune.init_from) / "model.json").string();
  const internal::ModelFile pretrained =
      internal::ModelFileFromJson(internal::ReadJsonFile(path), path);
  return {pretrained.calibration, fmt::format("the pretrained scales of {}", path)};
}

// A finished run keeps what `train --resume` and a fine-tune need and no more: checkpoint.pt
// keeps the optimizer state and epoch count (a resume continues exactly), not the weights, which
// are model.pt's; with a best epoch kept, model.pt is best.pt (removed) and the checkpoint keeps
// the last epoch's weights, which a resume continues from.
void KeepWhatResumeNeeds(const RunFiles& files, torch::optim::Adam& optimizer, int64_t epochs,
                         bool model_is_best) {
  std::error_code ec;
  if (model_is_best) {
    fs::remove(files.best_pt, ec);
  } else {
    SaveCheckpoint(nullptr, optimizer, epochs, files.checkpoint_pt);
  }
}

// The model files of a finished run: post-hoc calibration of the predictive distribution on the
// validation split (one scale for sigma_z, one for kappa, each minimizing the mean validation
// NLL; `kept` when it is too small, FitOrKeepCalibration), model.pt and model.json. Returns the
// validation metrics of the final model.
Metrics FinishRun(const RunFiles& files, internal::NetworkImpl& network, const FeatureSet& train,
                  const FeatureSet& val, const ModelConfig& model_config,
                  const TrainConfig& train_config, double surface_radius_m, uint64_t seed,
                  bool uncertainty_head, int64_t epochs, bool show_progress,
                  const std::pair<UncertaintyCalibration, std::string>& kept,
                  FineTune::Calibration calibration) {
  internal::ModelFile model_file;
  model_file.model_config = model_config;
  model_file.shapes = train.ShapesOnly();
  model_file.surface_radius_m = surface_radius_m;
  model_file.seed = seed;
  std::vector<Prediction> predictions =
      internal::PredictAll(network, val, model_config.crop_frames);
  bool fitted = false;
  if (uncertainty_head) {
    model_file.has_calibration = true;
    model_file.uncalibrated_val_metrics = ComputeMetrics(predictions, val, surface_radius_m);
    const CalibrationFit fit =
        calibration == FineTune::Calibration::kKeepPretrained
            ? KeptCalibrationFit(kept.first, kept.second)
            : FitOrKeepCalibration(predictions, val, kept.first, kept.second);
    model_file.calibration = fit.scales;
    model_file.calibration_method = fit.method;
    fitted = fit.fitted;
    for (Prediction& p : predictions) p = ApplyCalibration(p, model_file.calibration);
  }
  const Metrics val_metrics = ComputeMetrics(predictions, val, surface_radius_m);
  if (show_progress && fitted) {
    const Metrics& raw = model_file.uncalibrated_val_metrics;
    spdlog::info(
        "calibrated on {} validation strikes: sigma_z x {:.3g}, kappa x {:.3g}; 90 % coverage "
        "z {:.2f} -> {:.2f}, theta {:.2f} -> {:.2f}; NLL {:.3f} -> {:.3f}",
        val_metrics.n, model_file.calibration.z_std_scale, model_file.calibration.kappa_scale,
        raw.z_coverage_90, val_metrics.z_coverage_90, raw.theta_coverage_90,
        val_metrics.theta_coverage_90, raw.nll, val_metrics.nll);
  }
  internal::SaveModuleAtomically(network, files.model_pt);
  const json model_json = internal::ModelFileToJson(model_file, train_config, val_metrics, epochs);
  WriteTextAtomic(files.model_json, model_json.dump(2) + "\n");
  return val_metrics;
}

}  // namespace

Metrics Train(const FeatureSet& train, const FeatureSet& val, const ModelConfig& model_config,
              const TrainConfig& train_config, double surface_radius_m, uint64_t seed,
              const std::string& run_dir, bool resume, bool show_progress,
              const FineTune& fine_tune, const DataParallel& parallel) {
  const std::vector<int64_t> records = CheckedTrainingRecords(
      train, val, model_config, train_config, surface_radius_m, parallel.world_size);
  const internal::ModalitySet use = internal::SelectedModalities(model_config);

  // data parallel: every process takes its part of each batch; rank 0 writes the run
  const bool writes = parallel.rank == 0;
  std::unique_ptr<internal::ProcessGroup> group;
  if (parallel.world_size > 1) group = std::make_unique<internal::ProcessGroup>(parallel);

  internal::PrepareTrainingProcess(train_config);
  std::error_code ec;
  if (writes) fs::create_directories(run_dir, ec);
  if (writes && (ec || !fs::is_directory(run_dir))) {
    throw IoError(fmt::format("{}: cannot create run directory: {}", run_dir, ec.message()));
  }
  const RunFiles files{fs::path(run_dir)};

  // Network (initialized from the seed) and per-mic normalization from the training split.
  torch::manual_seed(seed);
  const bool uncertainty_head = train_config.uncertainty_weight > 0.0;
  internal::Network network(model_config, internal::ShapesOf(train, model_config),
                            uncertainty_head);
  std::vector<torch::Tensor> trainable = network->parameters();
  if (!fine_tune.init_from.empty()) trainable = StartFromPretrained(network.get(), fine_tune);
  const bool fit_normalization = fine_tune.init_from.empty() || fine_tune.refit_normalization;
  if (use.audio && train_config.normalize && fit_normalization) {
    const internal::MelStats stats = internal::ComputeMelStats(train, records);
    network->SetNormalization(stats.mean, stats.std);
  }
  if (trainable.empty()) throw ConfigError("fine-tuning: every weight is frozen; nothing to train");
  torch::optim::Adam optimizer(trainable, torch::optim::AdamOptions(train_config.learning_rate));

  const json identity = RunIdentity(model_config, train, seed, uncertainty_head, fine_tune);
  BestEpoch best;
  const int64_t epochs_done = ResumeOrClear(files, identity, resume, writes, train_config,
                                            network.get(), &optimizer, &best);
  if (resume && epochs_done > 0 && show_progress) {
    spdlog::info("resuming {} after epoch {}", run_dir, epochs_done);
  }
  // every process starts from rank 0's weights and statistics
  if (group) {
    group->Broadcast(network->parameters());
    group->Broadcast(network->buffers());
  }

  double seconds_sum = 0.0;
  for (int64_t epoch = epochs_done; epoch < train_config.epochs; ++epoch) {
    const auto start = std::chrono::steady_clock::now();
    // step schedule
    const double lr = train_config.learning_rate *
                      std::pow(train_config.lr_gamma, double(epoch / train_config.lr_step_epochs));
    SetLearningRate(&optimizer, lr);
    const EpochLoss loss =
        TrainEpoch(*network, optimizer, train, records, model_config, train_config, seed, epoch,
                   fine_tune, trainable, group.get(), parallel);
    if (!std::isfinite(loss.point) || !std::isfinite(loss.nll)) {
      throw NumericalError(fmt::format(
          "training loss became {} (uncertainty NLL {}) in epoch {} (train.learning_rate = {}); "
          "lower the rate",
          loss.point, loss.nll, epoch + 1, lr));
    }

    // Validation (without augmentation, in eval mode), metrics and checkpoints: rank 0's
    if (!writes) continue;
    const std::vector<Prediction> predictions =
        internal::PredictAll(*network, val, model_config.crop_frames);
    const Metrics val_metrics = ComputeMetrics(predictions, val, surface_radius_m);
    const double val_loss = PredictionLoss(predictions, val, train_config);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    seconds_sum += seconds;
    RecordEpoch(files, *network, optimizer, identity, train_config, epoch, lr, loss,
                uncertainty_head, val_loss, val_metrics, seconds, &best);
    if (show_progress) {
      const double eta =
          seconds_sum / double(epoch + 1 - epochs_done) * double(train_config.epochs - epoch - 1);
      spdlog::info(
          "epoch {}/{}: train loss {:.4g}, val loss {:.4g}, val MED {:.3f} cm (height {:.3f} cm, "
          "angle {:.2f} deg), lr {:.3g}, {:.1f} s, ETA {}",
          epoch + 1, train_config.epochs, loss.point, val_loss, val_metrics.med_cm,
          val_metrics.height_err_cm, val_metrics.angle_err_deg, lr, seconds, FormatDuration(eta));
    }
  }
  if (!writes) return Metrics{};
  // train.keep_best: the best epoch's weights are the model (a finished run's best.pt is its
  // model.pt)
  const bool model_is_best = train_config.keep_best && best.epoch > 0;
  if (model_is_best) {
    LoadWeights(network.get(), fs::exists(files.best_pt) ? files.best_pt : files.model_pt);
    if (show_progress)
      spdlog::info("keeping epoch {} (lowest validation loss {:.4g})", best.epoch, best.loss);
  }
  const int64_t epochs = std::max(epochs_done, train_config.epochs);
  const Metrics m = FinishRun(files, *network, train, val, model_config, train_config,
                              surface_radius_m, seed, uncertainty_head, epochs, show_progress,
                              KeptCalibration(fine_tune), fine_tune.calibration);
  KeepWhatResumeNeeds(files, optimizer, epochs, model_is_best);
  return m;
}

}  // namespace sonicboom::learning
