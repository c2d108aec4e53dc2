#include "sonicboom/core/constants.h"
#include "sonicboom/dsp/spectral_gate.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <time.h>
#include "common/test_util.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <complex>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"

namespace sonicboom::dsp {
namespace {

using testing::ThrownMessage;

using ::testing::HasSubstr;

constexpr double kFs = 44100.0;
using sonicboom::kPi;

// Goldens from scripts/make_goldens.py (features.json manifest + raw float32 LE, C order).
nlohmann::json Manifest() {
  std::ifstream in(std::string(SONICBOOM_SOURCE_DIR) + "/tests/data/goldens/features.json");
  if (!in) throw std::runtime_error("missing tests/data/goldens/features.json");
  return nlohmann::json::parse(in);
}

// Array `name` as a (rows x cols) matrix (a C-order 2-D golden).
Eigen::MatrixXf LoadGolden(const nlohmann::json& manifest, const std::string& name) {
  static_assert(std::endian::native == std::endian::little, "goldens are little-endian");
  const auto& entry = manifest.at("arrays").at(name);
  const auto shape = entry.at("shape").get<std::vector<int64_t>>();
  if (shape.size() != 2) throw std::runtime_error(name + " is not 2-D");
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> m(shape[0], shape[1]);
  std::ifstream in(std::string(SONICBOOM_SOURCE_DIR) + "/tests/data/goldens/" +
                       entry.at("file").get<std::string>(),
                   std::ios::binary);
  const std::streamsize bytes = static_cast<std::streamsize>(m.size() * sizeof(float));
  in.read(reinterpret_cast<char*>(m.data()), bytes);
  if (in.gcount() != bytes) throw std::runtime_error("short golden file for " + name);
  return m;
}

// (channels x n) white Gaussian noise, standard deviation sigma per channel.
Eigen::MatrixXf WhiteNoise(int channels, int64_t n, const std::vector<double>& sigma,
                           uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXf x(channels, n);
  for (int64_t t = 0; t < n; ++t) {
    for (int c = 0; c < channels; ++c) x(c, t) = static_cast<float>(sigma[c] * normal(rng));
  }
  return x;
}

// A decaying sinusoid starting at sample `onset`: amplitude * exp(-t / tau) sin(2 pi f t).
std::vector<double> Burst(int64_t n, int64_t onset, double amplitude, double f_hz, double tau_s) {
  std::vector<double> b(static_cast<size_t>(n), 0.0);
  for (int64_t t = onset; t < n; ++t) {
    const double s = (t - onset) / kFs;
    b[t] = amplitude * std::exp(-s / tau_s) * std::sin(2 * kPi * f_hz * s);
  }
  return b;
}

double Energy(const float* x, int64_t n) {
  double e = 0.0;
  for (int64_t i = 0; i < n; ++i) e += static_cast<double>(x[i]) * x[i];
  return e;
}

double Db(double ratio) {
  return 10.0 * std::log10(ratio);
}

// A measured value for RecordProperty, in scientific notation.
std::string Sci(double v) {
  std::ostringstream out;
  out << std::scientific << std::setprecision(3) << v;
  return out.str();
}

// Gated copy of row `channel` of x.
std::vector<float> GateRow(const SpectralGate& gate, const Eigen::MatrixXf& x, int channel) {
  const Eigen::VectorXf row = x.row(channel).transpose();
  std::vector<float> out(static_cast<size_t>(row.size()));
  gate.Apply(row.data(), row.size(), channel, out.data());
  return out;
}

// ---------------------------------------------------------------------------------------------
// Parameters and round trip

TEST(SpectralGateTest, KernelSpansFiveBinsAndEightFramesAt44k) {
  const SpectralGate gate(SpectralGateConfig{}, Eigen::MatrixXf::Zero(6, 4096), kFs);
  EXPECT_EQ(gate.channels(), 6);
  EXPECT_EQ(gate.freq_smooth_bins(), 5);    // floor(500 / (44100 / 512)) = floor(5.80)
  EXPECT_EQ(gate.time_smooth_frames(), 8);  // floor(50 ms / 5.805 ms) = floor(8.61)
  EXPECT_EQ(gate.frames(66150), 259);
  EXPECT_EQ(gate.threshold_db().rows(), 6);
  EXPECT_EQ(gate.threshold_db().cols(), 513);
  // a silent reference: every bin at the amin floor, -400 dB, with no spread
  EXPECT_NEAR(gate.threshold_db().maxCoeff(), -400.0, 1e-9);
  EXPECT_NEAR(gate.threshold_db().minCoeff(), -400.0, 1e-9);
}

// A silent reference clip calls nothing noise: every bin of a non-silent signal passes, the
// mask is ones everywhere (borders included), and the inverse STFT gives the input back.
TEST(SpectralGateTest, SilentReferencePassesEverythingAndReproducesInput) {
  const SpectralGate gate(SpectralGateConfig{}, Eigen::MatrixXf::Zero(2, 44100), kFs);
  for (const int64_t n : {int64_t{66150}, int64_t{1000}, int64_t{12345}}) {
    Eigen::MatrixXf x = WhiteNoise(2, n, {1e-3, 3e-5}, 11);
    const std::vector<double> burst = Burst(n, n / 3, 0.3, 1250.0, 0.02);
    for (int64_t t = 0; t < n; ++t) x(0, t) += static_cast<float>(burst[t]);
    for (int c = 0; c < 2; ++c) {
      const std::vector<float> y = GateRow(gate, x, c);
      double max_err = 0.0, max_in = 0.0;
      for (int64_t t = 0; t < n; ++t) {
        max_err = std::max(max_err, std::abs(static_cast<double>(y[t]) - x(c, t)));
        max_in = std::max(max_in, std::abs(static_cast<double>(x(c, t))));
      }
      RecordProperty("round_trip_rel_err_n" + std::to_string(n) + "_ch" + std::to_string(c),
                     Sci(max_err / max_in));
      EXPECT_LT(max_err / max_in, 1e-5) << "n " << n << " channel " << c;
    }
  }
}

// prop_decrease 0 turns the gate off (mask = 1 - 0) whatever the reference says.
TEST(SpectralGateTest, PropDecreaseZeroIsIdentity) {
  SpectralGateConfig config;
  config.prop_decrease = 0.0;
  const SpectralGate gate(config, WhiteNoise(1, 44100, {1e-2}, 3), kFs);
  const Eigen::MatrixXf x = WhiteNoise(1, 30000, {1e-3}, 4);  // 20 dB below the reference
  const std::vector<float> y = GateRow(gate, x, 0);
  double max_err = 0.0;
  for (int64_t t = 0; t < x.cols(); ++t)
    max_err = std::max(max_err, std::abs(double(y[t]) - x(0, t)));
  EXPECT_LT(max_err / x.cwiseAbs().maxCoeff(), 1e-5);
}

TEST(SpectralGateTest, MatchesNumpyGolden) {
  const nlohmann::json manifest = Manifest();
  const auto& p = manifest.at("gate");
  SpectralGateConfig config;
  config.n_fft = p.at("n_fft");
  config.hop = p.at("hop");
  config.n_std = p.at("n_std");
  config.freq_smooth_hz = p.at("freq_smooth_hz");
  config.time_smooth_s = p.at("time_smooth_s");
  config.prop_decrease = p.at("prop_decrease");
  config.top_db = p.at("top_db");
  const Eigen::MatrixXf noise = LoadGolden(manifest, "gate_noise");
  const Eigen::MatrixXf input = LoadGolden(manifest, "gate_input");
  const Eigen::MatrixXf threshold = LoadGolden(manifest, "gate_threshold_db");
  const Eigen::MatrixXf expected = LoadGolden(manifest, "gate_output");
  const SpectralGate gate(config, noise, manifest.at("sample_rate_hz").get<double>());
  EXPECT_EQ(gate.freq_smooth_bins(), p.at("freq_smooth_bins").get<int64_t>());
  EXPECT_EQ(gate.time_smooth_frames(), p.at("time_smooth_frames").get<int64_t>());

  // thresholds: float32-stored dB values (|dB| < 100, so ~1e-5 dB storage rounding)
  const double threshold_err =
      (gate.threshold_db() - threshold.cast<double>()).cwiseAbs().maxCoeff();
  RecordProperty("threshold_err_db", Sci(threshold_err));
  EXPECT_LT(threshold_err, 1e-3);

  for (int c = 0; c < input.rows(); ++c) {
    const std::vector<float> y = GateRow(gate, input, c);
    double max_err = 0.0, max_ref = 0.0, removed = 0.0;
    for (int64_t t = 0; t < input.cols(); ++t) {
      max_err = std::max(max_err, std::abs(static_cast<double>(y[t]) - expected(c, t)));
      max_ref = std::max(max_ref, std::abs(static_cast<double>(expected(c, t))));
      removed += std::abs(static_cast<double>(input(c, t)) - expected(c, t));
    }
    EXPECT_LT(max_err / max_ref, 1e-4) << "channel " << c;
    EXPECT_GT(removed, 0.0) << "the golden must gate something";
    RecordProperty("golden_rel_err_ch" + std::to_string(c), Sci(max_err / max_ref));
  }
}

// The gate written out directly, in long double: naive DFT of the centred, reflect-padded,
// Hann-windowed frames; a bin passes when its dB (floored top_db below the peak) exceeds the
// gate's threshold; the binary mask convolved with the 2-D triangle, divided by the taps inside
// the spectrogram; masked spectrum -> inverse DFT -> windowed overlap-add / summed squared window.
// `margin_db` gets the smallest distance of a bin's dB from its threshold (decisions closer than
// rounding could go either way).
std::vector<double> DirectGate(const SpectralGate& gate, const std::vector<float>& x, int channel,
                               double* margin_db) {
  const SpectralGateConfig& config = gate.config();
  const int64_t n = static_cast<int64_t>(x.size()), n_fft = config.n_fft, hop = config.hop;
  const int64_t half = n_fft / 2, bins = n_fft / 2 + 1, frames = gate.frames(n);
  const int64_t nf = gate.freq_smooth_bins(), nt = gate.time_smooth_frames();
  using Real = long double;
  const Real two_pi = 2 * std::numbers::pi_v<Real>;
  std::vector<Real> window(static_cast<size_t>(n_fft));
  for (int64_t m = 0; m < n_fft; ++m) window[m] = 0.5L - 0.5L * std::cos(two_pi * m / n_fft);
  auto reflect = [n](int64_t i) {
    if (n == 1) return int64_t{0};
    const int64_t period = 2 * (n - 1);
    int64_t k = i % period;
    if (k < 0) k += period;
    return k < n ? k : period - k;
  };
  // STFT (bins x frames) and its dB
  std::vector<std::vector<std::complex<Real>>> X(frames, std::vector<std::complex<Real>>(bins));
  std::vector<std::vector<double>> db(frames, std::vector<double>(bins));
  double peak_db = -std::numeric_limits<double>::infinity();
  for (int64_t f = 0; f < frames; ++f) {
    for (int64_t k = 0; k < bins; ++k) {
      std::complex<Real> sum = 0;
      for (int64_t m = 0; m < n_fft; ++m) {
        const Real sample = window[m] * x[reflect(f * hop + m - half)];
        sum += sample * std::polar(Real{1}, -two_pi * static_cast<Real>((k * m) % n_fft) / n_fft);
      }
      X[f][k] = sum;
      db[f][k] = 10.0 * std::log10(std::max(static_cast<double>(std::norm(sum)), 1e-40));
      peak_db = std::max(peak_db, db[f][k]);
    }
  }
  // binary mask
  std::vector<std::vector<int>> pass(frames, std::vector<int>(bins));
  *margin_db = std::numeric_limits<double>::infinity();
  for (int64_t f = 0; f < frames; ++f) {
    for (int64_t k = 0; k < bins; ++k) {
      const double value = std::max(db[f][k], peak_db - config.top_db);
      const double threshold = gate.threshold_db()(channel, k);
      pass[f][k] = value > threshold;
      *margin_db = std::min(*margin_db, std::abs(value - threshold));
    }
  }
  // smoothed mask, masked spectrum, inverse DFT, overlap-add
  std::vector<Real> acc(static_cast<size_t>((frames - 1) * hop + n_fft), 0.0L);
  std::vector<Real> window_sum(acc.size(), 0.0L);
  for (int64_t p = 0; p < frames; ++p) {
    std::vector<std::complex<Real>> Y(bins);
    for (int64_t k = 0; k < bins; ++k) {
      Real weighted = 0, taps = 0;  // over the taps inside the spectrogram
      for (int64_t j = std::max(-nt, -p); j <= std::min(nt, frames - 1 - p); ++j) {
        for (int64_t i = std::max(-nf, -k); i <= std::min(nf, bins - 1 - k); ++i) {
          const Real w = static_cast<Real>((nt + 1 - std::abs(j)) * (nf + 1 - std::abs(i)));
          weighted += w * pass[p + j][k + i];
          taps += w;
        }
      }
      const Real mask = config.prop_decrease * (weighted / taps) + (1 - config.prop_decrease);
      Y[k] = X[p][k] * mask;
    }
    for (int64_t m = 0; m < n_fft; ++m) {
      Real y = 0;  // real inverse: DC and Nyquist once (real parts), the others twice
      for (int64_t k = 0; k < bins; ++k) {
        const Real weight = (k == 0 || 2 * k == n_fft) ? 1 : 2;
        const Real angle = two_pi * static_cast<Real>((k * m) % n_fft) / n_fft;
        y += weight * (Y[k].real() * std::cos(angle) - Y[k].imag() * std::sin(angle));
      }
      acc[p * hop + m] += y / n_fft * window[m];
      window_sum[p * hop + m] += window[m] * window[m];
    }
  }
  std::vector<double> out(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    const Real sum = window_sum[i + half];
    out[i] = static_cast<double>(sum > 1e-300L ? acc[i + half] / sum : acc[i + half]);
  }
  return out;
}

// Apply against DirectGate on random signals (noise with random bursts) over kernel sizes, border
// cases (n_f or n_t zero, a signal shorter than a frame, kernels wider than the spectrogram and
// counts past int32), partial masks (prop_decrease < 1) and the top_db floor.
TEST(SpectralGateTest, MatchesDirectTriangleSmoothing) {
  struct Case {
    double freq_smooth_hz, time_smooth_s, prop_decrease, burst;
    int64_t n;
  };
  constexpr double kRate = 8000.0;  // n_fft 64, hop 16: n_f = floor(hz / 250), n_t = floor(s * 500)
  const std::vector<Case> cases = {
      {600.0, 0.007, 1.0, 0.05, 1500},  // n_f 2, n_t 3
      {900.0, 0.011, 0.7, 0.05, 1500},  // n_f 3, n_t 5, partial
      {100.0, 0.007, 1.0, 0.05, 1500},  // n_f 0
      {600.0, 0.001, 0.6, 0.05, 1500},  // n_t 0
      {0.0, 0.0, 1.0, 0.05, 1500},      // no smoothing
      {1100.0, 0.02, 1.0, 0.05, 40},    // shorter than a frame, kernel wider than it
      {4000.0, 6.0, 0.8, 0.05, 600},    // n_f 16, n_t 3000: counts past int32
      {600.0, 0.007, 1.0, 30.0, 1500},  // a loud burst: the top_db floor passes every bin
      {600.0, 0.007, 1.0, 6.5, 1500},   // the floor between thresholds: some bins
  };
  for (const Case& c : cases) {
    SpectralGateConfig config;
    config.n_fft = 64;
    config.hop = 16;
    config.n_std = 1.0;  // more passing bins, a richer mask
    config.freq_smooth_hz = c.freq_smooth_hz;
    config.time_smooth_s = c.time_smooth_s;
    config.prop_decrease = c.prop_decrease;
    config.top_db = 60.0;
    const SpectralGate gate(config, WhiteNoise(1, 4000, {1e-2}, 71), kRate);
    // a signal whose decisions are all clear of rounding (another draw otherwise)
    bool checked = false;
    for (uint32_t seed = 72; seed < 92 && !checked; ++seed) {
      std::mt19937 rng(seed);
      std::uniform_real_distribution<double> uniform(0.0, 1.0);
      Eigen::MatrixXf noise = WhiteNoise(1, c.n, {1e-2}, seed);
      std::vector<float> x(noise.data(), noise.data() + c.n);
      for (int burst = 0; burst < 4; ++burst) {  // decaying tones at random times and pitches
        const int64_t onset = static_cast<int64_t>(uniform(rng) * static_cast<double>(c.n));
        const double amplitude = c.burst * (0.5 + 0.5 * uniform(rng));
        const double f_hz = 200.0 + 3500.0 * uniform(rng), tau_s = 0.002 + 0.02 * uniform(rng);
        for (int64_t t = onset; t < c.n; ++t) {
          const double s = static_cast<double>(t - onset) / kRate;
          x[t] +=
              static_cast<float>(amplitude * std::exp(-s / tau_s) * std::sin(2 * kPi * f_hz * s));
        }
      }
      double margin_db = 0.0;
      const std::vector<double> expected = DirectGate(gate, x, 0, &margin_db);
      if (margin_db < 1e-6) continue;
      std::vector<float> y(x.size());
      gate.Apply(x.data(), c.n, 0, y.data());
      double max_err = 0.0, max_ref = 0.0, max_in = 0.0;
      for (int64_t t = 0; t < c.n; ++t) {
        max_err = std::max(max_err, std::abs(static_cast<double>(y[t]) - expected[t]));
        max_ref = std::max(max_ref, std::abs(expected[t]));
        max_in = std::max(max_in, std::abs(static_cast<double>(x[t])));
      }
      EXPECT_LT(max_err, 1e-6 * max_in)
          << "n_f " << gate.freq_smooth_bins() << " n_t " << gate.time_smooth_frames() << " prop "
          << c.prop_decrease << " n " << c.n << " burst " << c.burst;
      EXPECT_GT(max_ref, 0.0);
      checked = true;
    }
    EXPECT_TRUE(checked) << "no signal with clear decisions for n_f " << gate.freq_smooth_bins();
  }
}

// ---------------------------------------------------------------------------------------------
// What the gate does to noise and to strikes

// Stationary noise of the reference's statistics (a different draw) almost vanishes: a bin
// passes only when its dB exceeds the noise mean by 2.5 std (~1e-6 of bins for Gaussian noise).
TEST(SpectralGateTest, AttenuatesNoiseLikeTheReferenceByMoreThan20Db) {
  // white (ambient + preamp floor) on 0-2, a 110 Hz harmonic series on top for 3-5
  const int64_t n = 66150;
  auto record = [&](uint32_t seed, int64_t length) {
    Eigen::MatrixXf x = WhiteNoise(6, length, std::vector<double>(6, 3.6e-5), seed);
    std::mt19937 rng(seed + 1000);
    std::uniform_real_distribution<double> phase(0.0, 2 * kPi);
    for (int c = 3; c < 6; ++c) {
      for (int h = 1; h <= 8; ++h) {
        const double ph = phase(rng);
        for (int64_t t = 0; t < length; ++t) {
          x(c, t) += static_cast<float>(3e-4 / h * std::sin(2 * kPi * 110.0 * h * t / kFs + ph));
        }
      }
    }
    return x;
  };
  const SpectralGate gate(SpectralGateConfig{}, record(1, 88200), kFs);
  const Eigen::MatrixXf x = record(2, n);
  for (int c = 0; c < 6; ++c) {
    const std::vector<float> y = GateRow(gate, x, c);
    const Eigen::VectorXf row = x.row(c).transpose();
    const double attenuation = Db(Energy(row.data(), n) / Energy(y.data(), n));
    RecordProperty("attenuation_db_ch" + std::to_string(c), std::to_string(attenuation));
    EXPECT_GT(attenuation, 20.0) << "channel " << c;
  }
}

// A decaying burst starting at the centre of a 1.5 s window of white noise, `snr_db` above it
// (energy over the window): a 1250 Hz sinusoid, or white noise when `broadband`; gated against
// another draw of that noise.
struct BurstResult {
  double snr_db{0.0};            // burst energy over noise energy, measured
  double energy_change_db{0.0};  // gated output energy over clean burst energy
  double error_db{0.0};          // (gated - clean) energy over clean energy
  double pre_onset_db{0.0};      // output over input energy before the burst
  int64_t clean_onset{0};        // DetectOnset (128-sample frames, 10 % of peak)
  int64_t gated_onset{0};
};
BurstResult GateBurst(double tau_s, double snr_db, bool broadband) {
  const int64_t n = 66150, onset = 33075;
  const double sigma = 3.6e-5;
  const SpectralGate gate(SpectralGateConfig{}, WhiteNoise(1, 88200, {sigma}, 21), kFs);
  Eigen::MatrixXf clean = Eigen::MatrixXf::Zero(1, n);
  const Eigen::MatrixXf shape = WhiteNoise(1, n, {1.0}, 23);
  for (int64_t t = onset; t < n; ++t) {
    const double s = (t - onset) / kFs;
    const double carrier = broadband ? shape(0, t) : std::sin(2 * kPi * 1250.0 * s);
    clean(0, t) = static_cast<float>(std::exp(-s / tau_s) * carrier);
  }
  clean *= static_cast<float>(
      std::sqrt(std::pow(10.0, snr_db / 10.0) * sigma * sigma * n / clean.squaredNorm()));
  const Eigen::MatrixXf x = clean + WhiteNoise(1, n, {sigma}, 22);
  const std::vector<float> y = GateRow(gate, x, 0);
  Eigen::MatrixXf gated(1, n);
  for (int64_t t = 0; t < n; ++t) gated(0, t) = y[t];
  BurstResult r;
  r.snr_db = Db(clean.squaredNorm() / (x - clean).squaredNorm());
  r.energy_change_db = Db(gated.squaredNorm() / clean.squaredNorm());
  r.error_db = Db((gated - clean).squaredNorm() / clean.squaredNorm());
  // before the burst, ending one smoothing span (8 hops) and a half frame ahead of it
  const int64_t quiet = onset - 9 * 256 - 512;
  r.pre_onset_db = Db(gated.leftCols(quiet).squaredNorm() / x.leftCols(quiet).squaredNorm());
  r.clean_onset = DetectOnset(clean, kFs, 128 / kFs, 0.1);
  r.gated_onset = DetectOnset(gated, kFs, 128 / kFs, 0.1);
  return r;
}

void RecordBurst(const BurstResult& r) {
  ::testing::Test::RecordProperty("snr_db", std::to_string(r.snr_db));
  ::testing::Test::RecordProperty("energy_change_db", std::to_string(r.energy_change_db));
  ::testing::Test::RecordProperty("error_db", std::to_string(r.error_db));
  ::testing::Test::RecordProperty("pre_onset_db", std::to_string(r.pre_onset_db));
}

// Every case: the noise before the burst is removed and the onset does not move.
void ExpectCleanOnset(const BurstResult& r) {
  EXPECT_LT(r.pre_onset_db, -20.0);
  EXPECT_EQ(r.gated_onset, r.clean_onset);
  EXPECT_LE(std::abs(r.gated_onset - 33075), 128);
}

// A broadband burst 30 dB above the noise keeps its energy within 1 dB (measured -0.7 dB at
// tau 0.1 s) and its onset; the output is closer to the clean burst than the input was.
TEST(SpectralGateTest, KeepsBroadbandBurstEnergyAndOnset) {
  const BurstResult r = GateBurst(0.1, 30.0, true);
  RecordBurst(r);
  EXPECT_NEAR(r.snr_db, 30.0, 0.5);
  EXPECT_NEAR(r.energy_change_db, 0.0, 1.0);
  EXPECT_LT(r.error_db, -10.0);
  ExpectCleanOnset(r);
}

// A ringing tone 60 dB above the noise (energy): its spectrogram peak is about 95 dB above the
// noise bins, so the top_db floor (peak - 80 dB) lies above every bin's threshold and every bin
// passes, the noise before the burst included. The gate is then a no-op, as noisereduce's is
// (librosa amplitude_to_db with top_db 80 on the signal's spectrogram).
TEST(SpectralGateTest, LoudBurstPassesEverythingThroughTheTopDbFloor) {
  const BurstResult r = GateBurst(0.3, 60.0, false);
  RecordBurst(r);
  EXPECT_NEAR(r.energy_change_db, 0.0, 0.01);
  EXPECT_LT(r.error_db, -50.0);
  EXPECT_NEAR(r.pre_onset_db, 0.0, 0.1);
  EXPECT_EQ(r.gated_onset, r.clean_onset);
}

// At 30 dB above the noise a tone loses energy to the mask smoothing, as in noisereduce:
// a near bin-centred tone passes only about 5 bins (the Hann main lobe), and the +-5-bin
// triangle over frequency averages them with gated bins, a mask of about 0.67 at the tone
// (measured -4.1 dB at tau 0.3 s). A short one (tau 30 ms, energy in its first frames) also
// loses its attack to the +-8-frame smoothing over time, which averages the onset frames with
// the gated frames before them (measured -2.3 dB). The onset stays put in both.
TEST(SpectralGateTest, ToneThirtyDbAboveNoiseLosesTheSmoothingShare) {
  const BurstResult ringing = GateBurst(0.3, 30.0, false);
  RecordBurst(ringing);
  EXPECT_LT(ringing.energy_change_db, -3.0);
  EXPECT_GT(ringing.energy_change_db, -5.0);
  ExpectCleanOnset(ringing);
  const BurstResult short_burst = GateBurst(0.03, 30.0, false);
  ::testing::Test::RecordProperty("short_energy_change_db",
                                  std::to_string(short_burst.energy_change_db));
  EXPECT_LT(short_burst.energy_change_db, -1.0);
  EXPECT_GT(short_burst.energy_change_db, -3.5);
  ExpectCleanOnset(short_burst);
}

// Each channel is gated against its own row of the reference: the same signal passes on the
// quiet channel and is removed on the loud one.
TEST(SpectralGateTest, StatisticsArePerChannel) {
  const SpectralGate gate(SpectralGateConfig{}, WhiteNoise(2, 44100, {1e-4, 1e-2}, 31), kFs);
  EXPECT_GT(gate.threshold_db().row(1).mean(), gate.threshold_db().row(0).mean() + 35.0);
  const Eigen::MatrixXf x = WhiteNoise(2, 30000, {3.16e-3, 3.16e-3}, 32);
  const std::vector<float> quiet = GateRow(gate, x, 0);
  const std::vector<float> loud = GateRow(gate, x, 1);
  const Eigen::VectorXf row0 = x.row(0).transpose(), row1 = x.row(1).transpose();
  // 30 dB above channel 0's noise: within 1 dB (measured -0.1; at 20 dB above, 13 % of the
  // bins fall under the threshold and the smoothed mask costs 1.2 dB); 10 dB below channel 1's
  // noise: gone
  const double quiet_db = Db(Energy(quiet.data(), 30000) / Energy(row0.data(), 30000));
  const double loud_db = Db(Energy(loud.data(), 30000) / Energy(row1.data(), 30000));
  RecordProperty("quiet_channel_db", std::to_string(quiet_db));
  RecordProperty("loud_channel_db", std::to_string(loud_db));
  EXPECT_NEAR(quiet_db, 0.0, 1.0);
  EXPECT_LT(loud_db, -30.0);
}

TEST(SpectralGateTest, InPlaceAndConcurrentCallsMatchSerial) {
  const SpectralGate gate(SpectralGateConfig{},
                          WhiteNoise(6, 44100, std::vector<double>(6, 1e-4), 41), kFs);
  Eigen::MatrixXf x = WhiteNoise(6, 40000, std::vector<double>(6, 1e-4), 42);
  const std::vector<double> burst = Burst(40000, 15000, 0.05, 3000.0, 0.01);
  for (int c = 0; c < 6; ++c) {
    for (int64_t t = 0; t < 40000; ++t) x(c, t) += static_cast<float>(burst[t] * (1 + c));
  }
  std::vector<std::vector<float>> serial;
  for (int c = 0; c < 6; ++c) serial.push_back(GateRow(gate, x, c));
  // in place
  Eigen::VectorXf row = x.row(2).transpose();
  gate.Apply(row.data(), row.size(), 2, row.data());
  for (int64_t t = 0; t < row.size(); ++t) ASSERT_EQ(row[t], serial[2][t]) << "sample " << t;
  // 12 threads over 6 channels (and two signal lengths, so scratch is resized under load)
  std::vector<std::vector<float>> parallel(12);
  std::vector<std::thread> threads;
  for (int i = 0; i < 12; ++i) {
    threads.emplace_back([&, i] {
      const int c = i % 6;
      if (i >= 6) GateRow(gate, x.leftCols(12345), c);
      parallel[i] = GateRow(gate, x, c);
    });
  }
  for (auto& t : threads) t.join();
  for (int i = 0; i < 12; ++i) EXPECT_TRUE(parallel[i] == serial[i % 6]) << "thread " << i;
}

// ---------------------------------------------------------------------------------------------
// Error paths

TEST(SpectralGateTest, RejectsBadReferenceClips) {
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                SpectralGate gate(SpectralGateConfig{}, Eigen::MatrixXf::Zero(6, 1000), kFs);
              }),
              HasSubstr("1000 samples, shorter than one STFT frame (n_fft = 1024)"));
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                SpectralGate gate(SpectralGateConfig{}, Eigen::MatrixXf::Zero(0, 5000), kFs);
              }),
              HasSubstr("no channels"));
  Eigen::MatrixXf nan_clip = Eigen::MatrixXf::Zero(6, 5000);
  nan_clip(4, 1234) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(
      ThrownMessage<ConfigError>([&] { SpectralGate gate(SpectralGateConfig{}, nan_clip, kFs); }),
      HasSubstr("non-finite value (nan) at channel 4 sample 1234"));
  nan_clip(4, 1234) = std::numeric_limits<float>::infinity();
  EXPECT_THAT(
      ThrownMessage<ConfigError>([&] { SpectralGate gate(SpectralGateConfig{}, nan_clip, kFs); }),
      HasSubstr("non-finite"));
}

