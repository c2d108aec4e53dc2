#include "sonicboom/dsp/features.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/test_util.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "sonicboom/core/errors.h"

namespace sonicboom::dsp {
namespace {

using testing::ThrownMessage;

using ::testing::HasSubstr;

constexpr double kFs = 44100.0;

// Goldens written by scripts/make_goldens.py: a JSON manifest plus raw float32 LE arrays.
class Goldens {
 public:
  Goldens() {
    std::ifstream in(Dir() + "/features.json");
    if (!in) throw std::runtime_error("missing " + Dir() + "/features.json");
    manifest_ = nlohmann::json::parse(in);
  }
  const nlohmann::json& manifest() const { return manifest_; }

  // Shape of array `name`, e.g. {6, 50, 32}.
  std::vector<int64_t> Shape(const std::string& name) const {
    return manifest_.at("arrays").at(name).at("shape").get<std::vector<int64_t>>();
  }

  // Values of array `name` in C order.
  std::vector<float> Load(const std::string& name) const {
    static_assert(std::endian::native == std::endian::little, "goldens are little-endian");
    const auto& entry = manifest_.at("arrays").at(name);
    int64_t count = 1;
    for (int64_t d : Shape(name)) count *= d;
    std::ifstream in(Dir() + "/" + entry.at("file").get<std::string>(), std::ios::binary);
    std::vector<float> values(static_cast<size_t>(count));
    in.read(reinterpret_cast<char*>(values.data()), count * static_cast<int64_t>(sizeof(float)));
    if (in.gcount() != count * static_cast<int64_t>(sizeof(float))) {
      throw std::runtime_error("short golden file for " + name);
    }
    return values;
  }

