// The training step: batch assembly with augmentation, forward, loss, backward, optimizer step.
#include "internal/train_step.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <thread>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <torch/special.h>

#include "internal/data.h"

namespace sonicboom::learning::internal {

LossTerms Loss(const torch::Tensor& out, const torch::Tensor& target, const TrainConfig& c) {
  auto mse = [&](int64_t k) { return torch::mse_loss(out.select(1, k), target.select(1, k)); };
  LossTerms terms;
  terms.point = c.loss_weight_z * mse(0) + c.loss_weight_cos * mse(1) + c.loss_weight_sin * mse(2);
  if (out.size(1) < 5) return terms;
  const double log_two_pi = std::log(2.0 * std::numbers::pi);
  // Gaussian: log sigma + dz^2 / (2 sigma^2) + log(2 pi) / 2, sigma = exp(log sigma)
  const torch::Tensor log_std = out.select(1, 3);
  const torch::Tensor dz = target.select(1, 0) - out.select(1, 0).detach();
  const torch::Tensor nll_z =
      log_std + 0.5 * dz.square() * torch::exp(-2.0 * log_std) + 0.5 * log_two_pi;
  // von Mises: kappa (1 - cos d) + log(2 pi I0(kappa)), with 1 - cos d = |u_true - u_mean|^2 / 2
  // for the unit vectors, and log I0(kappa) = log(i0e(kappa)) + kappa
  const torch::Tensor direction = out.slice(1, 1, 3).detach();
  const torch::Tensor unit = direction / direction.norm(2, 1, true).clamp_min(1e-6);
  const torch::Tensor one_minus_cos = 0.5 * (target.slice(1, 1, 3) - unit).square().sum(1);
  const torch::Tensor kappa = torch::exp(out.select(1, 4));
  const torch::Tensor nll_theta =
      kappa * one_minus_cos + log_two_pi + torch::log(torch::special::i0e(kappa));
  terms.nll = (nll_z + nll_theta).mean();
  return terms;
}

void PrepareTrainingProcess(const TrainConfig& train_config) {
  const int64_t threads = train_config.threads > 0
                              ? train_config.threads
                              : std::max<int64_t>(1, std::thread::hardware_concurrency());
  torch::set_num_threads(static_cast<int>(threads));
#ifdef __GLIBC__
  // mallopt returns 0 where this glibc refuses a value (older ones cap the mmap threshold at
  // 32 MiB): then fall back to that cap
  if (mallopt(M_MMAP_THRESHOLD, 256 << 20) == 0) mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

StepLoss TrainStep(NetworkImpl& network, torch::optim::Optimizer& optimizer,
                   const FeatureSet& train, const std::vector<int64_t>& records,
                   const ModalitySet& use, const ModelConfig& model_config,
                   const TrainConfig& train_config, uint64_t seed, int64_t epoch,
                   const std::vector<float>& fill,
                   const std::function<void(StepLoss*)>* after_backward) {
  // augmentation of each record, drawn from (seed, epoch, record)
  std::vector<Augmentation> augment;
  if (train_config.augment) {
    for (int64_t r : records) {
      augment.push_back(
          DrawAugmentation(train_config, model_config.crop_frames, train.mels, seed, epoch, r));
    }
  }
  const Batch batch = AssembleBatch(train, records, use, model_config.crop_frames,
                                    train_config.augment ? &augment : nullptr, fill);
  // (B, 3) targets; (B, 3) or (B, 5) outputs
  const torch::Tensor target =
      AssembleTargets(train, records, train_config.augment ? &augment : nullptr);
  const LossTerms terms = Loss(network.forward(batch), target, train_config);
  const torch::Tensor loss =
      terms.nll.defined() ? terms.point + train_config.uncertainty_weight * terms.nll : terms.point;
  optimizer.zero_grad();
  loss.backward();
  StepLoss step{terms.point.item<double>(), terms.nll.defined() ? terms.nll.item<double>() : 0.0};
  if (after_backward != nullptr && *after_backward) (*after_backward)(&step);
  optimizer.step();
  return step;
}

}  // namespace sonicboom::learning::internal
