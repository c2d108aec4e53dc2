// Training throughput of the localization network (learning::MeasureTrainThroughput: the real
// training step of learning::Train) for each audio encoder, batch size and thread count.
// bench/torch_throughput.py compares these figures with the same model in PyTorch.
//
// Extra flags (before Google Benchmark's own): --steps=N timed steps (default 8),
// --warmup=N untimed steps (default 2). Benchmarks are named TrainStep/<encoder>/<batch>/<threads>.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "sonicboom/learning/throughput.h"

namespace sonicboom {
namespace {

int64_t g_steps = 8;
int64_t g_warmup = 2;

void TrainStep(benchmark::State& state, learning::AudioEncoderKind encoder, int64_t batch,
               int64_t threads) {
  learning::ModelConfig model;  // the paper's fusion: width 256, 6 blocks, 8 heads, all modalities
  model.audio_encoder = encoder;
  learning::TrainConfig train;
  train.batch_size = batch;
  train.threads = threads;
  train.uncertainty_weight = 0.0;     // the paper's model and loss, as the PyTorch mirror
  const learning::FeatureSet shapes;  // the paper's feature shapes
  learning::ThroughputResult r;
  for (auto _ : state) {
    r = learning::MeasureTrainThroughput(model, train, shapes, g_steps, g_warmup, 1);
    state.SetIterationTime(r.seconds_per_step * static_cast<double>(g_steps));
  }
  state.counters["samples_per_s"] = r.samples_per_s;
  state.counters["parameters"] = static_cast<double>(r.parameters);
}

// "--name=value" as an integer; removes the flag from argv
bool TakeFlag(const char* name, int* argc, char** argv, int64_t* value) {
  const std::string prefix = std::string("--") + name + "=";
  for (int i = 1; i < *argc; ++i) {
    if (std::strncmp(argv[i], prefix.c_str(), prefix.size()) != 0) continue;
    *value = std::atoll(argv[i] + prefix.size());
    for (int j = i; j + 1 < *argc; ++j) argv[j] = argv[j + 1];
    --*argc;
    return true;
  }
  return false;
}

}  // namespace
}  // namespace sonicboom

int main(int argc, char** argv) {
  using namespace sonicboom;
  TakeFlag("steps", &argc, argv, &g_steps);
  TakeFlag("warmup", &argc, argv, &g_warmup);
  const int64_t hw = std::max<int64_t>(1, std::thread::hardware_concurrency());
  std::vector<int64_t> thread_counts{1, 2};
  if (hw > 2) thread_counts.push_back(hw);
  for (const auto& [encoder, name] : learning::kAudioEncoderKindNames) {
    for (int64_t batch : {16, 32, 64, 128}) {
      for (int64_t threads : thread_counts) {
        benchmark::RegisterBenchmark((std::string("TrainStep/") + std::string(name) + "/" +
                                      std::to_string(batch) + "/" + std::to_string(threads))
                                         .c_str(),
                                     [encoder, batch, threads](benchmark::State& s) {
                                       TrainStep(s, encoder, batch, threads);
                                     })
            ->Iterations(1)
            ->UseManualTime()
            ->Unit(benchmark::kMillisecond);
      }
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