 private:
  static std::string Dir() { return std::string(SONICBOOM_SOURCE_DIR) + "/tests/data/goldens"; }
  nlohmann::json manifest_;
};

// Largest |a - b| and largest |b| over a (rows x cols) matrix vs a C-order reference block.
struct Deviation {
  double max_abs{0.0};
  double max_ref{0.0};
  double rel() const { return max_ref > 0.0 ? max_abs / max_ref : max_abs; }
};
Deviation Compare(const Eigen::MatrixXf& actual, const float* reference) {
  Deviation d;
  for (int64_t r = 0; r < actual.rows(); ++r) {
    for (int64_t c = 0; c < actual.cols(); ++c) {
      const double ref = reference[r * actual.cols() + c];
      d.max_abs = std::max(d.max_abs, std::abs(static_cast<double>(actual(r, c)) - ref));
      d.max_ref = std::max(d.max_ref, std::abs(ref));
    }
  }
  return d;
}

// Deterministic white noise (n samples, standard deviation sigma).
std::vector<float> Noise(int64_t n, double sigma, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  std::vector<float> x(static_cast<size_t>(n));
  for (float& v : x) v = static_cast<float>(normal(rng));
  return x;
}

// Column of `gcc` row `pair` with the largest value.
int64_t ArgMax(const Eigen::MatrixXf& gcc, int64_t pair) {
  Eigen::Index col = 0;
  gcc.row(pair).maxCoeff(&col);
  return col;
}

// ---------------------------------------------------------------------------------------------
// Mel spectrogram against torchaudio

TEST(MelSpectrogramTest, MultiChannelMatchesTorchaudio) {
  Goldens goldens;
  const auto in_shape = goldens.Shape("multi_input");  // (6, 4000)
  const auto mel_shape = goldens.Shape("multi_mel");   // (6, 50, 32)
  const std::vector<float> input = goldens.Load("multi_input");
  const std::vector<float> reference = goldens.Load("multi_mel");
  const auto& p = goldens.manifest().at("mel");
  MelSpectrogram mel(p.at("n_fft"), p.at("hop"), p.at("n_mels"), p.at("f_min_hz"), p.at("f_max_hz"),
                     kFs);
  ASSERT_EQ(mel.Frames(in_shape[1]), mel_shape[2]);
  double worst = 0.0;
  for (int64_t c = 0; c < in_shape[0]; ++c) {
    Eigen::MatrixXf out;
    mel.Compute(input.data() + c * in_shape[1], in_shape[1], &out);
    ASSERT_EQ(out.rows(), mel_shape[1]);
    ASSERT_EQ(out.cols(), mel_shape[2]);
    const Deviation d = Compare(out, reference.data() + c * mel_shape[1] * mel_shape[2]);
    EXPECT_LE(d.max_abs, 1e-4 * d.max_ref + 1e-12) << "channel " << c;
    worst = std::max(worst, d.rel());
    std::cout << "multi_mel channel " << c << ": max abs " << d.max_abs << ", rel " << d.rel()
              << "\n";
  }
  RecordProperty("max_rel_error", std::to_string(worst));
}

TEST(MelSpectrogramTest, FullWindowMatchesTorchaudio) {
  Goldens goldens;
  const std::vector<float> input = goldens.Load("long_input");    // (66150,)
  const std::vector<float> reference = goldens.Load("long_mel");  // (50, 517)
  MelSpectrogram mel(512, 128, 50, 0.0, kFs / 2, kFs);
  Eigen::MatrixXf out;
  mel.Compute(input.data(), static_cast<int64_t>(input.size()), &out);
  ASSERT_EQ(out.rows(), 50);
  ASSERT_EQ(out.cols(), 517);
  const Deviation d = Compare(out, reference.data());
  std::cout << "long_mel: max abs " << d.max_abs << ", rel " << d.rel() << "\n";
  EXPECT_LE(d.max_abs, 1e-4 * d.max_ref + 1e-12);
}

TEST(MelSpectrogramTest, BandLimitedMatchesTorchaudio) {
  Goldens goldens;
  const auto& p = goldens.manifest().at("band_mel");
  const std::vector<float> input = goldens.Load("multi_input");
  const std::vector<float> reference = goldens.Load("band_mel");  // (40, 63)
  const int64_t n = goldens.Shape("multi_input")[1];
  MelSpectrogram mel(p.at("n_fft"), p.at("hop"), p.at("n_mels"), p.at("f_min_hz"), p.at("f_max_hz"),
                     kFs);
  Eigen::MatrixXf out;
  mel.Compute(input.data() + 2 * n, n, &out);
  ASSERT_EQ(out.rows(), goldens.Shape("band_mel")[0]);
  ASSERT_EQ(out.cols(), goldens.Shape("band_mel")[1]);
  const Deviation d = Compare(out, reference.data());
  std::cout << "band_mel: max abs " << d.max_abs << ", rel " << d.rel() << "\n";
  EXPECT_LE(d.max_abs, 1e-4 * d.max_ref + 1e-12);
}

TEST(MelSpectrogramTest, FilterbankShapeAndTriangles) {
  MelSpectrogram mel(512, 128, 50, 0.0, kFs / 2, kFs);
  EXPECT_EQ(mel.Frames(66150), 517);
  EXPECT_EQ(mel.Frames(128), 2);
  const Eigen::MatrixXf& fb = mel.filterbank();
  ASSERT_EQ(fb.rows(), 50);
  ASSERT_EQ(fb.cols(), 257);
  EXPECT_GE(fb.minCoeff(), 0.0f);
  EXPECT_LE(fb.maxCoeff(), 1.0f);
  // Band centres rise with the band index.
  Eigen::Index previous = -1;
  for (int64_t j = 0; j < fb.rows(); ++j) {
    Eigen::Index centre = 0;
    fb.row(j).maxCoeff(&centre);
    EXPECT_GE(centre, previous) << "band " << j;
    previous = centre;
  }
}

TEST(MelSpectrogramTest, RejectsBadArguments) {
  EXPECT_THROW(MelSpectrogram(0, 128, 50, 0.0, kFs / 2, kFs), ConfigError);
  EXPECT_THROW(MelSpectrogram(512, 0, 50, 0.0, kFs / 2, kFs), ConfigError);
  EXPECT_THROW(MelSpectrogram(512, 128, 50, 0.0, kFs, kFs), ConfigError);
  EXPECT_THROW(MelSpectrogram(512, 128, 50, 5000.0, 4000.0, kFs), ConfigError);
}

// ---------------------------------------------------------------------------------------------
// GCC-PHAT

TEST(GccPhatTest, FftSizeIsASmoothMultipleOf512) {
  // 1.5 s and 1 s windows at 44.1 kHz with 441 lags, the golden input, a tiny window
  EXPECT_EQ(GccPhat(66150, 441, 6).fft_size(), 69120);  // 2^9 * 3^3 * 5
  EXPECT_EQ(GccPhat(44100, 441, 6).fft_size(), 46080);  // 2^10 * 3^2 * 5
  EXPECT_EQ(GccPhat(4000, 441, 6).fft_size(), 4608);    // 2^9 * 3^2
  EXPECT_EQ(GccPhat(100, 10, 2).fft_size(), 512);
  EXPECT_EQ(GccPhat(512, 0, 2).fft_size(), 512);
  EXPECT_EQ(GccPhat(513, 0, 2).fft_size(), 1024);
}

TEST(GccPhatTest, MatchesZeroPaddedNumpyReference) {
  Goldens goldens;
  const auto in_shape = goldens.Shape("multi_input");  // (6, 4000)
  const auto gcc_shape = goldens.Shape("multi_gcc");   // (15, 883)
  const std::vector<float> input = goldens.Load("multi_input");
  const std::vector<float> reference = goldens.Load("multi_gcc");
  const int64_t max_lag = goldens.manifest().at("gcc").at("max_lag");
  // Row-major (C order) input into a (channels x n) matrix.
  Eigen::MatrixXf window(in_shape[0], in_shape[1]);
  for (int64_t c = 0; c < in_shape[0]; ++c) {
    for (int64_t t = 0; t < in_shape[1]; ++t) window(c, t) = input[c * in_shape[1] + t];
  }
  GccPhat gcc(in_shape[1], max_lag, static_cast<int>(in_shape[0]));
  // the PHAT output depends on the transform size: the script's rule must be ours
  ASSERT_EQ(gcc.fft_size(), goldens.manifest().at("gcc").at("fft_size").get<int64_t>());
  Eigen::MatrixXf out;
  gcc.Compute(window, &out);
  ASSERT_EQ(out.rows(), gcc_shape[0]);
  ASSERT_EQ(out.cols(), gcc_shape[1]);
  const Deviation d = Compare(out, reference.data());
  std::cout << "multi_gcc: max abs " << d.max_abs << ", rel " << d.rel() << "\n";
  EXPECT_LE(d.max_abs, 1e-4 * d.max_ref + 1e-7);
  // The golden input has channel 3 = channel 2 delayed by 37 samples and channel 4 = channel 2
  // advanced by 120: pair (2,3) is row 9, pair (2,4) is row 10.
  EXPECT_EQ(ArgMax(out, 9) - max_lag, -37);
  EXPECT_EQ(ArgMax(out, 10) - max_lag, 120);
}

// Three channels of the same noise: ch1 lags ch0 by `delay` samples, ch2 = 0.5 * ch0.
Eigen::MatrixXf DelayedNoise(int64_t n, int64_t delay) {
  const int64_t margin = 1000;
  const std::vector<float> base = Noise(n + 2 * margin, 0.1, 1234);
  Eigen::MatrixXf x(3, n);
  for (int64_t t = 0; t < n; ++t) {
    x(0, t) = base[margin + t];
    x(1, t) = base[margin + t - delay];
    x(2, t) = 0.5f * base[margin + t];
  }
  return x;
}

class GccPhatDelayTest : public ::testing::TestWithParam<int64_t> {};

TEST_P(GccPhatDelayTest, PeakAtSignedLag) {
  const int64_t delay = GetParam();  // channel 1 receives `delay` samples after channel 0
  const int64_t n = 8192, max_lag = 441;
  GccPhat gcc(n, max_lag, 3);
  Eigen::MatrixXf out;
  gcc.Compute(DelayedNoise(n, delay), &out);
  ASSERT_EQ(out.rows(), 3);
  ASSERT_EQ(out.cols(), 2 * max_lag + 1);
  // Pair (0,1): first mic earlier => lag -delay. Pair (0,2): simultaneous. Pair (1,2): +delay.
  EXPECT_EQ(ArgMax(out, 0) - max_lag, -delay);
  EXPECT_EQ(ArgMax(out, 1) - max_lag, 0);
  EXPECT_EQ(ArgMax(out, 2) - max_lag, delay);
}

INSTANTIATE_TEST_SUITE_P(Delays, GccPhatDelayTest,
                         ::testing::Values(-441, -300, -37, -1, 0, 1, 5, 120, 440, 441));

TEST(GccPhatTest, NoCircularWrapAround) {
  // A 700-sample window with max_lag 441: circularly, lag +300 and lag -400 are the same bin,
  // so a wrapped correlation would show the same peak at -400 (found first by argmax).
  const int64_t n = 700, max_lag = 441, delay = 300;
  GccPhat gcc(n, max_lag, 3);
  Eigen::MatrixXf out;
  gcc.Compute(DelayedNoise(n, delay), &out);
  const float peak = out(2, max_lag + delay);
  EXPECT_EQ(ArgMax(out, 2) - max_lag, delay);
  EXPECT_LT(out(2, max_lag - (n - delay)), 0.5f * peak);
  EXPECT_EQ(ArgMax(out, 0) - max_lag, -delay);
}

TEST(GccPhatTest, FullWindowDelayAtMaxLag) {
  // Paper window (66150 samples) with the delay at the edge of the lag range.
  const int64_t n = 66150, max_lag = 441;
  GccPhat gcc(n, max_lag, 3);
  Eigen::MatrixXf out;
  gcc.Compute(DelayedNoise(n, 441), &out);
  EXPECT_EQ(ArgMax(out, 0), 0);            // lag -441
  EXPECT_EQ(ArgMax(out, 2), 2 * max_lag);  // lag +441
}

TEST(GccPhatTest, BandsEachPeakAtTheDelayAndSumToTheFullBand) {
  // white noise delayed by 37 samples: every band's correlation peaks there, and the bands
  // (contiguous, spanning 300 Hz .. Nyquist) add up to the full-band PHAT inside their span
  const int64_t n = 2048, max_lag = 96, delay = 37;
  const std::vector<double> edges{300.0, 1000.0, 3000.0, 9000.0, 22050.0};
  const GccPhat full(n, max_lag, 3), banded(n, max_lag, 3, kFs, edges);
  ASSERT_EQ(banded.rows(), 3 * 4);
  Eigen::MatrixXf a, b;
  full.Compute(DelayedNoise(n, delay), &a);
  banded.Compute(DelayedNoise(n, delay), &b);
  ASSERT_EQ(b.rows(), 12);
  for (int band = 0; band < 4; ++band) {
    EXPECT_EQ(ArgMax(b, 2 * 4 + band) - max_lag, delay) << "band " << band;
  }
  // a narrow band's peak is wide: 3 samples off it the lowest band keeps most of its peak,
  // where the full band's has fallen to nothing
  const int64_t at = max_lag + delay;
  EXPECT_GT(b(8, at + 3), 0.8f * b(8, at));
  EXPECT_LT(std::abs(a(2, at + 3)), 0.1f * a(2, at));
  // the bands' peaks together stay below the full band's (their weights sum to one only
  // between the lowest and the highest band centre)
  EXPECT_LT(b.middleRows(8, 4).col(at).sum(), a(2, at));
  EXPECT_GT(b.middleRows(8, 4).col(at).sum(), 0.5f * a(2, at));
  // bad edges are refused naming the key
  for (const std::vector<double>& bad :
       {std::vector<double>{1000.0}, {2000.0, 1000.0}, {1000.0, 30000.0}, {0.0, 1000.0}}) {
    try {
      GccPhat g(n, max_lag, 3, kFs, bad);
      FAIL() << "no ConfigError";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("features.gcc_bands_hz"), std::string::npos) << e.what();
    }
  }
}

TEST(GccPhatTest, RejectsBadArguments) {
  EXPECT_THROW(GccPhat(0, 0, 2), ConfigError);
  EXPECT_THROW(GccPhat(100, 100, 2), ConfigError);
  EXPECT_THROW(GccPhat(100, -1, 2), ConfigError);
  GccPhat gcc(100, 10, 2);
  Eigen::MatrixXf out;
  EXPECT_THROW(gcc.Compute(Eigen::MatrixXf::Zero(3, 100), &out), Error);
}

// ---------------------------------------------------------------------------------------------
// Onset

TEST(DetectOnsetTest, ImpulseOnOneChannelFoundWithinOneFrame) {
  const int64_t total = 44100;
  const int64_t frame = std::llround(0.0029 * kFs);  // 128 samples
  for (int64_t impulse : {int64_t{777}, int64_t{20000}, int64_t{43000}}) {
    Eigen::MatrixXf audio(6, total);
    for (int c = 0; c < 6; ++c) {
      const std::vector<float> noise = Noise(total, 1e-3, 100 + c);
      for (int64_t t = 0; t < total; ++t) audio(c, t) = noise[t];
    }
    audio(3, impulse) = 0.5f;
    const int64_t onset = DetectOnset(audio, kFs, 0.0029, 0.1);
    EXPECT_LE(onset, impulse) << "impulse at " << impulse;
    EXPECT_GT(onset, impulse - frame) << "impulse at " << impulse;
  }
}

TEST(DetectOnsetTest, FirstFrameAboveThresholdNotPeak) {
  // A ramp of bursts: the first burst above 10 % of the peak marks the onset, not the peak.
  Eigen::MatrixXf audio = Eigen::MatrixXf::Zero(2, 4096);
  audio(0, 1000) = 0.05f;  // energy 0.0025 < 0.1 * 1
  audio(1, 2000) = 0.4f;   // energy 0.16 >= 0.1
  audio(0, 3000) = 1.0f;   // peak
  const int64_t onset = DetectOnset(audio, kFs, 0.0029, 0.1);
  EXPECT_EQ(onset, (2000 / 128) * 128);
  EXPECT_THROW(DetectOnset(audio, kFs, 0.0, 0.1), ConfigError);
  EXPECT_THROW(DetectOnset(audio, kFs, 0.0029, 0.0), ConfigError);
}

// ---------------------------------------------------------------------------------------------
// FeatureExtractor

// Six channels of quiet noise with a decaying 2 kHz strike at `onset` (different gains).
Eigen::MatrixXf StrikeRecord(int64_t total, int64_t onset) {
  Eigen::MatrixXf audio(6, total);
  for (int c = 0; c < 6; ++c) {
    const std::vector<float> noise = Noise(total, 1e-4, 7 + c);
    for (int64_t t = 0; t < total; ++t) {
      const double s = t >= onset ? std::exp(-(t - onset) / 400.0) *
                                        std::sin(2 * std::numbers::pi * 2000.0 * (t - onset) / kFs)
                                  : 0.0;
      audio(c, t) = noise[t] + static_cast<float>((0.2 + 0.1 * c) * s);
    }
  }
  return audio;
}

// A record holds a strike when, on some channel about its mean, its peak stands 17 dB above the
// noise RMS and rises to it within 5 ms from a level 17 dB below, with room after the onset: a
// burst in noise does, atop a DC offset too; noise alone, a constant level and a burst cut off
// at the end do not.
TEST(CheckStrikeTest, BurstsPassNoiseLevelsAndCutOffBurstsFail) {
  const int64_t n = 26460;
  Eigen::MatrixXf noise(6, n);
  uint32_t state = 7;
  for (int64_t t = 0; t < n; ++t) {
    for (int c = 0; c < 6; ++c) {
      state = state * 1664525u + 1013904223u;
      noise(c, t) = 0.01f * (static_cast<float>(state >> 8) / 16777216.0f - 0.5f);
    }
  }
  const auto with_burst = [&](int64_t at, float offset) {
    Eigen::MatrixXf x = noise.array() + offset;
    for (int64_t t = at; t < std::min(n, at + 200); ++t)
      x.col(t).array() += 0.3f * std::exp(-(t - at) / 50.0f) * std::sin(0.5f * (t - at));
    return x;
  };
  const StrikeCheck strike = CheckStrike(with_burst(11025, 0.0f), kFs);
  EXPECT_TRUE(strike.found) << strike.reason;
  EXPECT_GT(strike.peak_to_noise_db, 30.0);
  EXPECT_GT(strike.rise_db, 30.0);
  EXPECT_GE(strike.channel, 0);
  EXPECT_NEAR(static_cast<double>(strike.onset_sample), 11025.0, 16.0);
  EXPECT_TRUE(CheckStrike(with_burst(11025, 0.4f), kFs).found);
  // uniform noise peaks at sqrt(3) times its RMS (4.8 dB)
  const StrikeCheck quiet = CheckStrike(noise, kFs);
  EXPECT_FALSE(quiet.found);
  EXPECT_LT(quiet.peak_to_noise_db, 6.0);
  EXPECT_THAT(quiet.reason, HasSubstr("no strike found"));
  EXPECT_FALSE(CheckStrike(Eigen::MatrixXf::Constant(6, n, 0.2f), kFs).found);
  const StrikeCheck cut = CheckStrike(with_burst(n - 90, 0.0f), kFs);
  EXPECT_FALSE(cut.found);
  EXPECT_THAT(cut.reason, HasSubstr("before the record's end"));
  // a strike and then a press swelling over the last 20 ms to the strike's level (a synthesized
  // record's second episode): the strike is the onset
  Eigen::MatrixXf pressed = with_burst(11025, 0.0f);
  for (int64_t t = n - 882; t < n; ++t) pressed.col(t).array() += 0.3f * (t - n + 882) / 882.0f;
  const StrikeCheck first = CheckStrike(pressed, kFs);
  EXPECT_TRUE(first.found) << first.reason;
  EXPECT_NEAR(static_cast<double>(first.onset_sample), 11025.0, 16.0);
}

// Two seconds of six channels of Gaussian noise (sigma) plus `signal` times each channel's gain
// (the loudest 1), signal(t) a function of the sample index
Eigen::MatrixXf NoisyRecord(double sigma, uint32_t seed,
                            const std::function<double(int64_t)>& signal = nullptr) {
  const int64_t n = 88200;
  Eigen::MatrixXf x(6, n);
  for (int c = 0; c < 6; ++c) {
    const std::vector<float> noise = Noise(n, sigma, seed + static_cast<uint32_t>(c));
    const double gain = 1.0 - 0.12 * c;
    for (int64_t t = 0; t < n; ++t)
      x(c, t) = noise[static_cast<size_t>(t)] + static_cast<float>(signal ? gain * signal(t) : 0.0);
  }
  return x;
}

// Strikes 20 dB above the noise RMS (the peak 10 sigma) are found: a decaying 3 kHz ring (a hard
// striker), and a 3 ms half-sine pulse (a soft one, its energy below 300 Hz), whose energy a
// 2.9 ms frame of all six channels' noise nearly matches (the old rule's measure)
TEST(CheckStrikeTest, StrikesTwentyDbAboveTheNoiseAreFound) {
  const double sigma = 1e-3, peak = 10.0 * sigma;
  const int64_t at = 30000;
  const auto ring = [&](int64_t t) {
    if (t < at) return 0.0;
    const double s = (t - at) / kFs;
    return peak * std::exp(-s / 0.01) * std::sin(2 * std::numbers::pi * 3000.0 * s + 0.5);
  };
  const auto pulse = [&](int64_t t) {
    const double s = (t - at) / kFs;
    return s < 0.0 || s > 0.003 ? 0.0 : peak * std::sin(std::numbers::pi * s / 0.003);
  };
  for (uint32_t seed : {11u, 12u, 13u}) {
    for (const auto& [name, signal] :
         {std::pair<const char*, std::function<double(int64_t)>>{"ring", ring}, {"pulse", pulse}}) {
      const StrikeCheck check = CheckStrike(NoisyRecord(sigma, seed, signal), kFs);
      EXPECT_TRUE(check.found) << name << " seed " << seed << ": " << check.reason;
      // the noise on the pulse's flat top adds up to 2-3 sigma to its peak
      EXPECT_GT(check.peak_to_noise_db, 19.0) << name;
      EXPECT_LT(check.peak_to_noise_db, 22.5) << name;
      EXPECT_NEAR(static_cast<double>(check.onset_sample), at, 0.0015 * kFs) << name;
    }
  }
}

// Backgrounds alone are refused, each with its measured dB in the message: white noise (peaks
// near 5 sigma, 14 dB), mains hum of 2 mV over a 30 uV floor (stationary: its level before any
// moment is its level), and motor tones whose amplitude follows a joint speed ramping up and down
// over 0.5 s (their peak stands 40 dB above the floor, but rises over hundreds of ms)
TEST(CheckStrikeTest, NoiseHumAndArmMotionAreRefused) {
  const double floor = 3e-5;
  const auto tones = [](double f0, int harmonics, double t_s) {
    double sum = 0.0;
    for (int k = 1; k <= harmonics; ++k)
      sum += std::sin(2 * std::numbers::pi * k * f0 * t_s + 0.7 * k * k) / (f0 < 100 ? k : 1);
    return sum;
  };
  const auto hum = [&](int64_t t) { return 2e-3 * tones(50.0, 5, t / kFs); };
  const auto motor = [&](int64_t t) {
    const double s = t / kFs - 0.6;  // the joint moves from 0.6 to 1.1 s
    const double speed = s < 0.0 || s > 0.5 ? 0.0 : std::pow(std::sin(std::numbers::pi * s / 0.5), 2);
    return 1.5e-3 * speed * tones(110.0, 8, t / kFs);
  };
  const StrikeCheck white = CheckStrike(NoisyRecord(floor, 21), kFs);
  EXPECT_FALSE(white.found);
  EXPECT_NEAR(white.peak_to_noise_db, 14.0, 1.5);
  EXPECT_THAT(white.reason, HasSubstr(fmt::format("stands {:.1f} dB above the noise RMS",
                                                  white.peak_to_noise_db)));
  const StrikeCheck humming = CheckStrike(NoisyRecord(floor, 22, hum), kFs);
  EXPECT_FALSE(humming.found);
  EXPECT_LT(humming.peak_to_noise_db, 10.0);
  EXPECT_THAT(humming.reason, HasSubstr(fmt::format("{:.1f} dB", humming.peak_to_noise_db)));
  const StrikeCheck moving = CheckStrike(NoisyRecord(floor, 23, motor), kFs);
  EXPECT_FALSE(moving.found);
  EXPECT_GT(moving.peak_to_noise_db, 35.0);  // the median frame is the floor: the rise refuses
  EXPECT_LT(moving.rise_db, 14.0);
  EXPECT_THAT(moving.reason, HasSubstr(fmt::format("{:.1f} dB", moving.rise_db)));
  EXPECT_THAT(moving.reason, HasSubstr("arm motion"));
  // a hard strike at the top of that motion, 20 dB above the motor's level there, is found
  const StrikeCheck struck = CheckStrike(NoisyRecord(floor, 24, [&](int64_t t) {
    const double s = (t - 37485) / kFs;  // 0.85 s, full speed
    return motor(t) + (s < 0 ? 0.0 : 10 * 1.5e-3 * 2 * std::exp(-s / 0.01) *
                                         std::sin(2 * std::numbers::pi * 3000.0 * s + 0.5));
  }), kFs);
  EXPECT_TRUE(struck.found) << struck.reason;
  // a strike 20 dB above the floor at 0.3 s, before that motion (whose peak stands 15 dB and
  // more above the strike's): the strike's peak is its own, and it is found where it rises (the
  // rule that measured it against the record's peak refused it)
  const StrikeCheck before = CheckStrike(NoisyRecord(floor, 25, [&](int64_t t) {
    const double s = (t - 13230) / kFs;
    return motor(t) + (s < 0 ? 0.0 : 10 * floor * std::exp(-s / 0.01) *
                                         std::sin(2 * std::numbers::pi * 3000.0 * s + 0.5));
  }), kFs);
  EXPECT_TRUE(before.found) << before.reason;
  EXPECT_GT(before.peak_to_noise_db, 35.0);  // the channel's peak: the motion's
  EXPECT_NEAR(static_cast<double>(before.onset_sample), 13230.0, 0.0015 * kFs);
  // a follow window of zero is refused, naming it
  StrikeRule bad;
  bad.follow_window_s = 0.0;
  EXPECT_THROW(CheckStrike(NoisyRecord(floor, 26), kFs, bad), ConfigError);
}

TEST(FeatureExtractorTest, WindowCentredOnOnsetWithZeroPadding) {
  FeatureConfig config;
  const FeatureExtractor extractor(config, kFs, 6);
  EXPECT_EQ(extractor.window_samples(), 66150);
  EXPECT_EQ(extractor.mel_frames(), 517);
  EXPECT_EQ(extractor.gcc_lags(), 883);
  EXPECT_EQ(extractor.channels(), 6);

  // Onset at 10000 in a 50000-sample record: the window starts before the record.
  const Eigen::MatrixXf audio = StrikeRecord(50000, 10000);
  const StrikeFeatures f = extractor.Compute(audio);
  EXPECT_LE(f.onset_sample, 10000);
  EXPECT_GT(f.onset_sample, 10000 - 128);
  EXPECT_EQ(f.window_start, f.onset_sample - 66150 / 2);
  ASSERT_EQ(f.mel.size(), 6u);
  ASSERT_EQ(f.gcc.rows(), 15);
  ASSERT_EQ(f.gcc.cols(), 883);

  // Reference: build the zero-padded window by hand and run the blocks directly.
  Eigen::MatrixXf window = Eigen::MatrixXf::Zero(6, 66150);
  for (int64_t i = 0; i < 66150; ++i) {
    const int64_t t = f.window_start + i;
    if (t >= 0 && t < audio.cols()) window.col(i) = audio.col(t);
  }
  MelSpectrogram mel(512, 128, 50, 0.0, kFs / 2, kFs);
  for (int c = 0; c < 6; ++c) {
    ASSERT_EQ(f.mel[c].rows(), 50);
    ASSERT_EQ(f.mel[c].cols(), 517);
    const Eigen::VectorXf row = window.row(c).transpose();
    Eigen::MatrixXf expected;
    mel.Compute(row.data(), row.size(), &expected);
    EXPECT_EQ((f.mel[c] - expected).cwiseAbs().maxCoeff(), 0.0f) << "channel " << c;
  }
  GccPhat gcc(66150, 441, 6);
  Eigen::MatrixXf expected_gcc;
  gcc.Compute(window, &expected_gcc);
  EXPECT_EQ((f.gcc - expected_gcc).cwiseAbs().maxCoeff(), 0.0f);
  // Every channel carries the strike simultaneously: all pairs peak at lag 0.
  for (int64_t p = 0; p < 15; ++p) EXPECT_EQ(ArgMax(f.gcc, p), 441) << "pair " << p;
}

TEST(FeatureExtractorTest, WaveformIsTheWindowItselfOneRowPerChannel) {
  FeatureConfig config;
  config.window_s = 0.02;
  config.gcc_max_lag = 96;
  config.gating = false;
  config.audio_representation = AudioRepresentation::kWaveform;
  const FeatureExtractor extractor(config, kFs, 6);
  EXPECT_EQ(extractor.audio_rows(), 1);
  EXPECT_EQ(extractor.mel_frames(), 882);
  // onset near the start of the record: the window's first samples are zero padding
  const Eigen::MatrixXf audio = StrikeRecord(20000, 300);
  const StrikeFeatures f = extractor.Compute(audio);
  ASSERT_LT(f.window_start, 0);
  ASSERT_EQ(f.mel.size(), 6u);
  for (int c = 0; c < 6; ++c) {
    ASSERT_EQ(f.mel[c].rows(), 1);
    ASSERT_EQ(f.mel[c].cols(), 882);
    for (int64_t i = 0; i < 882; ++i) {
      const int64_t t = f.window_start + i;
      EXPECT_EQ(f.mel[c](0, i), t >= 0 ? audio(c, t) : 0.0f) << "channel " << c << " sample " << i;
    }
  }
  // a part of the waveform is the same part of the whole
  const StrikeFeatures part = extractor.Compute(audio, FeatureRequest{true, false, 100, 500});
  for (int c = 0; c < 6; ++c) {
    EXPECT_TRUE(part.mel[c] == f.mel[c].middleCols(100, 500)) << "channel " << c;
  }
}

TEST(FeatureExtractorTest, LogMelIsLog10OfPowerPlusEpsilon) {
  FeatureConfig config;
  const FeatureExtractor power(config, kFs, 6);
  config.log_mel = true;
  const FeatureExtractor logged(config, kFs, 6);
  const Eigen::MatrixXf audio = StrikeRecord(80000, 40000);
  const StrikeFeatures a = power.Compute(audio);
  const StrikeFeatures b = logged.Compute(audio);
  for (int c = 0; c < 6; ++c) {
    const Eigen::MatrixXf expected =
        (a.mel[c].cast<double>().array() + 1e-10).log10().cast<float>().matrix();
    EXPECT_LE((b.mel[c] - expected).cwiseAbs().maxCoeff(), 1e-6f) << "channel " << c;
  }
  EXPECT_EQ((a.gcc - b.gcc).cwiseAbs().maxCoeff(), 0.0f);
}

TEST(FeatureExtractorTest, ConcurrentComputeMatchesSerial) {
  const FeatureExtractor extractor(FeatureConfig{}, kFs, 6);
  std::vector<Eigen::MatrixXf> records;
  std::vector<StrikeFeatures> serial;
  for (int i = 0; i < 4; ++i) {
    records.push_back(StrikeRecord(70000, 20000 + 5000 * i));
    serial.push_back(extractor.Compute(records.back()));
  }
  std::vector<StrikeFeatures> parallel(8);
  std::vector<std::thread> threads;
  for (int i = 0; i < 8; ++i) {
    threads.emplace_back([&, i] { parallel[i] = extractor.Compute(records[i % 4]); });
  }
  for (auto& t : threads) t.join();
  for (int i = 0; i < 8; ++i) {
    const StrikeFeatures& s = serial[i % 4];
    EXPECT_EQ(parallel[i].onset_sample, s.onset_sample);
    EXPECT_TRUE(parallel[i].gcc == s.gcc) << "thread " << i;
    for (int c = 0; c < 6; ++c) EXPECT_TRUE(parallel[i].mel[c] == s.mel[c]) << "thread " << i;
  }
}

TEST(FeatureExtractorTest, RequestedPartsEqualThoseOfTheWhole) {
  const FeatureExtractor extractor(FeatureConfig{}, kFs, 6);
  const Eigen::MatrixXf audio = StrikeRecord(88200, 30000);
  const StrikeFeatures whole = extractor.Compute(audio);
  // the model's centre crop only, no GCC-PHAT
  const StrikeFeatures crop = extractor.Compute(audio, FeatureRequest{true, false, 86, 345});
  EXPECT_EQ(crop.onset_sample, whole.onset_sample);
  EXPECT_EQ(crop.mel_first_frame, 86);
  ASSERT_EQ(crop.mel.size(), 6u);
  for (int c = 0; c < 6; ++c) {
    ASSERT_EQ(crop.mel[c].cols(), 345);
    EXPECT_TRUE(crop.mel[c] == whole.mel[c].middleCols(86, 345)) << "channel " << c;
  }
  EXPECT_EQ(crop.gcc.size(), 0);
  // GCC-PHAT only
  const StrikeFeatures gcc = extractor.Compute(audio, FeatureRequest{false, true, 0, -1});
  EXPECT_TRUE(gcc.mel.empty());
  EXPECT_TRUE(gcc.gcc == whole.gcc);
  // frames through the end (-1), and a range past it
  const StrikeFeatures tail = extractor.Compute(audio, FeatureRequest{true, false, 500, -1});
  EXPECT_TRUE(tail.mel[0] == whole.mel[0].middleCols(500, 17));
  EXPECT_THROW(extractor.Compute(audio, FeatureRequest{true, true, 200, 345}), Error);
  EXPECT_THROW(extractor.Compute(audio, FeatureRequest{true, true, -1, 10}), Error);
}

TEST(FeatureExtractorTest, GccWindowIsTheCentreSpanOfTheWindow) {
  FeatureConfig config;
  config.gcc_window_s = 0.2;
  const FeatureExtractor extractor(config, kFs, 6);
  EXPECT_EQ(extractor.gcc_samples(), 8820);
  const Eigen::MatrixXf audio = StrikeRecord(88200, 30000);
  const StrikeFeatures f = extractor.Compute(audio);
  // reference: the 8820 samples centred on the window's centre (the onset), by hand
  const int64_t first = f.window_start + 66150 / 2 - 8820 / 2;
  GccPhat gcc(8820, 441, 6);
  Eigen::MatrixXf expected;
  gcc.Compute(audio.middleCols(first, 8820), &expected);
  EXPECT_TRUE(f.gcc == expected);
  // and not the whole window's GCC-PHAT
  const StrikeFeatures whole = FeatureExtractor(FeatureConfig{}, kFs, 6).Compute(audio);
  EXPECT_GT((whole.gcc - f.gcc).cwiseAbs().maxCoeff(), 1e-3f);
  EXPECT_TRUE(whole.mel[0] == f.mel[0]);
}

TEST(FeatureExtractorTest, RejectsWrongChannelCount) {
  const FeatureExtractor extractor(FeatureConfig{}, kFs, 6);
  EXPECT_THROW(extractor.Compute(Eigen::MatrixXf::Zero(2, 70000)), Error);
}

struct BadConfigCase {
  std::string key;     // expected in the message
  std::string detail;  // also expected in the message
  void (*mutate)(FeatureConfig*);
};

class FeatureConfigErrorTest : public ::testing::TestWithParam<BadConfigCase> {};

TEST_P(FeatureConfigErrorTest, ThrowsConfigErrorNamingKey) {
  FeatureConfig config;
  GetParam().mutate(&config);
  const std::string message =
      ThrownMessage<ConfigError>([&] { FeatureExtractor extractor(config, kFs, 6); });
  EXPECT_THAT(message, HasSubstr(GetParam().key));
  EXPECT_THAT(message, HasSubstr(GetParam().detail));
}

INSTANTIATE_TEST_SUITE_P(
    Keys, FeatureConfigErrorTest,
    ::testing::Values(
        BadConfigCase{"features.hop", "got -1", [](FeatureConfig* c) { c->hop = -1; }},
        BadConfigCase{"features.n_fft", "got 0", [](FeatureConfig* c) { c->n_fft = 0; }},
        BadConfigCase{"features.n_mels", "got 0", [](FeatureConfig* c) { c->n_mels = 0; }},
        BadConfigCase{"features.window_s", "got 0", [](FeatureConfig* c) { c->window_s = 0.0; }},
        BadConfigCase{"features.f_max_hz", "got 30000",
                      [](FeatureConfig* c) { c->f_max_hz = 30000.0; }},
        BadConfigCase{"features.f_min_hz", "got -5", [](FeatureConfig* c) { c->f_min_hz = -5.0; }},
        BadConfigCase{"features.f_min_hz", "got 9000",
                      [](FeatureConfig* c) {
                        c->f_min_hz = 9000.0;
                        c->f_max_hz = 8000.0;
                      }},
        BadConfigCase{"features.gcc_max_lag", "got 66150",
                      [](FeatureConfig* c) { c->gcc_max_lag = 66150; }},
        BadConfigCase{"features.gcc_max_lag", "got -2",
                      [](FeatureConfig* c) { c->gcc_max_lag = -2; }},
        BadConfigCase{"features.gcc_window_s", "got 2",
                      [](FeatureConfig* c) { c->gcc_window_s = 2.0; }},
        BadConfigCase{"features.gcc_window_s", "got -0.1",
                      [](FeatureConfig* c) { c->gcc_window_s = -0.1; }},
        // 0.005 s is 221 samples, too few for lags up to 441
        BadConfigCase{"features.gcc_max_lag", "GCC-PHAT samples = 221",
                      [](FeatureConfig* c) { c->gcc_window_s = 0.005; }},
        BadConfigCase{"features.onset_frame_s", "got 0",
                      [](FeatureConfig* c) { c->onset_frame_s = 0.0; }},
        BadConfigCase{"features.onset_threshold", "got 1.5",
                      [](FeatureConfig* c) { c->onset_threshold = 1.5; }},
        BadConfigCase{"features.n_fft", "got 100000",
                      [](FeatureConfig* c) { c->n_fft = 100000; }}));

TEST(FeatureConfigTest, DefaultsAreValid) {
  EXPECT_NO_THROW(FeatureExtractor(FeatureConfig{}, kFs, 6));
}

// Records the names, kinds and bounds an Archive is shown.
class RecordingArchive : public Archive {
 public:
  struct Field {
    std::string name;
    std::string kind;
    Bounds bounds;
  };
  std::vector<Field> fields;

