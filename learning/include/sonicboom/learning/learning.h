#pragma once
/// Learning: the multimodal localization network (libtorch stays inside learning/*.cc),
/// training, evaluation and localization. Inputs are features already computed by
/// sonicboom::acoustics::FeatureExtractor plus proprioception windows.

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"

namespace sonicboom::learning {

/// Network shape. Cheaper settings trade accuracy for speed.
struct ModelConfig {
  std::string audio_encoder{"compact"};    // compact | resnet18 | resnet50 (6 input channels)
  int64_t width{256};                      // transformer width (token size)
  int64_t blocks{6};                       // pre-norm transformer blocks
  int64_t heads{8};
  double dropout{0.1};
  std::vector<std::string> modalities{"audio", "gcc", "proprio"};  // any non-empty subset
  int64_t crop_frames{345};                // mel frames seen by the network (centre crop)

  void Serialize(Archive* a);
  /// Checks every field and the cross-field rules (heads divide width, known modalities);
  /// throws ConfigError naming the key as "model.<field>".
  void Validate() const;
};

/// Optimisation and augmentation.
struct TrainConfig {
  int64_t epochs{100};
  int64_t batch_size{64};
  double learning_rate{5e-3};              // Adam
  int64_t lr_step_epochs{20};              // StepLR period
  double lr_gamma{0.5};
  double val_fraction{0.2};                // of the training file, split by sample seed
  double loss_weight_z{1.0};               // z in cm
  double loss_weight_cos{5.0};
  double loss_weight_sin{5.0};
  bool augment{true};                      // time shift + time/frequency masking (train only)
  int64_t time_shift_frames{34};           // +- mel frames, applied to every time-aligned input
  int64_t time_mask_frames{40};
  int64_t freq_mask_bands{5};
  bool normalize{true};                    // per-mic normalization, train-split statistics
  int64_t threads{0};                      // intra-op threads, 0 = all cores

  void Serialize(Archive* a);
  /// Checks every field; throws ConfigError naming the key as "train.<field>".
  void Validate() const;
};

/// In-memory features of N strikes. Row-major flat arrays with the shapes given.
struct FeatureSet {
  int64_t channels{6};
  int64_t mels{50};
  int64_t frames{517};
  int64_t gcc_pairs{15};
  int64_t gcc_lags{883};
  int64_t proprio_rows{50};
  int64_t proprio_features{10};
  std::vector<float> mel;                  // (N x channels x mels x frames)
  std::vector<float> gcc;                  // (N x gcc_pairs x gcc_lags)
  std::vector<float> proprio;              // (N x proprio_rows x proprio_features)
  std::vector<double> z_m;                 // (N) labels (may be NaN when unknown)
  std::vector<double> theta_rad;           // (N)
  int64_t size() const { return static_cast<int64_t>(z_m.size()); }
  /// The same shapes with no rows.
  FeatureSet ShapesOnly() const;
  /// Rows `rows` (indices into this set), in that order.
  FeatureSet SelectRows(const std::vector<int64_t>& rows) const;
};

/// Localization errors over a set of strikes.
struct Metrics {
  int64_t n{0};
  double med_cm{0.0};                      // mean 3-D distance between surface points, cm
  double height_err_cm{0.0};               // mean |dz|, cm
  double angle_err_deg{0.0};               // mean wrapped |dtheta|, degrees
  double reference_med_cm{0.0};            // published code's mixed-unit MED (z in cm, r in m)
};

/// One prediction.
struct Prediction {
  double z_m{0.0};
  double theta_rad{0.0};
};

/// Trains on `train`, validates on `val` each epoch, writes into run_dir:
/// model.pt (weights + normalization), model.json (ModelConfig + shapes + tube radius),
/// metrics.jsonl (one line per epoch), checkpoint.pt (resume). Resumes from run_dir/checkpoint.pt
/// when it exists and `resume` is set. `surface_radius_m` is used for the 3-D metrics.
/// Returns the validation metrics of the final model.
Metrics Train(const FeatureSet& train, const FeatureSet& val, const ModelConfig& model_config,
              const TrainConfig& train_config, double surface_radius_m, uint64_t seed,
              const std::string& run_dir, bool resume, bool show_progress);

/// A trained model loaded from a run directory, for evaluation and localization.
class Localizer {
 public:
  explicit Localizer(const std::string& run_dir);  // throws IoError/SchemaError naming the file
  ~Localizer();
  Localizer(Localizer&&) noexcept;
  Localizer& operator=(Localizer&&) noexcept;

  std::vector<Prediction> Predict(const FeatureSet& features) const;
  const ModelConfig& model_config() const;
  double surface_radius_m() const;
  /// Trainable parameters of the loaded network per part (see CountParameters).
  std::map<std::string, int64_t> ParameterCounts() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Trainable parameters of the network that `config` builds for features shaped like `shapes`
/// (only the shape fields are read), per part: "audio_encoder", "gcc_encoder", "proprio_encoder"
/// (present only when the modality is selected) and "fusion" (tokens, transformer, head).
std::map<std::string, int64_t> CountParameters(const ModelConfig& config, const FeatureSet& shapes);

/// Metrics of predictions against the labels in `truth`.
Metrics ComputeMetrics(const std::vector<Prediction>& predictions, const FeatureSet& truth,
                       double surface_radius_m);

}  // namespace sonicboom::learning
