// Localizer: a trained network loaded from a run directory (model.json + model.pt), or the
// members of an ensemble directory, whose predictions are combined.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <torch/serialize.h>

#include "internal/data.h"
#include "internal/loaded_run.h"
#include "internal/network.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;

internal::LoadedRun internal::LoadRun(const std::string& run_dir) {
  if (!fs::is_directory(run_dir)) {
    throw IoError(fmt::format("{}: run directory not found", run_dir));
  }
  LoadedRun member;
  // model.json: config and shapes the weights were trained with.
  const std::string json_path = (fs::path(run_dir) / "model.json").string();
  member.file = internal::ModelFileFromJson(internal::ReadJsonFile(json_path), json_path);
  member.origin = json_path;
  const ModelConfig& config = member.file.model_config;
  const FeatureSet& shapes = member.file.shapes;
  if (internal::SelectedModalities(config).audio && config.crop_frames > shapes.frames) {
    throw SchemaError(fmt::format("{}: model.crop_frames = {} exceeds shapes.frames = {}",
                                  json_path, config.crop_frames, shapes.frames));
  }
  // model.pt: weights and normalization buffers.
  const std::string weights_path = (fs::path(run_dir) / "model.pt").string();
  RequireReadableFile(weights_path);
  torch::serialize::InputArchive archive;
  bool uncertainty_head = false;
  try {
    archive.load_from(weights_path);
    // Weights trained before the uncertainty head existed, or with
    // train.uncertainty_weight = 0, have no "uncertainty_head" entry.
    torch::serialize::InputArchive head;
    uncertainty_head = archive.try_read("uncertainty_head", head);
  } catch (const c10::Error& e) {
    throw SchemaError(fmt::format("{}: unreadable: {}", weights_path, e.what_without_backtrace()));
  }
  member.network = internal::Network(config, internal::ShapesOf(shapes, config), uncertainty_head);
  internal::LoadModuleChecked(*member.network, archive,
                              fmt::format("{} (with {})", weights_path, json_path));
  member.network->eval();
  if (!uncertainty_head) {
    spdlog::info("{}: the model has no uncertainty head; predictions are point estimates only",
                 weights_path);
  } else if (!member.file.has_calibration) {
    spdlog::warn(
        "{}: no 'uncertainty' calibration (written before calibration existed); "
        "using the uncalibrated distribution (scales 1)",
        json_path);
  }
  return member;
}

void internal::CheckFeaturesFor(const LoadedRun& run, const FeatureSet& features,
                                const std::string& what) {
  const ModalitySet use = run.network->modalities();
  CheckFeatureSet(features, use, what);
  // the whole-window spectrogram as trained, or exactly the crop (its centre crop is itself)
  const int64_t crop = run.file.model_config.crop_frames;
  FeatureSet expected = run.file.shapes.ShapesOnly();
  if (use.audio && features.frames == crop) expected.frames = crop;
  try {
    CheckSameShapes(expected, features, use, what);
  } catch (const SchemaError& e) {
    throw SchemaError(fmt::format("{}: {} (the features: {}; the model's: {})", run.origin,
                                  e.what(), ShapesText(features, use), ShapesText(expected, use)));
  }
}

namespace {

using Member = internal::LoadedRun;

// What a member reads of each strike.
FeatureNeeds NeedsOf(const Member& m) {
  const internal::ModalitySet use = m.network->modalities();
  const int64_t frames = m.file.shapes.frames, crop = m.file.model_config.crop_frames;
  return FeatureNeeds{use.audio, use.gcc, use.proprio, CentreCropStart(frames, crop), crop};
}

bool SameNeeds(const FeatureNeeds& a, const FeatureNeeds& b) {
  return a.audio == b.audio && a.gcc == b.gcc && a.proprio == b.proprio &&
         a.mel_first_frame == b.mel_first_frame && a.mel_frames == b.mel_frames;
}

// One mixture per strike of several answers to every strike (each[k][i]: answer k to strike i).
std::vector<Prediction> MixPerStrike(const std::vector<std::vector<Prediction>>& each) {
  std::vector<Prediction> combined(each.front().size()), strike(each.size());
  for (size_t i = 0; i < combined.size(); ++i) {
    for (size_t k = 0; k < each.size(); ++k) strike[k] = each[k][i];
    combined[i] = CombinePredictions(strike);
  }
  return combined;
}

// Turning a strike moves its audio alone, by whole rings of three discs.
void CheckTurnable(const Member& m, const FeatureSet& features) {
  if (!internal::TurnsByRings(m.network->modalities(), features.channels)) {
    throw ConfigError(fmt::format(
        "turn averaging needs model.modalities = [audio] (a GCC pair or an arm pose would have "
        "to turn too) and channels in rings of {} (got {} channels)",
        internal::kRingDiscs, features.channels));
  }
}

// The calibrated predictions of one member for `features` (checked against its shapes), each
// the combination of its three turns with `turn_average`, of each turn and its mirror image
// with `mirror_average` too.
std::vector<Prediction> PredictMember(const Member& m, const FeatureSet& features,
                                      const LocalizerOptions& symmetry) {
  const internal::ModalitySet use = m.network->modalities();
  internal::CheckFeaturesFor(m, features, "features to localize");
  // non-finite inputs never become an answer
  auto check_finite = [&](const std::vector<float>& values, bool used, const char* what) {
    if (!used) return;
    for (size_t k = 0; k < values.size(); ++k) {
      if (!std::isfinite(values[k])) {
        throw NumericalError(
            fmt::format("features to localize: the {} of strike {} holds a "
                        "non-finite value",
                        what, k / std::max<size_t>(1, values.size() / features.size())));
      }
    }
  };
  check_finite(features.mel, use.audio, "mel spectrogram");
  check_finite(features.gcc, use.gcc, "GCC-PHAT");
  check_finite(features.proprio, use.proprio, "proprioception");
  // the strike as it is, then its turns and their mirror images as asked
  std::vector<internal::Augmentation> images;
  for (int64_t turn = 0; turn < (symmetry.turn_average ? internal::kRingDiscs : 1); ++turn) {
    for (const bool mirror : {false, true}) {
      if (mirror && !symmetry.mirror_average) continue;
      images.push_back({.rotation = turn, .mirror = mirror});
    }
  }
  std::vector<std::vector<Prediction>> turns;
  for (const internal::Augmentation& image : images) {
    turns.push_back(
        internal::PredictAll(*m.network.ptr(), features, m.file.model_config.crop_frames, image));
    for (size_t i = 0; i < turns.back().size(); ++i) {
      Prediction& p = turns.back()[i];
      if (!std::isfinite(p.z_m) || !std::isfinite(p.theta_rad)) {
        throw NumericalError(
            fmt::format("the network's answer for strike {} is not finite (z = {}, theta = {}): "
                        "its inputs lie far outside what it was trained on",
                        i, p.z_m, p.theta_rad));
      }
      p = ApplyCalibration(p, m.file.calibration);
    }
  }
  return turns.size() == 1 ? turns.front() : MixPerStrike(turns);
}

}  // namespace

