// The network modules: audio encoders (compact CNN, ResNet-18/50), GCC and proprioception
// encoders, transformer fusion and the regression head.

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <torch/nn.h>

#include "internal/network.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::learning::internal {

namespace nn = torch::nn;

NetworkShapes ShapesOf(const FeatureSet& f, const ModelConfig& config) {
  return NetworkShapes{f.channels, f.mels,         config.crop_frames, f.gcc_pairs,
                       f.gcc_lags, f.proprio_rows, f.proprio_features};
}

ModalitySet SelectedModalities(const ModelConfig& config) {
  ModalitySet set;
  for (const std::string& m : config.modalities) {
    if (m == "audio") set.audio = true;
    if (m == "gcc") set.gcc = true;
    if (m == "proprio") set.proprio = true;
  }
  set.arrivals = set.audio && config.arrival_picks != ArrivalPicks::kNone;
  set.audio_token = set.audio && config.arrival_picks != ArrivalPicks::kOnly;
  return set;
}

namespace {

// seq applied to x (B, features). For one row, each Linear runs as a matrix-vector product:
// BLAS gemm repacks the whole weight on every call, which for the GCC encoder's 1024 x 13 245
// weight cost more than the rest of a batch-1 forward pass together.
torch::Tensor ForwardRows(nn::Sequential& seq, torch::Tensor x) {
  for (auto& any : *seq) {
    const auto* linear = any.ptr()->as<nn::Linear>();
    if (linear != nullptr && x.dim() == 2 && x.size(0) == 1) {
      const torch::Tensor row = x.select(0, 0);
      x = (linear->bias.defined() ? torch::addmv(linear->bias, linear->weight, row)
                                  : torch::mv(linear->weight, row))
              .unsqueeze(0);
    } else {
      x = any.forward(x);
    }
  }
  return x;
}

nn::Conv2d Conv(int64_t in, int64_t out, int64_t kernel, int64_t stride, int64_t padding) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, kernel).stride(stride).padding(padding).bias(false));
}

// 1x1 conv + BN on the residual path when the block changes channels or resolution.
nn::Sequential Shortcut(int64_t in, int64_t out, int64_t stride) {
  if (stride == 1 && in == out) return nn::Sequential(nullptr);
  return nn::Sequential(Conv(in, out, 1, stride, 0), nn::BatchNorm2d(out));
}

}  // namespace

CompactCnnImpl::CompactCnnImpl(int64_t in_channels) {
  const int64_t widths[] = {16, 32, 64, kFeatures};
  int64_t in = in_channels;
  for (int i = 0; i < 4; ++i) {
    // the first convolution strides by 2: a quarter of the cost at full mel resolution
    const int64_t stride = i == 0 ? 2 : 1;
    convs_.push_back(register_module(fmt::format("conv{}", i), Conv(in, widths[i], 3, stride, 1)));
    norms_.push_back(register_module(fmt::format("bn{}", i), nn::BatchNorm2d(widths[i])));
    in = widths[i];
  }
}

torch::Tensor CompactCnnImpl::forward(torch::Tensor x) {
  // (B, C, H, W) -> (B, 128, ~H/32, ~W/32); an axis already of size 1 is not pooled further.
  for (size_t i = 0; i < convs_.size(); ++i) {
    x = torch::relu(norms_[i]->forward(convs_[i]->forward(x)));
    const int64_t kh = x.size(2) >= 2 ? 2 : 1, kw = x.size(3) >= 2 ? 2 : 1;
    x = torch::max_pool2d(x, {kh, kw});
  }
  // (B, 128)
  return x.mean({2, 3});
}

BasicBlockImpl::BasicBlockImpl(int64_t in_channels, int64_t planes, int64_t stride)
    : conv1_(register_module("conv1", Conv(in_channels, planes, 3, stride, 1))),
      conv2_(register_module("conv2", Conv(planes, planes, 3, 1, 1))),
      bn1_(register_module("bn1", nn::BatchNorm2d(planes))),
      bn2_(register_module("bn2", nn::BatchNorm2d(planes))),
      shortcut_(Shortcut(in_channels, planes * kExpansion, stride)) {
  if (shortcut_) register_module("shortcut", shortcut_);
}