TEST(SpectralGateTest, RejectsBadParameters) {
  const Eigen::MatrixXf clip = Eigen::MatrixXf::Zero(1, 8192);
  auto message = [&](auto mutate) {
    SpectralGateConfig config;
    mutate(&config);
    return ThrownMessage<ConfigError>([&] { SpectralGate gate(config, clip, kFs); });
  };
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->hop = 600; }),
              HasSubstr("hop must be in [1, n_fft / 2 = 512], got 600"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->hop = 0; }), HasSubstr("hop"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->n_fft = 1; }),
              HasSubstr("n_fft must be >= 2"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->n_std = std::nan(""); }), HasSubstr("n_std"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->prop_decrease = 1.5; }),
              HasSubstr("prop_decrease"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->freq_smooth_hz = -1; }),
              HasSubstr("freq_smooth_hz"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->time_smooth_s = -1; }),
              HasSubstr("time_smooth_s"));
  EXPECT_THAT(message([](SpectralGateConfig* c) { c->top_db = 0; }), HasSubstr("top_db"));
  EXPECT_THAT(
      ThrownMessage<ConfigError>([&] { SpectralGate gate(SpectralGateConfig{}, clip, 0.0); }),
      HasSubstr("sample rate"));
}

TEST(SpectralGateTest, RejectsBadCalls) {
  const SpectralGate gate(SpectralGateConfig{}, Eigen::MatrixXf::Zero(2, 4096), kFs);
  std::vector<float> x(5000, 0.0f), y(5000);
  EXPECT_THAT(ThrownMessage<Error>([&] { gate.Apply(x.data(), 5000, 2, y.data()); }),
              HasSubstr("channel 2 out of range [0, 2)"));
  EXPECT_THAT(ThrownMessage<Error>([&] { gate.Apply(x.data(), 0, 0, y.data()); }),
              HasSubstr("empty"));
  x[77] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(ThrownMessage<Error>([&] { gate.Apply(x.data(), 5000, 1, y.data()); }),
              HasSubstr("non-finite sample (nan) at index 77 of channel 1"));
}

