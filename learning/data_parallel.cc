// Data-parallel training's collectives: c10d's Gloo process group over a TCP rendezvous.
#include "internal/data_parallel.h"

#include <fmt/format.h>

#include <charconv>
#include <chrono>
#include <cstdlib>
#include <string>

#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/TCPStore.hpp>

#include "sonicboom/core/errors.h"

namespace sonicboom::learning {
namespace {

// An integer launcher variable in [lo, hi], or `fallback` when unset.
int IntegerVariable(const char* name, int fallback, int lo, int hi) {
  const char* text = std::getenv(name);
  if (text == nullptr || *text == '\0') return fallback;
  int value = 0;
  const char* end = text + std::char_traits<char>::length(text);
  const auto [ptr, ec] = std::from_chars(text, end, value);
  if (ec != std::errc() || ptr != end || value < lo || value > hi) {
    throw ConfigError(fmt::format("{}='{}' must be an integer in [{}, {}]", name, text, lo, hi));
  }
  return value;
}

}  // namespace

DataParallel DataParallel::FromEnvironment() {
  DataParallel p;
  p.world_size = IntegerVariable("WORLD_SIZE", 1, 1, 1 << 16);
  p.rank = IntegerVariable("RANK", 0, 0, p.world_size - 1);
  if (const char* addr = std::getenv("MASTER_ADDR"); addr != nullptr && *addr != '\0') {
    p.master_addr = addr;
  }
  p.master_port = IntegerVariable("MASTER_PORT", p.master_port, 1, 65535);
  return p;
}

namespace internal {

struct ProcessGroup::Impl {
  c10::intrusive_ptr<c10d::Store> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  int world_size{1};
};

ProcessGroup::ProcessGroup(const DataParallel& parallel) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.world_size = parallel.world_size;
  const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(1e3 * parallel.timeout_s));
  try {
    c10d::TCPStoreOptions options;
    options.port = static_cast<std::uint16_t>(parallel.master_port);
    options.isServer = parallel.rank == 0;
    options.numWorkers = static_cast<std::size_t>(parallel.world_size);
    options.timeout = timeout;
    m.store = c10::make_intrusive<c10d::TCPStore>(parallel.master_addr, options);
    auto gloo = c10d::ProcessGroupGloo::Options::create();
    gloo->timeout = timeout;
    // this host's interface: the one its hostname resolves to, or loopback on one machine
    const bool local = parallel.master_addr == "127.0.0.1" || parallel.master_addr == "localhost";
    gloo->devices.push_back(local ? c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1")
                                  : c10d::ProcessGroupGloo::createDefaultDevice());
    m.group = c10::make_intrusive<c10d::ProcessGroupGloo>(m.store, parallel.rank,
                                                          parallel.world_size, gloo);
  } catch (const std::exception& e) {
    throw IoError(fmt::format("data-parallel rendezvous at {}:{} (rank {} of {}) failed: {}",
                              parallel.master_addr, parallel.master_port, parallel.rank,
                              parallel.world_size, e.what()));
  }
}

ProcessGroup::~ProcessGroup() = default;

void ProcessGroup::Broadcast(const std::vector<torch::Tensor>& tensors) {
  torch::NoGradGuard no_grad;
  for (const torch::Tensor& t : tensors) {
    std::vector<at::Tensor> one{t.data()};
    impl_->group->broadcast(one)->wait();
  }
}

void ProcessGroup::SumGradients(const std::vector<torch::Tensor>& parameters, double weight,
                                std::vector<double>* scalars) {
  torch::NoGradGuard no_grad;
  // one flat tensor: every gradient (zeros where undefined), then the scalars
  std::vector<torch::Tensor> parts;
  for (const torch::Tensor& p : parameters) {
    parts.push_back(p.grad().defined() ? p.grad().reshape({-1}) * weight
                                       : torch::zeros({p.numel()}, p.options()));
  }
  parts.push_back(torch::tensor(*scalars, torch::kFloat64).to(torch::kFloat32));
  std::vector<at::Tensor> flat{torch::cat(parts)};
  impl_->group->allreduce(flat)->wait();
  // back into the gradients
  int64_t at = 0;
  for (const torch::Tensor& p : parameters) {
    const torch::Tensor summed = flat[0].slice(0, at, at + p.numel()).view(p.sizes());
    if (p.grad().defined()) {
      p.mutable_grad().copy_(summed);
    } else {
      p.mutable_grad() = summed.clone();
    }
    at += p.numel();
  }
  for (size_t k = 0; k < scalars->size(); ++k) {
    (*scalars)[k] = flat[0][at + static_cast<int64_t>(k)].item<double>();
  }
}

void ProcessGroup::AverageBuffers(const std::vector<torch::Tensor>& buffers) {
  torch::NoGradGuard no_grad;
  for (const torch::Tensor& b : buffers) {
    if (!b.is_floating_point()) continue;
    std::vector<at::Tensor> one{b.data()};
    impl_->group->allreduce(one)->wait();
    b.data().div_(static_cast<double>(impl_->world_size));
  }
}

}  // namespace internal
}  // namespace sonicboom::learning
