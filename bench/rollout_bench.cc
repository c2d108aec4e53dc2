// Dynamic strike rollouts in MuJoCo (sim/rollout.h): full rollouts of the reference strike on
// one thread, reported as simulated seconds per wall second and MuJoCo steps per second.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdint>

#include "sonicboom/core/rng.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::sim {
namespace {

void BM_ReferenceStrikeRollout(benchmark::State& state) {
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{},
                              RolloutConfig{});
  uint64_t index = 0;
  double simulated_s = 0.0, wall_s = 0.0;
  int64_t steps = 0, valid = 0, rollouts = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const RolloutResult result = rollout.Run(index, SampleSeed(1, index));
    ++index;
    wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    benchmark::DoNotOptimize(result.contacts.data());
    simulated_s += result.simulated_s;
    steps += result.steps;
    valid += result.valid ? 1 : 0;
    ++rollouts;
  }
  state.counters["sim_s_per_wall_s"] = simulated_s / wall_s;
  state.counters["steps_per_s"] = static_cast<double>(steps) / wall_s;
  state.counters["sim_s_per_rollout"] = simulated_s / static_cast<double>(rollouts);
  state.counters["valid_fraction"] = static_cast<double>(valid) / static_cast<double>(rollouts);
}
BENCHMARK(BM_ReferenceStrikeRollout)->Unit(benchmark::kMillisecond)->MinTime(3.0);

}  // namespace
}  // namespace sonicboom::sim