// ---------------------------------------------------------------------------------------------
// In the feature extractor

// Six channels: reference-level noise plus a strike with `strike_gain` (0: noise only), or a
// broadband signal far above the reference noise when `loud` is set.
Eigen::MatrixXf Record(uint32_t seed, double strike_gain, bool loud = false) {
  const int64_t n = 88200, onset = 30000;
  Eigen::MatrixXf x = WhiteNoise(6, n, std::vector<double>(6, loud ? 3e-2 : 3.6e-5), seed);
  const std::vector<double> burst = Burst(n, onset, strike_gain, 2000.0, 0.1);
  for (int c = 0; c < 6; ++c) {
    for (int64_t t = 0; t < n; ++t) x(c, t) += static_cast<float>((1.0 + 0.2 * c) * burst[t]);
  }
  return x;
}

TEST(FeatureExtractorGatingTest, GatesOnlyWithAClipAndTheKeyOn) {
  const Eigen::MatrixXf clip = WhiteNoise(6, 88200, std::vector<double>(6, 3.6e-5), 51);
  FeatureConfig config;
  EXPECT_EQ(FeatureExtractor(config, kFs, 6).gate(), nullptr);
  EXPECT_EQ(FeatureExtractor(config, kFs, 6, nullptr).gate(), nullptr);
  const FeatureExtractor gated(config, kFs, 6, &clip);
  ASSERT_NE(gated.gate(), nullptr);
  EXPECT_EQ(gated.gate()->freq_smooth_bins(), 5);
  config.gating = false;
  EXPECT_EQ(FeatureExtractor(config, kFs, 6, &clip).gate(), nullptr);
}

