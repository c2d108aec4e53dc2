#pragma once
/// Feature checks, per-mic statistics, batch assembly (with the training augmentation),
/// batched prediction and the run-directory files shared by training and the Localizer.

#include <cstdint>
#include <string>
#include <vector>

#include <torch/nn.h>
#include <torch/serialize.h>
#include <nlohmann/json.hpp>

#include "internal/network.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning::internal {

/// Time bases: audio at 44.1 kHz, proprioception at 100 Hz.
inline constexpr double kSampleRateHz = 44100.0;
inline constexpr double kProprioRateHz = 100.0;
/// Batch size of evaluation and prediction.
inline constexpr int64_t kPredictBatch = 64;

/// Checks that the shape fields are positive and the arrays of the selected modalities and the
/// labels hold N records; `what` names the set in the SchemaError ("training features").
void CheckFeatureSet(const FeatureSet& f, const ModalitySet& use, const std::string& what);

/// Checks that `actual` has the shapes of `expected` for the selected modalities; the
/// SchemaError names the first dimension that differs.
void CheckSameShapes(const FeatureSet& expected, const FeatureSet& actual, const ModalitySet& use,
                     const std::string& what);
/// The shapes of the selected modalities in words: "mel 6 x 50 x 517, GCC 15 x 883, ...".
std::string ShapesText(const FeatureSet& f, const ModalitySet& use);

/// Per-mic mean and standard deviation over (N, mels, frames) of the listed records.
struct MelStats {
  std::vector<float> mean;
  std::vector<float> std;
};
MelStats ComputeMelStats(const FeatureSet& f, const std::vector<int64_t>& records);

/// Augmentation of one training record. A shift moves the mel crop (and the proprioception
/// window) later by `shift_frames`; masks blank [start, start + width) of the crop.
struct Augmentation {
  int64_t shift_frames{0};
  int64_t time_mask_start{0};
  int64_t time_mask_width{0};
  int64_t freq_mask_start{0};
  int64_t freq_mask_width{0};
  float sign{1.0f};  // -1: the record's audio inverted (train.polarity_flip)
  // the record's waveform read at centre + (t - centre) / stretch (train.time_stretch); 1: as is
  double stretch{1.0};
  // the record turned by rotation x 120 degrees (train.rotate_rings): channel p of each ring of
  // three reads disc (p - rotation) mod 3 of that ring, theta grows by as much; 0: as is
  int64_t rotation{0};
  // then mirrored about disc 0's angle (train.mirror_rings): channel p reads what channel -p mod
  // 3 of its ring read, theta becomes -theta (disc 0 at theta 0)
  bool mirror{false};
};
/// Theta (rad) of a strike seen through `a`'s turn and mirror.
double SymmetricTheta(double theta_rad, const Augmentation& a);
/// Theta (rad) of the strike whose image through `a` is at `seen_rad` (SymmetricTheta undone).
double UnturnedTheta(double seen_rad, const Augmentation& a);
/// Discs per ring that train.rotate_rings turns.
inline constexpr int64_t kRingDiscs = 3;
/// Whether a record can be turned by whole rings (train.rotate_rings, model.turn_average): audio
/// alone (a GCC pair or an arm pose would have to turn too), channels in rings of kRingDiscs.
inline bool TurnsByRings(const ModalitySet& use, int64_t channels) {
  return use.audio && !use.gcc && !use.proprio && channels % kRingDiscs == 0;
}
/// Draws the augmentation of record `record` in epoch `epoch` (deterministic in all three).
Augmentation DrawAugmentation(const TrainConfig& config, int64_t crop_frames, int64_t mels,
                              uint64_t seed, int64_t epoch, int64_t record);

/// Proprioception rows matching a shift of `shift_frames` audio frames `frame_hop_samples`
/// samples apart (FeatureSet::frame_hop_samples).
int64_t ProprioShiftRows(int64_t shift_frames, int64_t frame_hop_samples);

/// Inputs of `records` (centre crop; `augment` optional, one per record). Blanked or
/// out-of-range mel values are filled with `mel_fill[c]` (the channel mean, 0 after
/// normalization); out-of-range proprioception rows with 0.
Batch AssembleBatch(const FeatureSet& f, const std::vector<int64_t>& records,
                    const ModalitySet& use, int64_t crop_frames,
                    const std::vector<Augmentation>* augment, const std::vector<float>& mel_fill);

/// (B, 3) targets (z_cm, cos theta, sin theta) of `records`.
torch::Tensor AssembleTargets(const FeatureSet& f, const std::vector<int64_t>& records,
                              const std::vector<Augmentation>* augment = nullptr);

/// Predictions for every record of `f` in eval mode without gradients, in batches of
/// kPredictBatch, with the uncalibrated distribution when the network has an uncertainty head.
/// Leaves the network in eval mode. `symmetry` reads every record turned by rotation x 120
/// degrees and mirrored (Augmentation.rotation, .mirror: rings of three discs; the rest of it is
/// ignored) and maps each answer's theta back (UnturnedTheta).
std::vector<Prediction> PredictAll(NetworkImpl& network, const FeatureSet& f, int64_t crop_frames,
                                   const Augmentation& symmetry = {});

/// Writes a torch archive to `path` through core's checked atomic writer (IoError, no partial
/// left, when the disk is full).
void WriteArchiveAtomically(torch::serialize::OutputArchive& archive, const std::string& path);
/// Saves a module (parameters and buffers) to `path` through "<path>.partial" and a rename.
void SaveModuleAtomically(torch::nn::Module& module, const std::string& path);
/// Loads parameters and buffers of `module` from `archive`, then checks every tensor kept the
/// shape the module was built with; SchemaError names `origin` and the tensor.
void LoadModuleChecked(torch::nn::Module& module, torch::serialize::InputArchive& archive,
                       const std::string& origin);
/// Reads a JSON file; IoError when missing or unreadable, SchemaError when malformed.
nlohmann::json ReadJsonFile(const std::string& path);

/// Shape fields of a FeatureSet as JSON and back (SchemaError names `origin`).
nlohmann::json ShapesToJson(const FeatureSet& f);
FeatureSet ShapesFromJson(const nlohmann::json& j, const std::string& origin);

/// Metrics as JSON (NaN becomes null).
nlohmann::json MetricsToJson(const Metrics& m);

/// The two scales of an "uncertainty" object (model.json or ensemble.json); SchemaError naming
/// `origin` and the key when either is not a positive finite number.
UncertaintyCalibration CalibrationFromJson(const nlohmann::json& uncertainty,
                                           const std::string& origin);

/// Contents of model.json. "uncertainty" (the calibration) is optional: files of models
/// without an uncertainty head, and files written before calibration existed, lack it.
struct ModelFile {
  ModelConfig model_config;
  FeatureSet shapes;  // shape fields only
  double surface_radius_m{0.0};
  uint64_t seed{0};
  bool has_calibration{false};
  UncertaintyCalibration calibration;  // scales 1 without "uncertainty"
  Metrics uncalibrated_val_metrics;    // written with the calibration, not read back
  std::string calibration_method;      // written as "method" (CalibrationFit), not read back
};
nlohmann::json ModelFileToJson(const ModelFile& file, const TrainConfig& train_config,
                               const Metrics& val_metrics, int64_t epochs_trained);
ModelFile ModelFileFromJson(const nlohmann::json& j, const std::string& origin);

}  // namespace sonicboom::learning::internal
