// Cost of one strike's features on one thread: the spectral gate, the mel spectrograms, GCC-PHAT
// and the whole extractor (onset, window, gate, mel, GCC), on a 6-channel 1.5 s window at 44.1 kHz.
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <cmath>
#include <random>

#include "sonicboom/dsp/features.h"
#include "sonicboom/dsp/spectral_gate.h"

namespace sonicboom {
namespace {

constexpr double kRateHz = 44100.0;
constexpr int kChannels = 6;

// (kChannels x n) white noise of standard deviation `level`, plus a decaying 2 kHz burst at
// `onset` when burst_amplitude > 0
Eigen::MatrixXf Signal(int64_t n, double level, int64_t onset, double burst_amplitude,
                       uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(level));
  Eigen::MatrixXf x(kChannels, n);
  for (int64_t t = 0; t < n; ++t) {
    const double dt = static_cast<double>(t - onset) / kRateHz;
    const double burst =
        t >= onset ? burst_amplitude * std::exp(-dt / 0.05) * std::sin(2.0 * M_PI * 2000.0 * dt)
                   : 0.0;
    for (int c = 0; c < kChannels; ++c) x(c, t) = noise(rng) + static_cast<float>(burst);
  }
  return x;
}

// spectral gate: all six channels of one window (default keys: STFT 1024 / 256)
void BM_SpectralGate(benchmark::State& state) {
  const dsp::FeatureConfig features;
  const int64_t n = std::llround(features.window_s * kRateHz);
  const dsp::SpectralGate gate(dsp::GatingConfig(features), Signal(22050, 0.01, 0, 0.0, 1),
                               kRateHz);
  const Eigen::MatrixXf x = Signal(n, 0.01, n / 2, 0.5, 2);
  Eigen::VectorXf row(n), out(n);
  for (auto _ : state) {
    for (int c = 0; c < kChannels; ++c) {
      row = x.row(c).transpose();
      gate.Apply(row.data(), n, c, out.data());
      benchmark::DoNotOptimize(out.data());
    }
  }
}
BENCHMARK(BM_SpectralGate)->Unit(benchmark::kMillisecond);

// mel spectrograms: all six channels of one window (n_fft 512, hop 128, 50 bands)
void BM_MelSpectrogram(benchmark::State& state) {
  const dsp::FeatureConfig f;
  const int64_t n = std::llround(f.window_s * kRateHz);
  const dsp::MelSpectrogram mel(f.n_fft, f.hop, f.n_mels, f.f_min_hz, kRateHz / 2.0, kRateHz);
  const Eigen::MatrixXf x = Signal(n, 0.01, n / 2, 0.5, 3);
  Eigen::VectorXf row(n);
  Eigen::MatrixXf out;
  for (auto _ : state) {
    for (int c = 0; c < kChannels; ++c) {
      row = x.row(c).transpose();
      mel.Compute(row.data(), n, &out);
      benchmark::DoNotOptimize(out.data());
    }
  }
}
BENCHMARK(BM_MelSpectrogram)->Unit(benchmark::kMillisecond);

// GCC-PHAT: the 15 pairs of one window, +-441 lags
void BM_GccPhat(benchmark::State& state) {
  const dsp::FeatureConfig f;
  const int64_t n = std::llround(f.window_s * kRateHz);
  const dsp::GccPhat gcc(n, f.gcc_max_lag, kChannels);
  const Eigen::MatrixXf x = Signal(n, 0.01, n / 2, 0.5, 4);
  Eigen::MatrixXf out;
  for (auto _ : state) {
    gcc.Compute(x, &out);
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_GccPhat)->Unit(benchmark::kMillisecond);

// the whole extractor on a 2 s record; arg 1: gated against a 0.5 s noise clip, 0: no gate
void BM_FeatureExtractor(benchmark::State& state) {
  dsp::FeatureConfig f;
  f.gating = state.range(0) != 0;
  const Eigen::MatrixXf noise = Signal(22050, 0.01, 0, 0.0, 5);
  const dsp::FeatureExtractor extractor(f, kRateHz, kChannels, &noise);
  const Eigen::MatrixXf record = Signal(88200, 0.01, 30000, 0.5, 6);
  for (auto _ : state) benchmark::DoNotOptimize(extractor.Compute(record));
}
BENCHMARK(BM_FeatureExtractor)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sonicboom