torch::Tensor BasicBlockImpl::forward(torch::Tensor x) {
  torch::Tensor y = torch::relu(bn1_->forward(conv1_->forward(x)));
  y = bn2_->forward(conv2_->forward(y));
  return torch::relu(y + (shortcut_ ? shortcut_->forward(x) : x));
}

BottleneckImpl::BottleneckImpl(int64_t in_channels, int64_t planes, int64_t stride)
    : conv1_(register_module("conv1", Conv(in_channels, planes, 1, 1, 0))),
      conv2_(register_module("conv2", Conv(planes, planes, 3, stride, 1))),
      conv3_(register_module("conv3", Conv(planes, planes * kExpansion, 1, 1, 0))),
      bn1_(register_module("bn1", nn::BatchNorm2d(planes))),
      bn2_(register_module("bn2", nn::BatchNorm2d(planes))),
      bn3_(register_module("bn3", nn::BatchNorm2d(planes * kExpansion))),
      shortcut_(Shortcut(in_channels, planes * kExpansion, stride)) {
  if (shortcut_) register_module("shortcut", shortcut_);
}

torch::Tensor BottleneckImpl::forward(torch::Tensor x) {
  torch::Tensor y = torch::relu(bn1_->forward(conv1_->forward(x)));
  y = torch::relu(bn2_->forward(conv2_->forward(y)));
  y = bn3_->forward(conv3_->forward(y));
  return torch::relu(y + (shortcut_ ? shortcut_->forward(x) : x));
}

ResNetImpl::ResNetImpl(int64_t in_channels, int depth) {
  SONICBOOM_DEMAND(depth == 18 || depth == 50);
  const bool bottleneck = depth == 50;
  const std::vector<int64_t> counts =
      bottleneck ? std::vector<int64_t>{3, 4, 6, 3} : std::vector<int64_t>{2, 2, 2, 2};
  const int64_t expansion = bottleneck ? BottleneckImpl::kExpansion : BasicBlockImpl::kExpansion;
  stem_conv_ = register_module("stem_conv", Conv(in_channels, 64, 7, 2, 3));
  stem_bn_ = register_module("stem_bn", nn::BatchNorm2d(64));
  // Stages of 64, 128, 256, 512 planes; every stage but the first halves the resolution.
  int64_t in = 64;
  for (int s = 0; s < 4; ++s) {
    const int64_t planes = int64_t{64} << s;
    nn::Sequential stage;
    for (int64_t b = 0; b < counts[s]; ++b) {
      const int64_t stride = (s > 0 && b == 0) ? 2 : 1;
      if (bottleneck) {
        stage->push_back(Bottleneck(in, planes, stride));
      } else {
        stage->push_back(BasicBlock(in, planes, stride));
      }
      in = planes * expansion;
    }
    stages_.push_back(register_module(fmt::format("stage{}", s + 1), stage));
  }
  features_ = in;
}

torch::Tensor ResNetImpl::forward(torch::Tensor x) {
  // (B, C, H, W) -> (B, 64, H/4, W/4)
  x = torch::relu(stem_bn_->forward(stem_conv_->forward(x)));
  x = torch::max_pool2d(x, 3, 2, 1);
  // -> (B, features, H/32, W/32)
  for (auto& stage : stages_) x = stage->forward(x);
  // (B, features)
  return x.mean({2, 3});
}

Conv1dTrunkImpl::Conv1dTrunkImpl(int64_t in_channels) {
  // Every layer halves the time axis: 882 samples (20 ms) -> 28 steps after five layers. The
  // first kernel spans 15 samples (0.34 ms at 44.1 kHz) of every channel at full resolution.
  const int64_t widths[] = {32, 48, 64, 96, 128};
  const int64_t kernels[] = {15, 7, 7, 5, 5};
  int64_t in = in_channels;
  for (int i = 0; i < 5; ++i) {
    convs_.push_back(register_module(
        fmt::format("conv{}", i),
        nn::Conv1d(nn::Conv1dOptions(in, widths[i], kernels[i])
                       .stride(2)
                       .padding(kernels[i] / 2)
                       .bias(false))));
    norms_.push_back(register_module(fmt::format("bn{}", i), nn::BatchNorm1d(widths[i])));
    in = widths[i];
  }
}

