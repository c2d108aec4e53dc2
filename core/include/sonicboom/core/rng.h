#pragma once
/// Deterministic random numbers. Every draw derives from (global seed, sample index, stream),
/// so results do not depend on thread count, shard count or the order of work.

#include <cmath>
#include <cstdint>

namespace sonicboom {

/// SplitMix64 finalizer: a bijective 64-bit mix.
constexpr uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// Seed of sample `index` under `global_seed`.
constexpr uint64_t SampleSeed(uint64_t global_seed, uint64_t index) {
  return SplitMix64(SplitMix64(global_seed) ^ SplitMix64(index * 0xD1B54A32D192ED03ULL + 1));
}

/// Named sub-streams of one sample (geometry, noise, ...), so adding draws to one stage
/// does not shift the numbers of another.
enum class Stream : uint64_t {
  kStrike = 1,
  kAcoustics = 2,
  kDaq = 3,
  kNoise = 4,
  kSplit = 5,
  kTrain = 6,
  kScene = 7,  // object drawn per strike, scene shapes
  kRandomize = 8,  // randomized structure and sensor chain
  kReference = 9,  // the reference solid's own striker, damping and sensor chain (rerender)
  kTheory = 10     // which model renders a sample (randomize.reference_fraction)
};

/// xoshiro256** generator with its own uniform and normal draws (no implementation-defined
/// std distributions, so numbers are identical across standard libraries).
class Rng {
 public:
  explicit Rng(uint64_t seed);
  Rng(uint64_t sample_seed, Stream stream);

  /// xoshiro256** step (inline: noise signals draw one per sample).
  uint64_t NextU64() {
    const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }
  /// Uniform in [0, 1).
  double Uniform();
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Uniform integer in [0, n).
  uint64_t UniformInt(uint64_t n);
  /// Standard normal (Marsaglia polar method, both values used).
  double Normal();
  double Normal(double mean, double stddev) { return mean + stddev * Normal(); }
  /// Unit-variance approximately normal draw for noise signals: the sum of four 16-bit
  /// uniforms from one 64-bit draw (Irwin-Hall, tails end at +-3.46). ~10x faster than Normal.
  double NoiseSample() {
    const uint64_t x = NextU64();
    const double sum =
        static_cast<double>((x & 0xFFFF) + ((x >> 16) & 0xFFFF) + ((x >> 32) & 0xFFFF) + (x >> 48));
    // mean 4 * 32767.5, variance 4 * (65536^2 - 1) / 12
    return (sum - 131070.0) * 2.6428997921303014e-05;
  }

 private:
  static constexpr uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
  double spare_{0.0};
  bool has_spare_{false};
};

}  // namespace sonicboom
