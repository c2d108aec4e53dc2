// Cost of one simulated strike: kinematic strike generation and 6-channel audio rendering.
#include <benchmark/benchmark.h>

#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom {
namespace {

// strike kinematics + proprioception window
void BM_StrikeKinematics(benchmark::State& state) {
  const sim::StrikeModel model(sim::StrikeConfig{}, sim::SceneConfig{}, TubeConfig{},
                               AudioConfig{});
  uint64_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(model.Generate(SampleSeed(1, i++)));
}
BENCHMARK(BM_StrikeKinematics)->Unit(benchmark::kMicrosecond);

// 2 s, 6-channel record at 44.1 kHz; arg = mode band in Hz (0 = derived from the contact)
void BM_RenderStrike(benchmark::State& state) {
  acoustics::AcousticModelConfig config;
  config.synth.model = acoustics::VibrationModel::kModalClosedForm;
  config.synth.max_frequency_hz = static_cast<double>(state.range(0));
  const acoustics::StrikeSynthesizer synthesizer(config);
  const sim::StrikeModel model(sim::StrikeConfig{}, sim::SceneConfig{}, TubeConfig{},
                               AudioConfig{});
  uint64_t i = 0;
  int64_t modes = 0;
  for (auto _ : state) {
    const sim::StrikeEvents ev = model.Generate(SampleSeed(1, i));
    const auto r = synthesizer.Render(ev.contact, ev.joint_speed_rad_s, ev.joint_speed_rate_hz,
                                      SampleSeed(1, i));
    modes = r.modes_used;
    ++i;
  }
  state.counters["modes"] = static_cast<double>(modes);
  state.counters["strikes_per_s"] =
      benchmark::Counter(static_cast<double>(i), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RenderStrike)->Arg(0)->Arg(5000)->Arg(20000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sonicboom
