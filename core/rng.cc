#include "sonicboom/core/rng.h"

#include <cmath>

namespace sonicboom {

Rng::Rng(uint64_t seed) {
  // fill the 256-bit state from a SplitMix64 sequence (never all zero)
  uint64_t x = seed;
  for (auto& s : s_) {
    x += 0x9E3779B97F4A7C15ULL;
    s = SplitMix64(x);
  }
}

Rng::Rng(uint64_t sample_seed, Stream stream)
    : Rng(SplitMix64(sample_seed ^ (static_cast<uint64_t>(stream) * 0xA0761D6478BD642FULL))) {}

double Rng::Uniform() {
  return static_cast<double>(NextU64() >> 11) * 0x1.0p-53;
}

uint64_t Rng::UniformInt(uint64_t n) {
  // rejection sampling avoids modulo bias
  if (n == 0) return 0;
  const uint64_t limit = UINT64_MAX - UINT64_MAX % n;
  uint64_t x = NextU64();
  while (x >= limit) x = NextU64();
  return x % n;
}

double Rng::Normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Marsaglia's polar method: two normals per accepted point, no trigonometry
  double u, v, s;
  do {
    u = 2.0 * Uniform() - 1.0;
    v = 2.0 * Uniform() - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double f = std::sqrt(-2.0 * std::log(s) / s);
  spare_ = v * f;
  has_spare_ = true;
  return u * f;
}

}  // namespace sonicboom
