#pragma once
/// The multimodal localization network: one encoder per selected modality (audio mel image,
/// GCC-PHAT lags, proprioception window) turns its input into a token; a learned CLS token and
/// the modality tokens pass through pre-norm transformer blocks; the CLS output is regressed to
/// (z_cm, cos theta, sin theta). An optional second head reads the detached CLS output and
/// predicts (log sigma_z in cm, log kappa) of the predictive distribution, so that no gradient
/// of the uncertainty loss reaches the point estimate.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <torch/nn.h>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning::internal {

/// Input sizes the network is built for.
struct NetworkShapes {
  int64_t channels{6};
  int64_t mels{50};
  int64_t crop_frames{345};
  int64_t gcc_pairs{15};
  int64_t gcc_lags{883};
  int64_t proprio_rows{50};
  int64_t proprio_features{10};
};

/// Shapes of features `f` as seen by a network with `config` (mel cropped to crop_frames).
NetworkShapes ShapesOf(const FeatureSet& f, const ModelConfig& config);

/// One batch of inputs; a tensor is undefined when its modality is not selected.
struct Batch {
  torch::Tensor mel;      // (B, channels, mels, crop_frames), un-normalized
  torch::Tensor gcc;      // (B, gcc_pairs, gcc_lags)
  torch::Tensor proprio;  // (B, proprio_rows, proprio_features)
};

/// Ranges the uncertainty head's outputs are clamped to: sigma_z in [0.0067, 1097] cm, kappa in
/// [9e-4, 1.6e5] (from a uniform angle to an angular standard deviation of 0.14 degrees).
inline constexpr double kLogStdZCmMin = -5.0;
inline constexpr double kLogStdZCmMax = 7.0;
inline constexpr double kLogKappaMin = -7.0;
inline constexpr double kLogKappaMax = 12.0;

/// Which modalities a config selects. `audio` says the audio features are read; `audio_token`
/// whether the audio encoder makes a token of them, `arrivals` whether the arrival picks do.
struct ModalitySet {
  bool audio{false};
  bool gcc{false};
  bool proprio{false};
  bool audio_token{false};
  bool arrivals{false};
  /// Tokens besides CLS.
  int64_t count() const {
    return int64_t{audio_token} + int64_t{gcc} + int64_t{proprio} + int64_t{arrivals};
  }
};
ModalitySet SelectedModalities(const ModelConfig& config);

/// Small CNN: 4 x (conv3x3-BN-ReLU-maxpool2) with 16-32-64-128 channels, global average pool.
class CompactCnnImpl : public torch::nn::Module {
 public:
  explicit CompactCnnImpl(int64_t in_channels);
  torch::Tensor forward(torch::Tensor x);  // (B, C, H, W) -> (B, 128)
  static constexpr int64_t kFeatures = 128;

 private:
  std::vector<torch::nn::Conv2d> convs_;
  std::vector<torch::nn::BatchNorm2d> norms_;
};
TORCH_MODULE(CompactCnn);

/// ResNet v1 basic residual block (two 3x3 convs), as in ResNet-18/34.
class BasicBlockImpl : public torch::nn::Module {
 public:
  BasicBlockImpl(int64_t in_channels, int64_t planes, int64_t stride);
  torch::Tensor forward(torch::Tensor x);
  static constexpr int64_t kExpansion = 1;

 private:
  torch::nn::Conv2d conv1_{nullptr}, conv2_{nullptr};
  torch::nn::BatchNorm2d bn1_{nullptr}, bn2_{nullptr};
  torch::nn::Sequential shortcut_{nullptr};  // 1x1 conv + BN when the shape changes
};
TORCH_MODULE(BasicBlock);

/// ResNet v1.5 bottleneck block (1x1 reduce, 3x3 with the stride, 1x1 expand x4), ResNet-50.
class BottleneckImpl : public torch::nn::Module {
 public:
  BottleneckImpl(int64_t in_channels, int64_t planes, int64_t stride);
  torch::Tensor forward(torch::Tensor x);
  static constexpr int64_t kExpansion = 4;