TEST(FeatureExtractorGatingTest, RemovesNoiseButLeavesLoudRecordsAlone) {
  const Eigen::MatrixXf clip = WhiteNoise(6, 88200, std::vector<double>(6, 3.6e-5), 51);
  const FeatureExtractor plain(FeatureConfig{}, kFs, 6);
  const FeatureExtractor gated(FeatureConfig{}, kFs, 6, &clip);

  // reference-level noise with a strike: the same window (onset unchanged); the mel energy of
  // the frames before the strike (noise only) drops by more than 20 dB on every channel, and
  // the GCC-PHAT changes (the gated noise no longer whitens it)
  {
    const Eigen::MatrixXf x = Record(52, 0.05);
    const StrikeFeatures a = plain.Compute(x);
    const StrikeFeatures b = gated.Compute(x);
    EXPECT_EQ(a.onset_sample, b.onset_sample);
    for (int c = 0; c < 6; ++c) {
      const int64_t quiet_frames = 200;  // window frames before the strike: 258 at 128 hop
      const double before = a.mel[c].leftCols(quiet_frames).cast<double>().sum();
      const double after = b.mel[c].leftCols(quiet_frames).cast<double>().sum();
      EXPECT_LT(Db(after / before), -20.0) << "channel " << c;
      // the strike's frames keep their energy (within 1 dB; it rings for tau = 0.1 s, see
      // ShortBurstLosesPartOfItsAttackButKeepsItsOnset for a short one)
      const double strike_a = a.mel[c].rightCols(517 - 258).cast<double>().sum();
      const double strike_b = b.mel[c].rightCols(517 - 258).cast<double>().sum();
      EXPECT_NEAR(Db(strike_b / strike_a), 0.0, 1.0) << "channel " << c;
    }
    EXPECT_GT((a.gcc - b.gcc).cwiseAbs().maxCoeff(), 0.01f);
  }
  // a broadband record 60 dB above the reference noise: every bin passes, features unchanged
  {
    const Eigen::MatrixXf x = Record(53, 0.5, true);
    const StrikeFeatures a = plain.Compute(x);
    const StrikeFeatures b = gated.Compute(x);
    EXPECT_EQ(a.onset_sample, b.onset_sample);
    for (int c = 0; c < 6; ++c) {
      const double rel =
          (a.mel[c] - b.mel[c]).cwiseAbs().maxCoeff() / a.mel[c].cwiseAbs().maxCoeff();
      EXPECT_LT(rel, 1e-4) << "channel " << c;
    }
    EXPECT_LT((a.gcc - b.gcc).cwiseAbs().maxCoeff(), 1e-3f);
  }
}