struct Localizer::Impl {
  LocalizerOptions options;
  std::vector<internal::LoadedRun> members;       // one, or an ensemble's
  UncertaintyCalibration mixture_calibration;  // an ensemble's, of the combined distribution
};

Localizer::Localizer(const std::string& run_dir, const LocalizerOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (!fs::is_directory(run_dir)) {
    throw IoError(fmt::format("{}: run directory not found", run_dir));
  }
  impl_->options = options;
  const std::vector<std::string> member_dirs = EnsembleMembers(run_dir);
  if (member_dirs.empty()) {
    impl_->members.push_back(internal::LoadRun(run_dir));
    return;
  }
  impl_->mixture_calibration = EnsembleCalibration(run_dir);
  for (const std::string& dir : member_dirs) {
    impl_->members.push_back(internal::LoadRun(dir));
    if (!SameNeeds(NeedsOf(impl_->members.front()), NeedsOf(impl_->members.back())) ||
        impl_->members.front().file.surface_radius_m !=
            impl_->members.back().file.surface_radius_m) {
      throw SchemaError(fmt::format(
          "{}: ensemble member {} reads other features (modalities, crop) or another tube than "
          "member {}",
          run_dir, dir, member_dirs.front()));
    }
  }
}

Localizer::~Localizer() = default;
Localizer::Localizer(Localizer&&) noexcept = default;
Localizer& Localizer::operator=(Localizer&&) noexcept = default;

std::vector<Prediction> Localizer::Predict(const FeatureSet& features) const {
  const std::vector<Member>& members = impl_->members;
  const ModelConfig& model = members.front().file.model_config;
  LocalizerOptions symmetry;
  symmetry.turn_average = impl_->options.turn_average || model.turn_average;
  symmetry.mirror_average = impl_->options.mirror_average || model.mirror_average;
  if (symmetry.mirror_average && !symmetry.turn_average) {
    throw ConfigError("mirror averaging reads each turn mirrored: it needs turn averaging too");
  }
  if (symmetry.turn_average) CheckTurnable(members.front(), features);
  if (members.size() == 1) return PredictMember(members.front(), features, symmetry);
  // every member's predictions, then one mixture per strike
  std::vector<std::vector<Prediction>> each;
  for (const Member& m : members) each.push_back(PredictMember(m, features, symmetry));
  std::vector<Prediction> combined = MixPerStrike(each);
  for (Prediction& p : combined) p = ApplyCalibration(p, impl_->mixture_calibration);
  return combined;
}

FeatureNeeds Localizer::needs() const {
  return NeedsOf(impl_->members.front());
}

bool Localizer::has_uncertainty() const {
  for (const Member& m : impl_->members) {
    if (!m.network->has_uncertainty_head()) return false;
  }
  return true;
}

const UncertaintyCalibration& Localizer::calibration() const {
  return impl_->members.size() > 1 ? impl_->mixture_calibration
                                   : impl_->members.front().file.calibration;
}

const ModelConfig& Localizer::model_config() const {
  return impl_->members.front().file.model_config;
}

double Localizer::surface_radius_m() const {
  return impl_->members.front().file.surface_radius_m;
}

std::map<std::string, int64_t> Localizer::ParameterCounts() const {
  std::map<std::string, int64_t> counts;
  for (const Member& m : impl_->members) {
    for (const auto& [part, n] : internal::CountParametersOf(*m.network)) counts[part] += n;
  }
  return counts;
}

int64_t Localizer::members() const {
  return static_cast<int64_t>(impl_->members.size());
}

}  // namespace sonicboom::learning