 private:
  torch::nn::Conv2d conv1_{nullptr}, conv2_{nullptr}, conv3_{nullptr};
  torch::nn::BatchNorm2d bn1_{nullptr}, bn2_{nullptr}, bn3_{nullptr};
  torch::nn::Sequential shortcut_{nullptr};
};
TORCH_MODULE(Bottleneck);

/// ResNet trunk with an `in_channels` stem, four stages and global average pooling.
class ResNetImpl : public torch::nn::Module {
 public:
  /// `depth` is 18 (BasicBlock [2,2,2,2]) or 50 (Bottleneck [3,4,6,3]).
  ResNetImpl(int64_t in_channels, int depth);
  torch::Tensor forward(torch::Tensor x);  // (B, C, H, W) -> (B, features())
  int64_t features() const { return features_; }

 private:
  torch::nn::Conv2d stem_conv_{nullptr};
  torch::nn::BatchNorm2d stem_bn_{nullptr};
  std::vector<torch::nn::Sequential> stages_;
  int64_t features_{0};
};
TORCH_MODULE(ResNet);

/// Strided 1-D convolutions over time, the input's (channel, row) pairs as input channels:
/// (B, C, R, T) -> (B, 256): average and maximum over time of the last layer's 128 channels.
/// Each record is first scaled to unit RMS over all its values.
class Conv1dTrunkImpl : public torch::nn::Module {
 public:
  explicit Conv1dTrunkImpl(int64_t in_channels);
  torch::Tensor forward(torch::Tensor x);
  static constexpr int64_t kFeatures = 256;

 private:
  std::vector<torch::nn::Conv1d> convs_;
  std::vector<torch::nn::BatchNorm1d> norms_;
};
TORCH_MODULE(Conv1dTrunk);

/// Audio token: a CNN trunk over the normalized mel image, projected to `width`.
class AudioEncoderImpl : public torch::nn::Module {
 public:
  AudioEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes);
  torch::Tensor forward(torch::Tensor mel);  // (B, C, mels, crop) -> (B, width)

 private:
  CompactCnn compact_{nullptr};
  ResNet resnet_{nullptr};
  Conv1dTrunk conv1d_{nullptr};
  torch::nn::Sequential projection_{nullptr};
};
TORCH_MODULE(AudioEncoder);

/// GCC token: LayerNorm over the flattened lags, then an MLP 4w -> 2w -> w.
class GccEncoderImpl : public torch::nn::Module {
 public:
  GccEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes);
  torch::Tensor forward(torch::Tensor gcc);  // (B, pairs, lags) -> (B, width)

 private:
  torch::nn::Sequential mlp_{nullptr};    // "mlp"
  torch::nn::Sequential convs_{nullptr};  // "conv": (B, rows, lags) -> (B, 64, ~lags / 4)
  torch::nn::Linear projection_{nullptr};
};
TORCH_MODULE(GccEncoder);

/// Arrival picks of a waveform window (model.arrival_picks): (B, C, 1, T) -> (B, C, K), in
/// samples, the first (sub-sample) time each channel's energy, smoothed over kSmoothSamples,
/// reaches kArrivalFractions[k] of that channel's peak. Not differentiable (an input).
inline constexpr double kArrivalFractions[] = {0.03, 0.1, 0.3, 1.0};
torch::Tensor ArrivalPicksOf(const torch::Tensor& waveform);

/// Arrival token: from the picks, the times relative to the channels' mean (ms at 44.1 kHz),
/// the same over their spread across channels, and the log spread, (B, 2CK + K), through an
/// MLP (4w, LayerNorm, GELU) to width.
class ArrivalEncoderImpl : public torch::nn::Module {
 public:
  ArrivalEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes);
  torch::Tensor forward(const torch::Tensor& waveform);  // (B, C, 1, T) -> (B, width)

 private:
  torch::nn::Sequential mlp_{nullptr};
};
TORCH_MODULE(ArrivalEncoder);

