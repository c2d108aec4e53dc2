#pragma once
/// One optimization step of the localization network: the step learning::Train repeats and
/// learning::MeasureTrainThroughput times.

#include <cstdint>
#include <functional>
#include <vector>

#include <torch/nn.h>
#include <torch/optim.h>

#include "internal/network.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning::internal {

/// The two parts of the training loss of one batch.
struct LossTerms {
  torch::Tensor point;  // the paper's weighted MSE
  torch::Tensor nll;    // mean NLL of the predictive distribution; undefined without the head
};

/// Weighted MSE of the (B, 3) point outputs against (B, 3) targets: z_cm, cos, sin. With the
/// uncertainty head (B, 5 outputs), also the mean negative log-likelihood of the targets under
/// z ~ Normal(mean, sigma^2) (cm) and theta ~ VonMises(mean direction, kappa), with the means
/// detached: only the uncertainty outputs learn from it.
LossTerms Loss(const torch::Tensor& out, const torch::Tensor& target, const TrainConfig& c);

/// Prepares this process for training steps: torch's intra-op threads (train_config.threads,
/// or every core when it is 0), and, with glibc, a malloc that keeps freed memory. By default
/// glibc maps blocks above its dynamic threshold (at most 32 MiB) fresh, and returns the heap's
/// free top to the system, so each step's large buffers (the GCC encoder's 54 MB weight
/// gradient and Adam's temporaries among them) are page-faulted and zeroed again. Here blocks
/// up to 256 MiB come from the heap and the heap is trimmed only above 1 GiB free; resident
/// memory stays near its peak. Measured with bench/torch_throughput.py (docs/learning.md).
/// Process-wide and idempotent.
void PrepareTrainingProcess(const TrainConfig& train_config);

/// Loss values of one step (nll is 0 without the uncertainty head).
struct StepLoss {
  double point{0.0};
  double nll{0.0};
};

/// Assembles `records` of `train` (with the augmentation drawn from (seed, epoch, record) when
/// train_config.augment), runs forward, loss, backward and one optimizer step. `fill` is the
/// per-mic mel fill value (NetworkImpl::MelMean). The network must be in train mode.
/// `after_backward`, when given, runs between the backward pass and the optimizer step with this
/// step's loss (data parallel: it sums gradients and losses over the processes).
StepLoss TrainStep(NetworkImpl& network, torch::optim::Optimizer& optimizer,
                   const FeatureSet& train, const std::vector<int64_t>& records,
                   const ModalitySet& use, const ModelConfig& model_config,
                   const TrainConfig& train_config, uint64_t seed, int64_t epoch,
                   const std::vector<float>& fill,
                   const std::function<void(StepLoss*)>* after_backward = nullptr);

}  // namespace sonicboom::learning::internal
