#pragma once
// Frequency bands as cos^2 weights in log2 frequency: band b spans [edges[b], edges[b+1]], centred
// at their geometric mean with half power at the edges, so that neighbouring bands of a contiguous
// set sum to one. Shared by the band-limited GCC-PHAT features and the TDOA locator.

#include <cstdint>
#include <string_view>
#include <vector>

namespace sonicboom::dsp {

/// Weight of every rfft bin (fft_size / 2 + 1 of them; bin 0 always 0) for band
/// [low_hz, high_hz] at sample_rate_hz. Throws ConfigError naming `key` when the band holds no
/// bin.
std::vector<double> LogBandWeights(double low_hz, double high_hz, int64_t fft_size,
                                   double sample_rate_hz, std::string_view key);

/// Checks a list of band edges: at least two, strictly ascending, positive and at most Nyquist;
/// throws ConfigError naming `key`.
void ValidateBandEdges(const std::vector<double>& edges_hz, double sample_rate_hz,
                       std::string_view key);

}  // namespace sonicboom::dsp
