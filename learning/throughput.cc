// Training speed of the network on random features: the step of learning::Train, timed.
#include "sonicboom/learning/throughput.h"

#include <algorithm>
#include <chrono>
#include <random>

#include <fmt/format.h>

#include <torch/optim.h>
#include <torch/torch.h>

#include "internal/network.h"
#include "internal/train_step.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::learning {

ThroughputResult MeasureTrainThroughput(const ModelConfig& model_config,
                                        const TrainConfig& train_config, const FeatureSet& shapes,
                                        int64_t steps, int64_t warmup, uint64_t seed) {
  model_config.Validate();
  train_config.Validate();
  if (steps < 1) throw ConfigError(fmt::format("throughput steps must be >= 1, got {}", steps));
  internal::PrepareTrainingProcess(train_config);

  // random features of two batches: mel power in [0, 1), small GCC values, unit proprioception
  const int64_t n = 2 * train_config.batch_size;
  FeatureSet f = shapes.ShapesOnly();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  f.mel.resize(static_cast<size_t>(n * f.channels * f.mels * f.frames));
  for (float& v : f.mel) v = unit(rng);
  f.gcc.resize(static_cast<size_t>(n * f.gcc_pairs * f.gcc_lags));
  for (float& v : f.gcc) v = 0.01f * normal(rng);
  f.proprio.resize(static_cast<size_t>(n * f.proprio_rows * f.proprio_features));
  for (float& v : f.proprio) v = normal(rng);
  for (int64_t i = 0; i < n; ++i) {
    f.z_m.push_back(0.1 * (unit(rng) - 0.5));
    f.theta_rad.push_back(6.28 * (unit(rng) - 0.5));
  }

  // the network and optimizer as Train builds them
  torch::manual_seed(seed);
  internal::Network network(model_config, internal::ShapesOf(f, model_config),
                            train_config.uncertainty_weight > 0.0);
  torch::optim::Adam optimizer(network->parameters(),
                               torch::optim::AdamOptions(train_config.learning_rate));
  const internal::ModalitySet use = internal::SelectedModalities(model_config);
  network->train();
  const std::vector<float> fill = network->MelMean();

  // warm-up steps (allocator, kernels), then timed steps over the two batches in turn
  std::vector<std::vector<int64_t>> batches(2);
  for (int64_t i = 0; i < n; ++i) batches[i / train_config.batch_size].push_back(i);
  auto step = [&](int64_t k) {
    internal::TrainStep(*network, optimizer, f, batches[k % 2], use, model_config, train_config,
                        seed, k, fill);
  };
  for (int64_t k = 0; k < warmup; ++k) step(k);
  const auto start = std::chrono::steady_clock::now();
  for (int64_t k = 0; k < steps; ++k) step(warmup + k);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  ThroughputResult r;
  for (const auto& p : network->parameters()) r.parameters += p.numel();
  r.seconds_per_step = seconds / static_cast<double>(steps);
  r.samples_per_s = static_cast<double>(steps * train_config.batch_size) / seconds;
  return r;
}

}  // namespace sonicboom::learning