TEST(FeatureExtractorGatingTest, RejectsClipsThatDoNotFit) {
  const FeatureConfig config;
  const Eigen::MatrixXf four = Eigen::MatrixXf::Zero(4, 44100);
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { FeatureExtractor fx(config, kFs, 6, &four); }),
              HasSubstr("reference noise clip has 4 channels, the records have 6"));
  const Eigen::MatrixXf short_clip = Eigen::MatrixXf::Zero(6, 512);
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { FeatureExtractor fx(config, kFs, 6, &short_clip); }),
              HasSubstr("features.gating_n_fft = 1024"));
  Eigen::MatrixXf nan_clip = Eigen::MatrixXf::Zero(6, 44100);
  nan_clip(0, 9) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { FeatureExtractor fx(config, kFs, 6, &nan_clip); }),
              HasSubstr("non-finite"));
}

struct BadGatingKey {
  std::string key;
  std::string detail;
  void (*mutate)(FeatureConfig*);
};

class GatingConfigErrorTest : public ::testing::TestWithParam<BadGatingKey> {};

TEST_P(GatingConfigErrorTest, ThrowsConfigErrorNamingKey) {
  FeatureConfig config;
  GetParam().mutate(&config);
  const Eigen::MatrixXf clip = Eigen::MatrixXf::Zero(6, 44100);
  const std::string message =
      ThrownMessage<ConfigError>([&] { FeatureExtractor fx(config, kFs, 6, &clip); });
  EXPECT_THAT(message, HasSubstr(GetParam().key));
  EXPECT_THAT(message, HasSubstr(GetParam().detail));
}