torch::Tensor Conv1dTrunkImpl::forward(torch::Tensor x) {
  // (B, C, R, T) -> (B, C * R, T), scaled to unit RMS per record
  x = x.flatten(1, 2);
  x = x / torch::sqrt(x.square().mean({1, 2}, /*keepdim=*/true) + 1e-12);
  for (size_t i = 0; i < convs_.size(); ++i) {
    x = torch::gelu(norms_[i]->forward(convs_[i]->forward(x)));
  }
  // (B, 128, T') -> (B, 256)
  return torch::cat({x.mean(2), std::get<0>(x.max(2))}, 1);
}

AudioEncoderImpl::AudioEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes) {
  const int64_t w = config.width;
  if (config.audio_encoder == AudioEncoderKind::kConv1d) {
    conv1d_ = register_module("conv1d", Conv1dTrunk(shapes.channels * shapes.mels));
    projection_ =
        register_module("projection", nn::Sequential(nn::Linear(Conv1dTrunkImpl::kFeatures, w)));
  } else if (config.audio_encoder == AudioEncoderKind::kCompact) {
    compact_ = register_module("compact", CompactCnn(shapes.channels));
    projection_ =
        register_module("projection", nn::Sequential(nn::Linear(CompactCnnImpl::kFeatures, w)));
  } else {
    resnet_ = register_module(
        "resnet",
        ResNet(shapes.channels, config.audio_encoder == AudioEncoderKind::kResnet18 ? 18 : 50));
    // Projection MLP of the paper's model: features -> 4w -> w.
    projection_ = register_module(
        "projection", nn::Sequential(nn::Linear(resnet_->features(), 4 * w),
                                     nn::LayerNorm(nn::LayerNormOptions({4 * w})), nn::GELU(),
                                     nn::Dropout(config.dropout), nn::Linear(4 * w, w)));
  }
}

torch::Tensor AudioEncoderImpl::forward(torch::Tensor mel) {
  // (B, C, mels, crop) -> (B, features) -> (B, width)
  torch::Tensor features = compact_  ? compact_->forward(mel)
                           : conv1d_ ? conv1d_->forward(mel)
                                     : resnet_->forward(mel);
  return ForwardRows(projection_, features);
}

GccEncoderImpl::GccEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes) {
  const int64_t w = config.width, in = shapes.gcc_pairs * shapes.gcc_lags;
  if (config.gcc_encoder == GccEncoderKind::kConv) {
    // rows as channels; two stride-2 convolutions quarter the lag axis
    constexpr int64_t kChannels = 64;
    auto conv = [](int64_t from, int64_t to, int64_t stride) {
      return nn::Conv1d(nn::Conv1dOptions(from, to, 5).stride(stride).padding(2));
    };
    convs_ =
        register_module("convs", nn::Sequential(conv(shapes.gcc_pairs, kChannels, 1), nn::GELU(),
                                                conv(kChannels, kChannels, 2), nn::GELU(),
                                                conv(kChannels, kChannels, 2), nn::GELU()));
    int64_t lags = shapes.gcc_lags;
    for (int i = 0; i < 2; ++i) lags = (lags - 1) / 2 + 1;
    projection_ = register_module("projection", nn::Linear(kChannels * lags, w));
    return;
  }
  mlp_ = register_module(
      "mlp", nn::Sequential(nn::LayerNorm(nn::LayerNormOptions({in})), nn::Linear(in, 4 * w),
                            nn::LayerNorm(nn::LayerNormOptions({4 * w})), nn::GELU(),
                            nn::Dropout(config.dropout), nn::Linear(4 * w, 2 * w),
                            nn::LayerNorm(nn::LayerNormOptions({2 * w})), nn::GELU(),
                            nn::Dropout(config.dropout), nn::Linear(2 * w, w)));
}

torch::Tensor GccEncoderImpl::forward(torch::Tensor gcc) {
  // conv: (B, rows, lags) -> (B, 64, ~lags / 4) -> (B, width)
  if (convs_) return projection_->forward(convs_->forward(gcc).flatten(1));
  // mlp: (B, rows, lags) -> (B, rows * lags) -> (B, width)
  return ForwardRows(mlp_, gcc.flatten(1));
}

