#pragma once
/// The collectives of data-parallel training over c10d's Gloo backend (learning::DataParallel):
/// a process group joined once, then gradient sums, scalar sums and buffer averages.

#include <memory>
#include <vector>

#include <torch/torch.h>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning::internal {

class ProcessGroup {
 public:
  /// Joins the group (rank 0 hosts the rendezvous store). Throws IoError naming the address
  /// when the rendezvous fails within the timeout.
  explicit ProcessGroup(const DataParallel& parallel);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;

  /// Rank 0's values of `tensors` on every rank (in place).
  void Broadcast(const std::vector<torch::Tensor>& tensors);
  /// Every parameter's gradient becomes sum over ranks of (weight_r x gradient_r); an undefined
  /// gradient counts as zeros (and is defined after). Also sums `scalars` (in place).
  void SumGradients(const std::vector<torch::Tensor>& parameters, double weight,
                    std::vector<double>* scalars);
  /// Floating-point buffers (BatchNorm running statistics) averaged over the ranks.
  void AverageBuffers(const std::vector<torch::Tensor>& buffers);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::learning::internal