INSTANTIATE_TEST_SUITE_P(
    Keys, GatingConfigErrorTest,
    ::testing::Values(BadGatingKey{"features.gating_hop", "got 600",
                                   [](FeatureConfig* c) { c->gating_hop = 600; }},
                      BadGatingKey{"features.gating_hop", "got 0",
                                   [](FeatureConfig* c) { c->gating_hop = 0; }},
                      BadGatingKey{"features.gating_n_fft", "got 100000",
                                   [](FeatureConfig* c) { c->gating_n_fft = 100000; }},
                      BadGatingKey{"features.gating_n_fft", "got 1",
                                   [](FeatureConfig* c) { c->gating_n_fft = 1; }},
                      BadGatingKey{"features.gating_n_std", "got inf",
                                   [](FeatureConfig* c) {
                                     c->gating_n_std = std::numeric_limits<double>::infinity();
                                   }},
                      BadGatingKey{"features.gating_freq_smooth_hz", "got 30000",
                                   [](FeatureConfig* c) { c->gating_freq_smooth_hz = 30000.0; }},
                      BadGatingKey{"features.gating_time_smooth_s", "got 2",
                                   [](FeatureConfig* c) { c->gating_time_smooth_s = 2.0; }},
                      BadGatingKey{"features.gating_prop_decrease", "got -0.5",
                                   [](FeatureConfig* c) { c->gating_prop_decrease = -0.5; }}));