torch::Tensor ArrivalPicksOf(const torch::Tensor& waveform) {
  constexpr int64_t kSmoothSamples = 31;  // 0.7 ms at 44.1 kHz
  torch::NoGradGuard no_grad;
  // (B, C, 1, T) -> (B, C, T) energy, smoothed
  const torch::Tensor x = waveform.squeeze(2);
  const torch::Tensor energy = torch::avg_pool1d(x * x, kSmoothSamples, 1, kSmoothSamples / 2,
                                                 /*ceil_mode=*/false, /*count_include_pad=*/false);
  // (B, C, 1) each channel's peak (a silent channel picks 0)
  const torch::Tensor peak = std::get<0>(energy.max(2, /*keepdim=*/true)) + 1e-30;
  std::vector<torch::Tensor> picks;
  for (double fraction : kArrivalFractions) {
    const torch::Tensor level = peak * fraction;
    // first sample at or above the level (argmax returns the first maximum)
    const torch::Tensor at = (energy >= level).to(torch::kFloat).argmax(2, /*keepdim=*/true);
    const torch::Tensor before = (at - 1).clamp_min(0);
    // linear interpolation between the sample before and the crossing
    const torch::Tensor e0 = energy.gather(2, before), e1 = energy.gather(2, at);
    const torch::Tensor step = ((level - e0) / (e1 - e0).clamp_min(1e-30)).clamp(0.0, 1.0);
    const torch::Tensor t = before.to(torch::kFloat) + step * (at > 0).to(torch::kFloat);
    picks.push_back(t.squeeze(2));
  }
  return torch::stack(picks, 2);  // (B, C, K)
}

ArrivalEncoderImpl::ArrivalEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes) {
  const int64_t w = config.width, k = std::size(kArrivalFractions);
  const int64_t in = 2 * shapes.channels * k + k;
  mlp_ = register_module(
      "mlp", nn::Sequential(nn::Linear(in, 4 * w), nn::LayerNorm(nn::LayerNormOptions({4 * w})),
                            nn::GELU(), nn::Dropout(config.dropout), nn::Linear(4 * w, w)));
}

torch::Tensor ArrivalEncoderImpl::forward(const torch::Tensor& waveform) {
  constexpr double kSamplesPerMs = 44.1;  // a fixed scale; the MLP learns its own
  // (B, C, K) picks relative to the channels' mean, ms
  const torch::Tensor picks = ArrivalPicksOf(waveform);
  const torch::Tensor relative = (picks - picks.mean(1, /*keepdim=*/true)) / kSamplesPerMs;
  // (B, 1, K) spread across channels, ms (at least one sample)
  const torch::Tensor spread =
      relative.pow(2).mean(1, /*keepdim=*/true).sqrt().clamp_min(1.0 / kSamplesPerMs);
  // (B, 2CK + K)
  const torch::Tensor features = torch::cat(
      {relative.flatten(1), (relative / spread).flatten(1), spread.log().flatten(1)}, 1);
  return ForwardRows(mlp_, features);
}

ProprioEncoderImpl::ProprioEncoderImpl(const ModelConfig& config, const NetworkShapes& shapes) {
  auto conv = [](int64_t in, int64_t out) {
    return nn::Conv1d(nn::Conv1dOptions(in, out, 5).stride(2).padding(2));
  };
  const int64_t f = shapes.proprio_features;
  convs_ = register_module(
      "convs",
      nn::Sequential(nn::BatchNorm1d(f), conv(f, 16), nn::BatchNorm1d(16), nn::ReLU(),
                     nn::Dropout(config.dropout), conv(16, 32), nn::BatchNorm1d(32), nn::ReLU(),
                     nn::Dropout(config.dropout), conv(32, 128), nn::BatchNorm1d(128), nn::ReLU()));
  projection_ = register_module("projection", nn::Linear(128, config.width));
}

torch::Tensor ProprioEncoderImpl::forward(torch::Tensor proprio) {
  // (B, rows, features) -> (B, features, rows) -> (B, 128, ceil(rows / 8))
  torch::Tensor x = convs_->forward(proprio.transpose(1, 2));
  // (B, 128) -> (B, width)
  return projection_->forward(x.mean(2));
}

TransformerBlockImpl::TransformerBlockImpl(int64_t width, int64_t heads, double dropout)
    : heads_(heads),
      norm1_(register_module("norm1", nn::LayerNorm(nn::LayerNormOptions({width})))),
      norm2_(register_module("norm2", nn::LayerNorm(nn::LayerNormOptions({width})))),
      qkv_(register_module("qkv", nn::Linear(width, 3 * width))),
      out_(register_module("out", nn::Linear(width, width))),
      fc1_(register_module("fc1", nn::Linear(width, 4 * width))),
      fc2_(register_module("fc2", nn::Linear(4 * width, width))),
      attention_dropout_(register_module("attention_dropout", nn::Dropout(dropout))),
      dropout_(register_module("dropout", nn::Dropout(dropout))) {}