/// Proprioception token: BatchNorm over features, three strided 1-D convs, pooled, linear.
class ProprioEncoderImpl : public torch::nn::Module {
 public:
  ProprioEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes);
  torch::Tensor forward(torch::Tensor proprio);  // (B, rows, features) -> (B, width)

 private:
  torch::nn::Sequential convs_{nullptr};
  torch::nn::Linear projection_{nullptr};
};
TORCH_MODULE(ProprioEncoder);

/// Pre-norm transformer block: x + Attn(LN(x)), then x + MLP(LN(x)) with a 4x GELU MLP.
class TransformerBlockImpl : public torch::nn::Module {
 public:
  TransformerBlockImpl(int64_t width, int64_t heads, double dropout);
  torch::Tensor forward(torch::Tensor x);  // (B, T, width) -> (B, T, width)

 private:
  int64_t heads_;
  torch::nn::LayerNorm norm1_{nullptr}, norm2_{nullptr};
  torch::nn::Linear qkv_{nullptr}, out_{nullptr}, fc1_{nullptr}, fc2_{nullptr};
  torch::nn::Dropout attention_dropout_{nullptr}, dropout_{nullptr};
};
TORCH_MODULE(TransformerBlock);

/// The whole network. The per-mic mel normalization lives in buffers mel_mean / mel_std, so it
/// is saved with the weights.
class NetworkImpl : public torch::nn::Module {
 public:
  /// With `uncertainty_head` false this is the paper's network (and the weights of runs trained
  /// before the head existed). The head is built after every other part is initialized, so for
  /// a given torch seed the other parts start from the same weights either way.
  NetworkImpl(const ModelConfig& config, const NetworkShapes& shapes, bool uncertainty_head);
  /// (B, 3) = (z_cm, cos theta, sin theta), or with the uncertainty head (B, 5) with
  /// (log sigma_z_cm, log kappa) appended, clamped to the ranges above.
  torch::Tensor forward(const Batch& batch);
  bool has_uncertainty_head() const { return !uncertainty_head_.is_empty(); }

  /// Sets the normalization (one mean and std per mel channel).
  void SetNormalization(const std::vector<float>& mean, const std::vector<float>& std);
  /// Per-channel means (the raw value that normalizes to 0), empty without audio.
  std::vector<float> MelMean() const;

  const ModalitySet& modalities() const { return modalities_; }
  const NetworkShapes& shapes() const { return shapes_; }

 private:
  ModalitySet modalities_;
  NetworkShapes shapes_;
  AudioEncoder audio_encoder_{nullptr};
  GccEncoder gcc_encoder_{nullptr};
  ProprioEncoder proprio_encoder_{nullptr};
  ArrivalEncoder arrival_encoder_{nullptr};
  torch::Tensor mel_mean_, mel_std_;  // (1, channels, 1, 1) buffers
  torch::Tensor cls_token_;           // (1, 1, width)
  torch::Tensor modality_embedding_;  // (1, modalities, width)
  torch::nn::LayerNorm input_norm_{nullptr};
  std::vector<TransformerBlock> blocks_;
  torch::nn::Sequential head_{nullptr};
  torch::nn::Sequential uncertainty_head_{nullptr};
};
TORCH_MODULE(Network);

/// Whether a top-level part of the network (a child module's name) is a modality encoder.
bool IsEncoder(const std::string& part);

/// Trainable parameters per part ("audio_encoder", "gcc_encoder", "proprio_encoder",
/// "arrival_encoder", "fusion").
std::map<std::string, int64_t> CountParametersOf(const NetworkImpl& network);

}  // namespace sonicboom::learning::internal