  void Visit(std::string_view name, double*, Bounds b) override { Add(name, "double", b); }
  void Visit(std::string_view name, int64_t*, Bounds b) override { Add(name, "int", b); }
  void Visit(std::string_view name, bool*) override { Add(name, "bool", {}); }
  void Visit(std::string_view name, std::string*) override { Add(name, "string", {}); }
  void Visit(std::string_view name, std::vector<double>*, Bounds b) override {
    Add(name, "doubles", b);
  }
  void Visit(std::string_view name, std::vector<std::string>*) override {
    Add(name, "strings", {});
  }
  void VisitChoice(std::string_view name, std::string*, const std::vector<std::string>&) override {
    Add(name, "choice", {});
  }

 protected:
  void BeginGroup(std::string_view) override {}
  void EndGroup() override {}
  // lists: record the fields of the existing items
  std::optional<size_t> BeginList(std::string_view) override { return std::nullopt; }
  void BeginItem(size_t) override {}
  void EndItem() override {}
  void EndList() override {}

 private:
  void Add(std::string_view name, const char* kind, Bounds b) {
    fields.push_back({std::string(name), kind, b});
  }
};

TEST(FeatureConfigTest, SerializeVisitsEveryMemberByName) {
  FeatureConfig config;
  RecordingArchive archive;
  config.Serialize(&archive);
  std::vector<std::string> names;
  for (const auto& f : archive.fields) names.push_back(f.name);
  EXPECT_THAT(names, ::testing::ElementsAre(
                         "window_s", "audio_representation", "n_fft", "hop", "n_mels", "f_min_hz",
                         "f_max_hz", "log_mel", "gcc_max_lag", "gcc_window_s", "gcc_bands_hz",
                         "onset_frame_s", "onset_threshold", "gating", "gating_n_std",
                         "gating_n_fft", "gating_hop", "gating_freq_smooth_hz",
                         "gating_time_smooth_s", "gating_prop_decrease", "gating_noise_wav"));
  ASSERT_EQ(archive.fields.size(), 21u);
  // window_s: (0, inf); hop: (0, inf); log_mel: bool; onset_threshold: (0, 1].
  EXPECT_EQ(archive.fields[0].bounds.lo, 0.0);
  EXPECT_TRUE(archive.fields[0].bounds.lo_open);
  EXPECT_EQ(archive.fields[3].kind, "int");
  EXPECT_TRUE(archive.fields[3].bounds.lo_open);
  EXPECT_EQ(archive.fields[7].kind, "bool");
  EXPECT_EQ(archive.fields[12].bounds.hi, 1.0);
  EXPECT_FALSE(archive.fields[12].bounds.hi_open);
}

}  // namespace
}  // namespace sonicboom::dsp