torch::Tensor TransformerBlockImpl::forward(torch::Tensor x) {
  const int64_t b = x.size(0), t = x.size(1), w = x.size(2), d = w / heads_;
  // Self-attention: (B, T, 3w) -> (3, B, heads, T, d)
  torch::Tensor qkv = qkv_->forward(norm1_->forward(x)).reshape({b, t, 3, heads_, d});
  qkv = qkv.permute({2, 0, 3, 1, 4});
  torch::Tensor q = qkv[0], k = qkv[1], v = qkv[2];
  // (B, heads, T, T) attention weights
  torch::Tensor attention = torch::matmul(q, k.transpose(-2, -1)) / std::sqrt(double(d));
  attention = attention_dropout_->forward(torch::softmax(attention, -1));
  // (B, heads, T, d) -> (B, T, w)
  torch::Tensor y = torch::matmul(attention, v).transpose(1, 2).reshape({b, t, w});
  x = x + dropout_->forward(out_->forward(y));
  // MLP: (B, T, w) -> (B, T, 4w) -> (B, T, w)
  y = fc2_->forward(dropout_->forward(torch::gelu(fc1_->forward(norm2_->forward(x)))));
  return x + dropout_->forward(y);
}

NetworkImpl::NetworkImpl(const ModelConfig& config, const NetworkShapes& shapes,
                         bool uncertainty_head)
    : modalities_(SelectedModalities(config)), shapes_(shapes) {
  const int64_t w = config.width;
  // Encoders of the selected modalities only.
  if (modalities_.audio) {
    if (modalities_.audio_token) {
      audio_encoder_ = register_module("audio_encoder", AudioEncoder(config, shapes));
    }
    mel_mean_ = register_buffer("mel_mean", torch::zeros({1, shapes.channels, 1, 1}));
    mel_std_ = register_buffer("mel_std", torch::ones({1, shapes.channels, 1, 1}));
  }
  if (modalities_.gcc) gcc_encoder_ = register_module("gcc_encoder", GccEncoder(config, shapes));
  if (modalities_.proprio) {
    proprio_encoder_ = register_module("proprio_encoder", ProprioEncoder(config, shapes));
  }
  if (modalities_.arrivals) {
    arrival_encoder_ = register_module("arrival_encoder", ArrivalEncoder(config, shapes));
  }
  // Tokens, transformer and head.
  cls_token_ = register_parameter("cls_token", torch::randn({1, 1, w}) * 0.02);
  modality_embedding_ =
      register_parameter("modality_embedding", torch::randn({1, modalities_.count(), w}) * 0.02);
  input_norm_ = register_module("input_norm", nn::LayerNorm(nn::LayerNormOptions({w})));
  for (int64_t i = 0; i < config.blocks; ++i) {
    blocks_.push_back(register_module(fmt::format("block{}", i),
                                      TransformerBlock(w, config.heads, config.dropout)));
  }
  head_ = register_module(
      "head", nn::Sequential(nn::LayerNorm(nn::LayerNormOptions({w})), nn::Linear(w, 2 * w),
                             nn::GELU(), nn::Dropout(config.dropout), nn::Linear(2 * w, 3)));
  // Init: Xavier for linear layers, He (fan-out) for convolutions, zero biases.
  torch::NoGradGuard no_grad;
  for (const auto& module : modules(/*include_self=*/false)) {
    if (auto* linear = module->as<nn::Linear>()) {
      nn::init::xavier_uniform_(linear->weight);
      nn::init::zeros_(linear->bias);
    } else if (auto* conv2 = module->as<nn::Conv2d>()) {
      nn::init::kaiming_normal_(conv2->weight, 0.0, torch::kFanOut, torch::kReLU);
    } else if (auto* conv1 = module->as<nn::Conv1d>()) {
      nn::init::kaiming_normal_(conv1->weight, 0.0, torch::kFanOut, torch::kReLU);
      if (conv1->bias.defined()) nn::init::zeros_(conv1->bias);
    }
  }
  // Uncertainty head last: its random draws come after those of every other part.
  if (uncertainty_head) {
    uncertainty_head_ = register_module(
        "uncertainty_head", nn::Sequential(nn::LayerNorm(nn::LayerNormOptions({w})),
                                           nn::Linear(w, w), nn::GELU(), nn::Linear(w, 2)));
    for (const auto& module : uncertainty_head_->modules(/*include_self=*/false)) {
      if (auto* linear = module->as<nn::Linear>()) {
        nn::init::xavier_uniform_(linear->weight);
        nn::init::zeros_(linear->bias);
      }
    }
  }
}

