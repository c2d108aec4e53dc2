// Localizer: a trained network loaded from a run directory (model.json + model.pt).

#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <torch/serialize.h>

#include "internal/data.h"
#include "internal/network.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;

struct Localizer::Impl {
  internal::ModelFile file;
  internal::Network network{nullptr};
};

Localizer::Localizer(const std::string& run_dir) : impl_(std::make_unique<Impl>()) {
  if (!fs::is_directory(run_dir)) {
    throw IoError(fmt::format("{}: run directory not found", run_dir));
  }
  // model.json: config and shapes the weights were trained with.
  const std::string json_path = (fs::path(run_dir) / "model.json").string();
  impl_->file = internal::ModelFileFromJson(internal::ReadJsonFile(json_path), json_path);
  const ModelConfig& config = impl_->file.model_config;
  const FeatureSet& shapes = impl_->file.shapes;
  if (internal::SelectedModalities(config).audio && config.crop_frames > shapes.frames) {
    throw SchemaError(fmt::format("{}: model.crop_frames = {} exceeds shapes.frames = {}",
                                  json_path, config.crop_frames, shapes.frames));
  }
  // model.pt: weights and normalization buffers.
  const std::string weights_path = (fs::path(run_dir) / "model.pt").string();
  if (!fs::is_regular_file(weights_path)) {
    throw IoError(fmt::format("{}: file not found", weights_path));
  }
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
  impl_->network = internal::Network(config, internal::ShapesOf(shapes, config), uncertainty_head);
  internal::LoadModuleChecked(*impl_->network, archive,
                              fmt::format("{} (with {})", weights_path, json_path));
  impl_->network->eval();
  if (!uncertainty_head) {
    spdlog::info("{}: the model has no uncertainty head; predictions are point estimates only",
                 weights_path);
  } else if (!impl_->file.has_calibration) {
    spdlog::warn(
        "{}: no 'uncertainty' calibration (written before calibration existed); "
        "using the uncalibrated distribution (scales 1)",
        json_path);
  }
}

Localizer::~Localizer() = default;
Localizer::Localizer(Localizer&&) noexcept = default;
Localizer& Localizer::operator=(Localizer&&) noexcept = default;

std::vector<Prediction> Localizer::Predict(const FeatureSet& features) const {
  const internal::ModalitySet use = impl_->network->modalities();
  internal::CheckFeatureSet(features, use, "features to localize");
  // the whole-window spectrogram as trained, or exactly the crop (its centre crop is itself)
  const int64_t crop = impl_->file.model_config.crop_frames;
  FeatureSet expected = impl_->file.shapes.ShapesOnly();
  if (use.audio && features.frames == crop) expected.frames = crop;
  internal::CheckSameShapes(expected, features, use, "features to localize");
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
  std::vector<Prediction> predictions = internal::PredictAll(*impl_->network, features, crop);
  for (size_t i = 0; i < predictions.size(); ++i) {
    Prediction& p = predictions[i];
    if (!std::isfinite(p.z_m) || !std::isfinite(p.theta_rad)) {
      throw NumericalError(
          fmt::format("the network's answer for strike {} is not finite (z = {}, theta = {}): "
                      "its inputs lie far outside what it was trained on",
                      i, p.z_m, p.theta_rad));
    }
    p = ApplyCalibration(p, impl_->file.calibration);
  }
  return predictions;
}

FeatureNeeds Localizer::needs() const {
  const internal::ModalitySet use = impl_->network->modalities();
  const int64_t frames = impl_->file.shapes.frames, crop = impl_->file.model_config.crop_frames;
  return FeatureNeeds{use.audio, use.gcc, use.proprio, CentreCropStart(frames, crop), crop};
}

bool Localizer::has_uncertainty() const {
  return impl_->network->has_uncertainty_head();
}

const UncertaintyCalibration& Localizer::calibration() const {
  return impl_->file.calibration;
}

const ModelConfig& Localizer::model_config() const {
  return impl_->file.model_config;
}

double Localizer::surface_radius_m() const {
  return impl_->file.surface_radius_m;
}

std::map<std::string, int64_t> Localizer::ParameterCounts() const {
  return internal::CountParametersOf(*impl_->network);
}

}  // namespace sonicboom::learning
