#pragma once
/// Training and inference speed of the localization network on synthetic inputs of the paper's
/// shapes: the same training step as learning::Train (batch assembly with augmentation, forward,
/// loss, backward, Adam), timed after a warm-up.

#include <cstdint>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

struct ThroughputResult {
  int64_t parameters{0};         // trainable parameters of the network
  double samples_per_s{0.0};     // training samples per second (timed steps only)
  double seconds_per_step{0.0};  // one batch, s
};

/// Times `steps` training steps of batch `train_config.batch_size` after `warmup` untimed ones,
/// with `train_config.threads` intra-op threads, on random features shaped like `shapes`
/// (shape fields only are read). Deterministic in `seed` except for the timing.
ThroughputResult MeasureTrainThroughput(const ModelConfig& model_config,
                                        const TrainConfig& train_config, const FeatureSet& shapes,
                                        int64_t steps, int64_t warmup, uint64_t seed);

}  // namespace sonicboom::learning