void NetworkImpl::SetNormalization(const std::vector<float>& mean, const std::vector<float>& std) {
  SONICBOOM_DEMAND(modalities_.audio);
  SONICBOOM_DEMAND(static_cast<int64_t>(mean.size()) == shapes_.channels);
  SONICBOOM_DEMAND(static_cast<int64_t>(std.size()) == shapes_.channels);
  torch::NoGradGuard no_grad;
  for (int64_t c = 0; c < shapes_.channels; ++c) {
    mel_mean_[0][c].fill_(mean[c]);
    mel_std_[0][c].fill_(std[c]);
  }
}

std::vector<float> NetworkImpl::MelMean() const {
  if (!modalities_.audio) return {};
  torch::Tensor flat = mel_mean_.reshape({-1}).contiguous();
  return std::vector<float>(flat.data_ptr<float>(), flat.data_ptr<float>() + flat.numel());
}

torch::Tensor NetworkImpl::forward(const Batch& batch) {
  // One (B, w) token per selected modality, in the fixed order audio, gcc, proprio, arrivals.
  std::vector<torch::Tensor> tokens;
  if (modalities_.audio_token) {
    // (B, C, mels, crop), normalized per mic
    torch::Tensor mel = (batch.mel - mel_mean_) / mel_std_;
    tokens.push_back(audio_encoder_->forward(mel));
  }
  if (modalities_.gcc) tokens.push_back(gcc_encoder_->forward(batch.gcc));
  if (modalities_.proprio) tokens.push_back(proprio_encoder_->forward(batch.proprio));
  // picks of the raw waveform: each channel against its own peak, so no scale matters
  if (modalities_.arrivals) tokens.push_back(arrival_encoder_->forward(batch.mel));
  const int64_t b = tokens.front().size(0);
  // (B, M, w) modality tokens + embeddings, then (B, 1 + M, w) with the CLS token first.
  torch::Tensor x = torch::stack(tokens, 1) + modality_embedding_;
  x = torch::cat({cls_token_.expand({b, 1, cls_token_.size(2)}), x}, 1);
  x = input_norm_->forward(x);
  for (auto& block : blocks_) x = block->forward(x);
  // CLS output (B, w) -> (B, 3)
  const torch::Tensor cls = x.select(1, 0);
  const torch::Tensor point = ForwardRows(head_, cls);
  if (!uncertainty_head_) return point;
  // (B, 2) log sigma_z (cm), log kappa from the detached CLS output -> (B, 5)
  const torch::Tensor raw = uncertainty_head_->forward(cls.detach());
  const torch::Tensor log_std = raw.select(1, 0).clamp(kLogStdZCmMin, kLogStdZCmMax);
  const torch::Tensor log_kappa = raw.select(1, 1).clamp(kLogKappaMin, kLogKappaMax);
  return torch::cat({point, torch::stack({log_std, log_kappa}, 1)}, 1);
}

bool IsEncoder(const std::string& part) {
  return part == "audio_encoder" || part == "gcc_encoder" || part == "proprio_encoder" ||
         part == "arrival_encoder";
}

std::map<std::string, int64_t> CountParametersOf(const NetworkImpl& network) {
  std::map<std::string, int64_t> counts;
  for (const auto& item : network.named_parameters(/*recurse=*/true)) {
    const std::string& name = item.key();
    const std::string top = name.substr(0, name.find('.'));
    counts[IsEncoder(top) ? top : "fusion"] += item.value().numel();
  }
  return counts;
}

}  // namespace sonicboom::learning::internal

namespace sonicboom::learning {

std::map<std::string, int64_t> CountParameters(const ModelConfig& config, const FeatureSet& shapes,
                                               bool uncertainty_head) {
  config.Validate();
  internal::Network network(config, internal::ShapesOf(shapes, config), uncertainty_head);
  return internal::CountParametersOf(*network);
}

}  // namespace sonicboom::learning