// ---------------------------------------------------------------------------------------------
// Cost of gating one 1.5 s six-channel window (reported, not asserted)

TEST(SpectralGateTest, TimesOneSixChannelWindow) {
  const SpectralGate gate(SpectralGateConfig{},
                          WhiteNoise(6, 88200, std::vector<double>(6, 3.6e-5), 61), kFs);
  const Eigen::MatrixXf x = Record(62, 0.05).leftCols(66150);
  std::vector<Eigen::VectorXf> rows;
  for (int c = 0; c < 6; ++c) rows.push_back(x.row(c).transpose());
  std::vector<float> out(66150);
  for (int c = 0; c < 6; ++c) gate.Apply(rows[c].data(), 66150, c, out.data());  // warm scratch
  // thread CPU time as well as wall time, the best of 10 batches of 3 windows: on a loaded
  // machine the wall time overstates the cost
  auto cpu_now = [] {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  };
  double ms = 1e300, cpu_ms = 1e300;
  for (int batch = 0; batch < 10; ++batch) {
    const double cpu_start = cpu_now();
    const auto start = std::chrono::steady_clock::now();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 6; ++c) gate.Apply(rows[c].data(), 66150, c, out.data());
    }
    const auto wall = std::chrono::steady_clock::now() - start;
    ms = std::min(ms, std::chrono::duration<double, std::milli>(wall).count() / 3);
    cpu_ms = std::min(cpu_ms, (cpu_now() - cpu_start) / 3);
  }
  RecordProperty("wall_ms_per_six_channel_window", std::to_string(ms));
  RecordProperty("cpu_ms_per_six_channel_window", std::to_string(cpu_ms));
  std::cout << "[ timing ] spectral gate, 6 x 66150 samples: " << cpu_ms << " ms CPU, " << ms
            << " ms wall per window (best of 10)\n";
  EXPECT_GT(ms, 0.0);
}

}  // namespace
}  // namespace sonicboom::dsp
