#include "sonicboom/dsp/band_weights.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::dsp {

std::vector<double> LogBandWeights(double low_hz, double high_hz, int64_t fft_size,
                                   double sample_rate_hz, std::string_view key) {
  const double centre = std::sqrt(low_hz * high_hz);
  const double half_width = std::log2(high_hz / low_hz);
  const int64_t bins = fft_size / 2 + 1;
  std::vector<double> w(static_cast<size_t>(bins), 0.0);
  double sum = 0.0;
  for (int64_t k = 1; k < bins; ++k) {
    const double f = k * sample_rate_hz / static_cast<double>(fft_size);
    const double x = std::log2(f / centre) / half_width;
    if (std::abs(x) < 1.0) {
      const double c = std::cos(0.5 * std::numbers::pi * x);
      w[static_cast<size_t>(k)] = c * c;
      sum += c * c;
    }
  }
  if (!(sum > 0.0)) {
    throw ConfigError(fmt::format("{}: band {}-{} Hz holds no frequency bin of the {}-point FFT",
                                  key, low_hz, high_hz, fft_size));
  }
  return w;
}

void ValidateBandEdges(const std::vector<double>& edges_hz, double sample_rate_hz,
                       std::string_view key) {
  if (edges_hz.size() < 2) {
    throw ConfigError(
        fmt::format("{} needs at least two edges (one band), got {}", key, edges_hz.size()));
  }
  for (size_t b = 0; b < edges_hz.size(); ++b) {
    const double e = edges_hz[b];
    if (!(e > 0.0) || !(e <= 0.5 * sample_rate_hz)) {
      throw ConfigError(fmt::format("{}[{}] = {} Hz must be in (0, Nyquist = {}]", key, b, e,
                                    0.5 * sample_rate_hz));
    }
    if (b > 0 && !(e > edges_hz[b - 1])) {
      throw ConfigError(fmt::format("{} must be strictly ascending: [{}] = {} after {}", key, b, e,
                                    edges_hz[b - 1]));
    }
  }
}

}  // namespace sonicboom::dsp
