#include "sonicboom/dsp/features.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "internal/fftw_util.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/band_weights.h"
#include "sonicboom/dsp/spectral_gate.h"

namespace sonicboom::dsp {

void FeatureConfig::Serialize(Archive* a) {
  a->Visit("window_s", &window_s, Bounds::Positive());
  a->Visit("audio_representation", &audio_representation);
  a->Visit("n_fft", &n_fft, Bounds::Positive());
  a->Visit("hop", &hop, Bounds::Positive());
  a->Visit("n_mels", &n_mels, Bounds::Positive());
  a->Visit("f_min_hz", &f_min_hz, Bounds::NonNegative());
  a->Visit("f_max_hz", &f_max_hz, Bounds::NonNegative());
  a->Visit("log_mel", &log_mel);
  a->Visit("gcc_max_lag", &gcc_max_lag, Bounds::NonNegative());
  a->Visit("gcc_window_s", &gcc_window_s, Bounds::NonNegative());
  a->Visit("gcc_bands_hz", &gcc_bands_hz, Bounds::Positive());
  a->Visit("onset_frame_s", &onset_frame_s, Bounds::Positive());
  a->Visit("onset_threshold", &onset_threshold, Bounds{0.0, 1.0, true, false});
  a->Visit("gating", &gating);
  a->Visit("gating_n_std", &gating_n_std, Bounds::Closed(-100.0, 100.0));
  a->Visit("gating_n_fft", &gating_n_fft, Bounds::Closed(2, 1 << 20));
  a->Visit("gating_hop", &gating_hop, Bounds::Closed(1, 1 << 19));
  a->Visit("gating_freq_smooth_hz", &gating_freq_smooth_hz, Bounds::NonNegative());
  a->Visit("gating_time_smooth_s", &gating_time_smooth_s, Bounds::Closed(0.0, 60.0));
  a->Visit("gating_prop_decrease", &gating_prop_decrease, Bounds::Closed(0.0, 1.0));
  a->Visit("gating_noise_wav", &gating_noise_wav);
}

SpectralGateConfig GatingConfig(const FeatureConfig& config) {
  SpectralGateConfig g;
  g.n_fft = config.gating_n_fft;
  g.hop = config.gating_hop;
  g.n_std = config.gating_n_std;
  g.freq_smooth_hz = config.gating_freq_smooth_hz;
  g.time_smooth_s = config.gating_time_smooth_s;
  g.prop_decrease = config.gating_prop_decrease;
  return g;
}

namespace {

// FFTW plumbing shared with spectral_gate.cc (one planner lock for the whole module)
template <typename T>
using FftwArray = internal::fftw::Array<T>;
using FftwPlan = internal::fftw::Plan;
template <typename T>
using ScratchPool = internal::fftw::ScratchPool<T>;

// GCC-PHAT transform size: the smallest multiple of 512 >= n whose other prime factors are 2, 3
// and 5. FFTW's estimated plans run fastest on sizes rich in factors of 2: for the 1.5 s window
// (66 591 points needed) 69 120 = 2^9 * 135 against 67 500 = 2^2 * 16 875, the smallest 5-smooth
// size (docs/learning.md). PHAT output depends on the size, so scripts/make_goldens.py uses the
// same rule.
int64_t GccFftSize(int64_t n) {
  for (int64_t k = std::max<int64_t>((n + 511) / 512, 1);; ++k) {
    int64_t r = k;
    for (int64_t p : {2, 3, 5}) {
      while (r % p == 0) r /= p;
    }
    if (r == 1) return 512 * k;
  }
}

// Sum of term(i) for i in [0, count) as four interleaved partial sums (independent add chains
// the compiler can pipeline and vectorize), combined in a fixed order: deterministic bits.
template <typename Term>
double FourChainSum(int64_t count, Term term) {
  double part[4] = {0.0, 0.0, 0.0, 0.0};
  int64_t i = 0;
  for (; i + 4 <= count; i += 4) {
    for (int q = 0; q < 4; ++q) part[q] += term(i + q);
  }
  for (; i < count; ++i) part[0] += term(i);
  return (part[0] + part[1]) + (part[2] + part[3]);
}

double HzToMelHtk(double hz) {
  return 2595.0 * std::log10(1.0 + hz / 700.0);
}
double MelToHzHtk(double mel) {
  return 700.0 * (std::pow(10.0, mel / 2595.0) - 1.0);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// MelSpectrogram

struct MelSpectrogram::Impl {
  // Per-call scratch: one windowed frame (n_fft), its spectrum and power (n_fft/2+1), double.
  struct Scratch {
    FftwArray<double> frame;
    FftwArray<fftw_complex> spectrum;
    Eigen::VectorXd power;
  };

  int64_t n_fft{0};
  int64_t hop{0};
  int64_t n_mels{0};
  int64_t n_freqs{0};
  std::vector<double> window;        // periodic Hann (n_fft)
  Eigen::MatrixXf filterbank;        // (n_mels x n_freqs), float copy for callers
  Eigen::MatrixXd filterbank_d;      // (n_mels x n_freqs)
  std::vector<int64_t> band_begin;   // per mel band: first non-zero frequency bin
  std::vector<int64_t> band_end;     // per mel band: one past the last non-zero bin
  std::vector<double> band_weights;  // the non-zero weights of band j, contiguous from
  std::vector<int64_t> band_offset;  // band_offset[j] (n_mels + 1 offsets)
  FftwPlan plan;                     // r2c of one frame
  std::unique_ptr<ScratchPool<Scratch>> pool;

  std::unique_ptr<Scratch> MakeScratch() const {
    auto s = std::make_unique<Scratch>();
    s->frame = FftwArray<double>(n_fft);
    s->spectrum = FftwArray<fftw_complex>(n_freqs);
    s->power = Eigen::VectorXd::Zero(n_freqs);
    return s;
  }
};

MelSpectrogram::MelSpectrogram(int64_t n_fft, int64_t hop, int64_t n_mels, double f_min_hz,
                               double f_max_hz, double sample_rate_hz)
    : impl_(std::make_unique<Impl>()) {
  if (n_fft <= 0) throw ConfigError(fmt::format("mel n_fft must be > 0, got {}", n_fft));
  if (hop <= 0) throw ConfigError(fmt::format("mel hop must be > 0, got {}", hop));
  if (n_mels <= 0) throw ConfigError(fmt::format("mel n_mels must be > 0, got {}", n_mels));
  if (!(sample_rate_hz > 0.0)) {
    throw ConfigError(fmt::format("mel sample rate must be > 0 Hz, got {}", sample_rate_hz));
  }
  if (!(f_min_hz >= 0.0 && f_min_hz < f_max_hz && f_max_hz <= sample_rate_hz / 2.0)) {
    throw ConfigError(fmt::format("mel band must satisfy 0 <= f_min < f_max <= {} Hz, got [{}, {}]",
                                  sample_rate_hz / 2.0, f_min_hz, f_max_hz));
  }
  Impl& m = *impl_;
  m.n_fft = n_fft;
  m.hop = hop;
  m.n_mels = n_mels;
  m.n_freqs = n_fft / 2 + 1;

  m.window = internal::fftw::PeriodicHann(n_fft);

  // HTK triangular filterbank without area normalisation (torchaudio melscale_fbanks): bin
  // centres linspace(0, floor(sr/2), n_freqs) Hz, n_mels+2 corner frequencies equally spaced
  // in mel between f_min and f_max.
  const double nyquist_floor = std::floor(sample_rate_hz / 2.0);
  Eigen::VectorXd bin_hz(m.n_freqs);
  for (int64_t k = 0; k < m.n_freqs; ++k) {
    bin_hz[k] = m.n_freqs == 1 ? 0.0 : nyquist_floor * static_cast<double>(k) / (m.n_freqs - 1);
  }
  const double mel_lo = HzToMelHtk(f_min_hz);
  const double mel_hi = HzToMelHtk(f_max_hz);
  Eigen::VectorXd corner_hz(n_mels + 2);
  for (int64_t i = 0; i < n_mels + 2; ++i) {
    corner_hz[i] = MelToHzHtk(mel_lo + (mel_hi - mel_lo) * static_cast<double>(i) / (n_mels + 1));
  }
  m.filterbank_d = Eigen::MatrixXd::Zero(n_mels, m.n_freqs);
  m.band_begin.assign(n_mels, 0);
  m.band_end.assign(n_mels, 0);
  for (int64_t j = 0; j < n_mels; ++j) {
    const double left = corner_hz[j], centre = corner_hz[j + 1], right = corner_hz[j + 2];
    int64_t begin = m.n_freqs, end = 0;
    for (int64_t k = 0; k < m.n_freqs; ++k) {
      const double down = (bin_hz[k] - left) / (centre - left);
      const double up = (right - bin_hz[k]) / (right - centre);
      const double w = std::max(0.0, std::min(down, up));
      m.filterbank_d(j, k) = w;
      if (w > 0.0) {
        begin = std::min(begin, k);
        end = k + 1;
      }
    }
    m.band_begin[j] = std::min(begin, end);
    m.band_end[j] = end;
  }
  // each band's weights in one contiguous run, for the per-frame product
  m.band_offset.assign(n_mels + 1, 0);
  for (int64_t j = 0; j < n_mels; ++j) {
    for (int64_t k = m.band_begin[j]; k < m.band_end[j]; ++k) {
      m.band_weights.push_back(m.filterbank_d(j, k));
    }
    m.band_offset[j + 1] = static_cast<int64_t>(m.band_weights.size());
  }
  m.filterbank = m.filterbank_d.cast<float>();

  // One r2c plan for a single frame; Compute runs it on per-call scratch arrays.
  internal::fftw::PlanRealTransforms(n_fft, &m.plan, nullptr);
  const Impl* self = impl_.get();
  m.pool = std::make_unique<ScratchPool<Impl::Scratch>>([self] { return self->MakeScratch(); });
}

MelSpectrogram::~MelSpectrogram() = default;

int64_t MelSpectrogram::Frames(int64_t n) const {
  return 1 + n / impl_->hop;
}

const Eigen::MatrixXf& MelSpectrogram::filterbank() const {
  return impl_->filterbank;
}

void MelSpectrogram::Compute(const float* x, int64_t n, Eigen::MatrixXf* out) const {
  Compute(x, n, 0, Frames(n), out);
}

void MelSpectrogram::Compute(const float* x, int64_t n, int64_t first_frame, int64_t frames,
                             Eigen::MatrixXf* out) const {
  if (n <= 0) throw Error(fmt::format("mel spectrogram of an empty signal (n = {})", n));
  if (first_frame < 0 || frames < 0 || first_frame + frames > Frames(n)) {
    throw Error(fmt::format("mel frames [{}, {}) outside the {} frames of {} samples", first_frame,
                            first_frame + frames, Frames(n), n));
  }
  const Impl& m = *impl_;
  out->resize(m.n_mels, frames);
  auto scratch = m.pool->Acquire();
  double* frame = scratch->frame.data();
  fftw_complex* spectrum = scratch->spectrum.data();
  double* power = scratch->power.data();
  const int64_t half = m.n_fft / 2;
  for (int64_t i = 0; i < frames; ++i) {
    // Frame f covers padded samples [f*hop, f*hop + n_fft), i.e. input samples from
    // f*hop - n_fft/2 (center=True), reflected at both ends, times the Hann window.
    const int64_t f = first_frame + i;
    internal::fftw::WindowedFrame(x, n, f * m.hop - half, m.window.data(), m.n_fft, frame);
    fftw_execute_dft_r2c(m.plan.get(), frame, spectrum);
    // Power spectrum |X|^2 (n_freqs), then each band's weights over its contiguous bins.
    for (int64_t k = 0; k < m.n_freqs; ++k) {
      power[k] = spectrum[k][0] * spectrum[k][0] + spectrum[k][1] * spectrum[k][1];
    }
    float* column = out->data() + i * m.n_mels;
    for (int64_t j = 0; j < m.n_mels; ++j) {
      const double* w = m.band_weights.data() + m.band_offset[j];
      const double* p = power + m.band_begin[j];
      const int64_t taps = m.band_offset[j + 1] - m.band_offset[j];
      column[j] = static_cast<float>(FourChainSum(taps, [&](int64_t k) { return w[k] * p[k]; }));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// GccPhat

struct GccPhat::Impl {
  // Per-call scratch, single precision: the zero-padded channel (fft_size), the spectra and
  // magnitudes of all channels (channels x (fft_size/2+1)), the PHAT-weighted cross spectrum and
  // its inverse (fft_size).
  struct Scratch {
    FftwArray<float> signal;
    std::vector<FftwArray<fftwf_complex>> spectra;
    std::vector<std::vector<float>> magnitudes;  // |X_c| per bin
    FftwArray<fftwf_complex> cross;
    FftwArray<fftwf_complex> phat;  // the PHAT cross spectrum before band weights
    FftwArray<float> correlation;
  };

  int64_t n{0};
  int64_t max_lag{0};
  int channels{0};
  int64_t fft_size{0};
  int64_t n_bins{0};
  std::vector<std::pair<int, int>> pairs;       // itertools.combinations(range(C), 2) order
  std::vector<std::vector<float>> band_weight;  // (bands x bins); empty: the full band
  internal::fftw::PlanF forward;                // r2c, fft_size, single precision
  internal::fftw::PlanF inverse;                // c2r, fft_size, single precision
  std::unique_ptr<ScratchPool<Scratch>> pool;

  std::unique_ptr<Scratch> MakeScratch() const {
    auto s = std::make_unique<Scratch>();
    s->signal = FftwArray<float>(fft_size);
    for (int c = 0; c < channels; ++c) {
      s->spectra.emplace_back(n_bins);
      s->magnitudes.emplace_back(static_cast<size_t>(n_bins), 0.0f);
    }
    s->cross = FftwArray<fftwf_complex>(n_bins);
    if (!band_weight.empty()) s->phat = FftwArray<fftwf_complex>(n_bins);
    s->correlation = FftwArray<float>(fft_size);
    return s;
  }
};

GccPhat::GccPhat(int64_t n, int64_t max_lag, int channels) : impl_(std::make_unique<Impl>()) {
  if (n <= 0) throw ConfigError(fmt::format("GCC-PHAT window must be > 0 samples, got {}", n));
  if (max_lag < 0 || max_lag >= n) {
    throw ConfigError(
        fmt::format("GCC-PHAT max_lag must be in [0, {}) samples, got {}", n, max_lag));
  }
  if (channels < 1) throw ConfigError(fmt::format("GCC-PHAT needs >= 1 channel, got {}", channels));
  Impl& g = *impl_;
  g.n = n;
  g.max_lag = max_lag;
  g.channels = channels;
  // Linear (not circular) correlation for |lag| <= max_lag needs fft_size >= n + max_lag.
  g.fft_size = GccFftSize(n + max_lag);
  g.n_bins = g.fft_size / 2 + 1;
  for (int i = 0; i < channels; ++i) {
    for (int j = i + 1; j < channels; ++j) g.pairs.emplace_back(i, j);
  }
  internal::fftw::PlanRealTransforms(g.fft_size, &g.forward, &g.inverse);
  const Impl* self = impl_.get();
  g.pool = std::make_unique<ScratchPool<Impl::Scratch>>([self] { return self->MakeScratch(); });
}

GccPhat::GccPhat(int64_t n, int64_t max_lag, int channels, double sample_rate_hz,
                 const std::vector<double>& band_edges_hz)
    : GccPhat(n, max_lag, channels) {
  if (band_edges_hz.empty()) return;
  ValidateBandEdges(band_edges_hz, sample_rate_hz, "features.gcc_bands_hz");
  Impl& g = *impl_;
  for (size_t b = 0; b + 1 < band_edges_hz.size(); ++b) {
    const std::vector<double> w = LogBandWeights(band_edges_hz[b], band_edges_hz[b + 1], g.fft_size,
                                                 sample_rate_hz, "features.gcc_bands_hz");
    g.band_weight.emplace_back(w.begin(), w.end());
  }
}

GccPhat::~GccPhat() = default;

int64_t GccPhat::fft_size() const {
  return impl_->fft_size;
}

int64_t GccPhat::rows() const {
  const int64_t bands =
      impl_->band_weight.empty() ? 1 : static_cast<int64_t>(impl_->band_weight.size());
  return static_cast<int64_t>(impl_->pairs.size()) * bands;
}

void GccPhat::Compute(const Eigen::Ref<const RowMatrixXf>& window, Eigen::MatrixXf* out) const {
  const Impl& g = *impl_;
  if (window.rows() != g.channels || window.cols() != g.n) {
    throw Error(fmt::format("GCC-PHAT expects a ({} x {}) window, got ({} x {})", g.channels, g.n,
                            window.rows(), window.cols()));
  }
  const int64_t lags = 2 * g.max_lag + 1;
  out->resize(rows(), lags);
  auto scratch = g.pool->Acquire();
  Impl::Scratch& s = *scratch;

  // Spectrum X_c of every channel, zero-padded from n to fft_size samples, and its magnitude
  // (single precision throughout: the float window in, float features out).
  std::fill(s.signal.data() + g.n, s.signal.data() + g.fft_size, 0.0f);
  for (int c = 0; c < g.channels; ++c) {
    const float* row = window.data() + c * window.outerStride();
    std::copy(row, row + g.n, s.signal.data());
    fftwf_complex* x = s.spectra[c].data();
    fftwf_execute_dft_r2c(g.forward.get(), s.signal.data(), x);
    float* magnitude = s.magnitudes[c].data();
    for (int64_t k = 0; k < g.n_bins; ++k) {
      magnitude[k] = std::sqrt(x[k][0] * x[k][0] + x[k][1] * x[k][1]);
    }
  }

  // Per pair (i, j): G = X_i conj(X_j), PHAT weight G / (|G| + 1e-10) with |G| = |X_i| |X_j|,
  // inverse FFT / fft_size. Output column m is lag m - max_lag; negative lag L sits at index
  // fft_size + L.
  const float scale = 1.0f / static_cast<float>(g.fft_size);
  // the lags -max_lag..max_lag of the inverse of `spectrum` into output row `row`
  auto correlate = [&](fftwf_complex* spectrum, int64_t row) {
    fftwf_execute_dft_c2r(g.inverse.get(), spectrum, s.correlation.data());
    for (int64_t m = 0; m < lags; ++m) {
      const int64_t lag = m - g.max_lag;
      const int64_t index = lag >= 0 ? lag : g.fft_size + lag;
      (*out)(row, m) = s.correlation[index] * scale;
    }
  };
  const int64_t bands = static_cast<int64_t>(g.band_weight.size());
  for (size_t p = 0; p < g.pairs.size(); ++p) {
    const fftwf_complex* x = s.spectra[g.pairs[p].first].data();
    const fftwf_complex* y = s.spectra[g.pairs[p].second].data();
    const float* mx = s.magnitudes[g.pairs[p].first].data();
    const float* my = s.magnitudes[g.pairs[p].second].data();
    fftwf_complex* phat = bands > 0 ? s.phat.data() : s.cross.data();
    for (int64_t k = 0; k < g.n_bins; ++k) {
      const float weight = 1.0f / (mx[k] * my[k] + 1e-10f);
      phat[k][0] = (x[k][0] * y[k][0] + x[k][1] * y[k][1]) * weight;
      phat[k][1] = (x[k][1] * y[k][0] - x[k][0] * y[k][1]) * weight;
    }
    if (bands == 0) {
      correlate(phat, static_cast<int64_t>(p));
      continue;
    }
    // one band at a time (the c2r transform overwrites its input)
    for (int64_t b = 0; b < bands; ++b) {
      const float* w = g.band_weight[static_cast<size_t>(b)].data();
      fftwf_complex* cross = s.cross.data();
      for (int64_t k = 0; k < g.n_bins; ++k) {
        cross[k][0] = phat[k][0] * w[k];
        cross[k][1] = phat[k][1] * w[k];
      }
      correlate(cross, static_cast<int64_t>(p) * bands + b);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Onset

namespace {

// One channel's strike evidence, as ratios of amplitudes
struct ChannelStrike {
  double peak_to_noise{0.0};  // its peak over its noise RMS
  double best_rise{0.0};      // the best window's peak over the RMS before it (0: none near)
  double rise{0.0};           // the same of the first window that passes the rule
  int64_t onset{-1};          // first sample of that window reaching half its peak (-1: none)
};

// A ratio of amplitudes in dB; a zero denominator reads 300 dB (a record without noise)
double AmplitudeDb(double num, double den) {
  if (!(num > 0.0)) return 0.0;
  return 20.0 * std::log10(num / std::max(den, 1e-15 * num));
}

// The upper median of `values` (the middle one of an odd count, the upper of the two of an even
// one); values non-empty, taken by value and reordered
double UpperMedian(std::vector<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// Noise RMS of one channel (T, about its mean): the median of its frame-sample frames' RMS
// values, so that a strike's frames (a few of the record's) do not count
double NoiseRms(const Eigen::ArrayXd& x, int64_t frame) {
  const int64_t frames = std::max<int64_t>(1, x.size() / frame);
  const int64_t len = std::min<int64_t>(frame, x.size());
  std::vector<double> rms(static_cast<size_t>(frames));
  for (int64_t f = 0; f < frames; ++f)
    rms[static_cast<size_t>(f)] = std::sqrt(x.segment(f * len, len).square().mean());
  return UpperMedian(std::move(rms));
}

// max(v[b], ..., v[min(b + w, n) - 1]) for every b (w >= 1), in one backward pass: a deque of
// indices whose values decrease from its front
std::vector<double> ForwardWindowMax(const std::vector<double>& v, int64_t w) {
  const int64_t n = static_cast<int64_t>(v.size());
  std::vector<double> out(v.size());
  std::deque<int64_t> best;
  for (int64_t b = n - 1; b >= 0; --b) {
    const double x = v[static_cast<size_t>(b)];
    while (!best.empty() && v[static_cast<size_t>(best.back())] <= x) best.pop_back();
    best.push_back(b);
    while (best.front() >= b + w) best.pop_front();
    out[static_cast<size_t>(b)] = v[static_cast<size_t>(best.front())];
  }
  return out;
}

// A rule's windows: the hop and the noise frame in samples, the others in hops
struct RuleBlocks {
  int64_t hop{1};
  int64_t rise{1};         // the rise window
  int64_t pre{1};          // the level before the onset
  int64_t follow{1};       // the strike's own peak after the onset
  int64_t noise_frame{1};
};

// The rule on one channel (T, about its mean): onsets tried every hop, each with the peak of the
// rise window after it against the loudest of the follow window after it, and the RMS of the
// pre window before it
ChannelStrike ChannelEvidence(const Eigen::ArrayXd& x, const StrikeRule& rule,
                              const RuleBlocks& w) {
  const int64_t hop = w.hop, rise_blocks = w.rise, pre_blocks = w.pre;
  const int64_t follow_blocks = std::max(w.follow, w.rise);
  const int64_t total = x.size();
  const int64_t blocks = (total + hop - 1) / hop;
  // per hop block: peak |x| and the sum of squares before it (blocks + 1)
  std::vector<double> block_peak(static_cast<size_t>(blocks));
  std::vector<double> energy_before(static_cast<size_t>(blocks + 1), 0.0);
  for (int64_t b = 0; b < blocks; ++b) {
    const auto seg = x.segment(b * hop, std::min(hop, total - b * hop));
    block_peak[static_cast<size_t>(b)] = seg.abs().maxCoeff();
    energy_before[static_cast<size_t>(b + 1)] = energy_before[static_cast<size_t>(b)] +
                                                seg.square().sum();
  }
  const double peak = *std::max_element(block_peak.begin(), block_peak.end());
  ChannelStrike out;
  out.peak_to_noise = AmplitudeDb(peak, NoiseRms(x, w.noise_frame));
  // onsets whose window comes near the loudest that follows: the best rise, and the first that
  // passes (the strike; a later swell, such as a press at the record's end, is not its onset)
  const double near = std::pow(10.0, -rule.near_peak_db / 20.0);
  const std::vector<double> rise_peak = ForwardWindowMax(block_peak, rise_blocks);
  const std::vector<double> follow_peak = ForwardWindowMax(block_peak, follow_blocks);
  for (int64_t b = pre_blocks; b < blocks; ++b) {
    const double level = rise_peak[static_cast<size_t>(b)];
    if (!(level > 0.0) || level < near * follow_peak[static_cast<size_t>(b)]) continue;
    const double pre_energy = energy_before[static_cast<size_t>(b)] -
                              energy_before[static_cast<size_t>(b - pre_blocks)];
    const double rise =
        AmplitudeDb(level, std::sqrt(std::max(pre_energy, 0.0) / (pre_blocks * hop)));
    out.best_rise = std::max(out.best_rise, rise);
    if (rise < rule.min_db) continue;
    // the wavefront: the window's first sample reaching half its peak
    out.rise = rise;
    out.onset = b * hop;
    while (out.onset + 1 < total && std::abs(x[out.onset]) < 0.5 * level) ++out.onset;
    break;
  }
  return out;
}

}  // namespace

StrikeCheck CheckStrike(const Eigen::MatrixXf& audio, double sample_rate_hz,
                        const StrikeRule& rule) {
  if (!(sample_rate_hz > 0.0) || !(rule.hop_s > 0.0) || !(rule.rise_window_s > 0.0) ||
      !(rule.pre_window_s > 0.0) || !(rule.noise_frame_s > 0.0) ||
      !(rule.follow_window_s > 0.0)) {
    throw ConfigError(fmt::format("strike check: the sample rate {} Hz and the windows (hop {} s, "
                                  "rise {} s, follow {} s, pre {} s, noise frame {} s) must be > 0",
                                  sample_rate_hz, rule.hop_s, rule.rise_window_s,
                                  rule.follow_window_s, rule.pre_window_s, rule.noise_frame_s));
  }
  const auto samples = [&](double s) {
    return std::max<int64_t>(1, std::llround(s * sample_rate_hz));
  };
  const auto blocks_of = [&](double s) {
    return std::max<int64_t>(1, std::llround(s / rule.hop_s));
  };
  const RuleBlocks w{samples(rule.hop_s), blocks_of(rule.rise_window_s),
                     blocks_of(rule.pre_window_s), blocks_of(rule.follow_window_s),
                     samples(rule.noise_frame_s)};
  const int64_t hop = w.hop, rise_blocks = w.rise, pre_blocks = w.pre;
  StrikeCheck check;
  const int64_t total = audio.cols();
  if (total <= (pre_blocks + rise_blocks) * hop) {
    check.reason = fmt::format("the record is {} samples long, not over the {:.0f} ms the strike "
                               "check reads",
                               total, 1e3 * (rule.pre_window_s + rule.rise_window_s));
    return check;
  }
  // each channel about its mean (a DC offset is no strike), the rule on each
  std::vector<ChannelStrike> channels;
  for (Eigen::Index c = 0; c < audio.rows(); ++c) {
    const Eigen::ArrayXd x = audio.row(c).cast<double>().transpose().array();
    channels.push_back(ChannelEvidence(x - x.mean(), rule, w));
  }
  // the strike's channel: of those whose peak stands min_db above their noise and that rise,
  // the first to rise; else the best rise of those channels (for the message)
  int chosen = -1;
  bool loud = false;
  for (size_t c = 0; c < channels.size(); ++c) {
    const ChannelStrike& ch = channels[c];
    check.peak_to_noise_db = std::max(check.peak_to_noise_db, ch.peak_to_noise);
    if (ch.peak_to_noise < rule.min_db) continue;
    loud = true;
    check.rise_db = std::max(check.rise_db, ch.best_rise);
    if (ch.onset >= 0 &&
        (chosen < 0 || ch.onset < channels[static_cast<size_t>(chosen)].onset))
      chosen = static_cast<int>(c);
  }
  if (chosen >= 0) {
    check.rise_db = channels[static_cast<size_t>(chosen)].rise;
    check.onset_sample = channels[static_cast<size_t>(chosen)].onset;
  }
  const double after_s = static_cast<double>(total - check.onset_sample) / sample_rate_hz;
  if (!loud) {
    check.reason = fmt::format(
        "no strike found: the loudest peak stands {:.1f} dB above the noise RMS, a strike at "
        "least {:g} dB and rising within {:g} ms (noise, hum or a constant level alone?)",
        check.peak_to_noise_db, rule.min_db, 1e3 * rule.rise_window_s);
  } else if (chosen < 0) {
    check.reason = fmt::format(
        "no strike found: the loudest peak stands {:.1f} dB above the noise RMS, but no channel "
        "rises within {:g} ms to within {:g} dB of the loudest of the {:g} ms that follow from a "
        "level more than {:.1f} dB below it (the RMS of the {:g} ms before), a strike at least "
        "{:g} dB (arm motion or hum alone?)",
        check.peak_to_noise_db, 1e3 * rule.rise_window_s, rule.near_peak_db,
        1e3 * std::max(rule.follow_window_s, rule.rise_window_s), check.rise_db,
        1e3 * rule.pre_window_s, rule.min_db);
  } else if (after_s < rule.min_after_s) {
    check.reason = fmt::format(
        "no strike found: its onset lies {:.1f} ms before the record's end, under the {:.0f} ms "
        "a strike needs (cut off?)",
        1e3 * after_s, 1e3 * rule.min_after_s);
  }
  check.found = check.reason.empty();
  if (check.found) check.channel = chosen;
  return check;
}

int64_t DetectOnset(const Eigen::MatrixXf& audio, double sample_rate_hz, double frame_s,
                    double threshold) {
  if (!(sample_rate_hz > 0.0)) {
    throw ConfigError(fmt::format("onset sample rate must be > 0 Hz, got {}", sample_rate_hz));
  }
  if (!(frame_s > 0.0)) {
    throw ConfigError(fmt::format("features.onset_frame_s must be > 0, got {}", frame_s));
  }
  if (!(threshold > 0.0 && threshold <= 1.0)) {
    throw ConfigError(fmt::format("features.onset_threshold must be in (0, 1], got {}", threshold));
  }
  const int64_t total = audio.cols();
  if (total == 0) return 0;
  const int64_t frame = std::max<int64_t>(1, std::llround(frame_s * sample_rate_hz));
  // Energy of frame [start, start+frame): sum over channels and samples of x^2 (last frame
  // may be short).
  // (the frame's columns are contiguous in the column-major record: one flat run of samples)
  auto energy = [&](int64_t start) {
    const int64_t len = std::min(frame, total - start);
    const float* x = audio.data() + start * audio.rows();
    const int64_t count = len * audio.rows();
    return FourChainSum(count, [x](int64_t i) { return static_cast<double>(x[i]) * x[i]; });
  };
  // per frame energies (one pass over the record), then the first at threshold * peak
  std::vector<double> energies;
  energies.reserve(static_cast<size_t>((total + frame - 1) / frame));
  for (int64_t start = 0; start < total; start += frame) energies.push_back(energy(start));
  // above the threshold's share of the peak and above the floor (the median frame)
  const double floor = UpperMedian(energies) * std::pow(10.0, kOnsetOverFloorDb / 10.0);
  const double level =
      std::max(threshold * *std::max_element(energies.begin(), energies.end()), floor);
  for (size_t i = 0; i < energies.size(); ++i) {
    if (energies[i] >= level) return static_cast<int64_t>(i) * frame;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// FeatureExtractor

struct FeatureExtractor::Impl {
  // Per-call scratch: the window (channels x window_samples, one contiguous row per channel).
  struct Scratch {
    RowMatrixXf window;
  };

  FeatureConfig config;
  double sample_rate_hz{0.0};
  int channels{0};
  int64_t window_samples{0};
  int64_t gcc_samples{0};              // GCC-PHAT span, centred in the window
  std::unique_ptr<SpectralGate> gate;  // null: no gating
  bool waveform{false};                // the waveform representation: no mel spectrogram
  std::unique_ptr<MelSpectrogram> mel;  // null for the waveform representation
  std::unique_ptr<GccPhat> gcc;
  std::unique_ptr<ScratchPool<Scratch>> pool;
};

namespace {

// Checks a FeatureConfig against the sample rate; throws ConfigError naming the key.
void ValidateFeatureConfig(const FeatureConfig& c, double fs, int channels) {
  if (!(fs > 0.0)) throw ConfigError(fmt::format("sample rate must be > 0 Hz, got {}", fs));
  if (channels < 1) throw ConfigError(fmt::format("channels must be >= 1, got {}", channels));
  if (!(c.window_s > 0.0)) {
    throw ConfigError(fmt::format("features.window_s must be > 0, got {}", c.window_s));
  }
  const int64_t window_samples = std::llround(c.window_s * fs);
  if (window_samples < 1) {
    throw ConfigError(
        fmt::format("features.window_s must be at least one sample, got {} s", c.window_s));
  }
  if (c.n_fft <= 0) throw ConfigError(fmt::format("features.n_fft must be > 0, got {}", c.n_fft));
  if (c.n_fft > window_samples) {
    throw ConfigError(fmt::format("features.n_fft must be <= window samples ({}), got {}",
                                  window_samples, c.n_fft));
  }
  if (c.hop <= 0) throw ConfigError(fmt::format("features.hop must be > 0, got {}", c.hop));
  if (c.n_mels <= 0) {
    throw ConfigError(fmt::format("features.n_mels must be > 0, got {}", c.n_mels));
  }
  const double nyquist = fs / 2.0;
  if (!(c.f_min_hz >= 0.0)) {
    throw ConfigError(fmt::format("features.f_min_hz must be >= 0, got {}", c.f_min_hz));
  }
  if (!(c.f_max_hz >= 0.0 && c.f_max_hz <= nyquist)) {
    throw ConfigError(fmt::format("features.f_max_hz must be in [0, Nyquist = {}] Hz, got {}",
                                  nyquist, c.f_max_hz));
  }
  const double f_max = c.f_max_hz == 0.0 ? nyquist : c.f_max_hz;
  if (!(c.f_min_hz < f_max)) {
    throw ConfigError(
        fmt::format("features.f_min_hz must be < f_max ({} Hz), got {}", f_max, c.f_min_hz));
  }
  if (!(c.gcc_window_s >= 0.0 && c.gcc_window_s <= c.window_s)) {
    throw ConfigError(
        fmt::format("features.gcc_window_s must be in [0, features.window_s = {}] "
                    "s (0: the whole window), got {}",
                    c.window_s, c.gcc_window_s));
  }
  const int64_t gcc_samples = std::llround(c.gcc_span_s() * fs);
  if (c.gcc_max_lag < 0 || c.gcc_max_lag >= gcc_samples) {
    throw ConfigError(
        fmt::format("features.gcc_max_lag must be in [0, GCC-PHAT samples = {}), "
                    "got {} (features.gcc_window_s sets the span; 0 is the whole window)",
                    gcc_samples, c.gcc_max_lag));
  }

  if (!(c.onset_frame_s > 0.0)) {
    throw ConfigError(fmt::format("features.onset_frame_s must be > 0, got {}", c.onset_frame_s));
  }
  if (!(c.onset_threshold > 0.0 && c.onset_threshold <= 1.0)) {
    throw ConfigError(
        fmt::format("features.onset_threshold must be in (0, 1], got {}", c.onset_threshold));
  }
  if (!c.gating) return;
  if (!std::isfinite(c.gating_n_std)) {
    throw ConfigError(fmt::format("features.gating_n_std must be finite, got {}", c.gating_n_std));
  }
  if (c.gating_n_fft < 2 || c.gating_n_fft > window_samples) {
    throw ConfigError(
        fmt::format("features.gating_n_fft must be in [2, window samples = {}], "
                    "got {}",
                    window_samples, c.gating_n_fft));
  }
  if (c.gating_hop < 1 || c.gating_hop > c.gating_n_fft / 2) {
    throw ConfigError(
        fmt::format("features.gating_hop must be in [1, gating_n_fft / 2 = {}], "
                    "got {}",
                    c.gating_n_fft / 2, c.gating_hop));
  }
  if (!(c.gating_freq_smooth_hz >= 0.0 && c.gating_freq_smooth_hz <= nyquist)) {
    throw ConfigError(
        fmt::format("features.gating_freq_smooth_hz must be in [0, Nyquist = {}] Hz, "
                    "got {}",
                    nyquist, c.gating_freq_smooth_hz));
  }
  const double window_s = static_cast<double>(window_samples) / fs;
  if (!(c.gating_time_smooth_s >= 0.0 && c.gating_time_smooth_s <= window_s)) {
    throw ConfigError(
        fmt::format("features.gating_time_smooth_s must be in [0, window = {} s], "
                    "got {}",
                    window_s, c.gating_time_smooth_s));
  }
  if (!(c.gating_prop_decrease >= 0.0 && c.gating_prop_decrease <= 1.0)) {
    throw ConfigError(fmt::format("features.gating_prop_decrease must be in [0, 1], got {}",
                                  c.gating_prop_decrease));
  }
}

}  // namespace

FeatureExtractor::FeatureExtractor(const FeatureConfig& config, double sample_rate_hz, int channels)
    : FeatureExtractor(config, sample_rate_hz, channels, nullptr) {}

FeatureExtractor::FeatureExtractor(const FeatureConfig& config, double sample_rate_hz, int channels,
                                   const Eigen::MatrixXf* noise_clip)
    : impl_(std::make_unique<Impl>()) {
  ValidateFeatureConfig(config, sample_rate_hz, channels);
  Impl& e = *impl_;
  e.config = config;
  e.sample_rate_hz = sample_rate_hz;
  e.channels = channels;
  e.window_samples = std::llround(config.window_s * sample_rate_hz);
  e.waveform = config.audio_representation == AudioRepresentation::kWaveform;
  if (!e.waveform) {
    const double f_max = config.f_max_hz == 0.0 ? sample_rate_hz / 2.0 : config.f_max_hz;
    e.mel = std::make_unique<MelSpectrogram>(config.n_fft, config.hop, config.n_mels,
                                             config.f_min_hz, f_max, sample_rate_hz);
  }
  e.gcc_samples = std::llround(config.gcc_span_s() * sample_rate_hz);
  e.gcc = std::make_unique<GccPhat>(e.gcc_samples, config.gcc_max_lag, channels, sample_rate_hz,
                                    config.gcc_bands_hz);
  if (config.gating && noise_clip != nullptr) {
    if (noise_clip->rows() != channels) {
      throw ConfigError(
          fmt::format("features.gating: the reference noise clip has {} channels, "
                      "the records have {}",
                      noise_clip->rows(), channels));
    }
    if (noise_clip->cols() < config.gating_n_fft) {
      throw ConfigError(
          fmt::format("features.gating: the reference noise clip has {} samples, "
                      "shorter than one gate frame (features.gating_n_fft = {})",
                      noise_clip->cols(), config.gating_n_fft));
    }
    e.gate = std::make_unique<SpectralGate>(GatingConfig(config), *noise_clip, sample_rate_hz);
  }
  const int64_t n = e.window_samples;
  e.pool = std::make_unique<ScratchPool<Impl::Scratch>>([channels, n] {
    auto s = std::make_unique<Impl::Scratch>();
    s->window = RowMatrixXf::Zero(channels, n);
    return s;
  });
}

FeatureExtractor::~FeatureExtractor() = default;

int64_t FeatureExtractor::window_samples() const {
  return impl_->window_samples;
}
int64_t FeatureExtractor::mel_frames() const {
  return impl_->waveform ? impl_->window_samples : impl_->mel->Frames(impl_->window_samples);
}
int64_t FeatureExtractor::frame_hop() const {
  return impl_->waveform ? 1 : impl_->config.hop;
}
int64_t FeatureExtractor::audio_rows() const {
  return impl_->waveform ? 1 : impl_->config.n_mels;
}
int64_t FeatureExtractor::gcc_lags() const {
  return 2 * impl_->config.gcc_max_lag + 1;
}
int64_t FeatureExtractor::gcc_rows() const {
  return impl_->gcc->rows();
}
int64_t FeatureExtractor::gcc_samples() const {
  return impl_->gcc_samples;
}
int FeatureExtractor::channels() const {
  return impl_->channels;
}
const SpectralGate* FeatureExtractor::gate() const {
  return impl_->gate.get();
}

StrikeFeatures FeatureExtractor::Compute(const Eigen::MatrixXf& audio,
                                         const FeatureRequest& request) const {
  const Impl& e = *impl_;
  if (audio.rows() != e.channels) {
    throw Error(
        fmt::format("feature extraction expects {} channels, got {}", e.channels, audio.rows()));
  }
  const int64_t all_frames = mel_frames();
  const int64_t first_frame = request.mel_first_frame;
  const int64_t frames = request.mel_frames < 0 ? all_frames - first_frame : request.mel_frames;
  if (request.mel && (first_frame < 0 || frames < 0 || first_frame + frames > all_frames)) {
    throw Error(
        fmt::format("feature request: mel frames [{}, {}) outside the {} frames of the "
                    "window",
                    first_frame, first_frame + frames, all_frames));
  }
  StrikeFeatures features;
  features.onset_sample =
      DetectOnset(audio, e.sample_rate_hz, e.config.onset_frame_s, e.config.onset_threshold);
  const int64_t n = e.window_samples;
  features.window_start = features.onset_sample - n / 2;
  features.mel_first_frame = first_frame;
  if (!request.mel && !request.gcc) return features;

  // Window (channels x n) centred on the onset; samples outside the record are zero.
  auto scratch = e.pool->Acquire();
  RowMatrixXf& window = scratch->window;
  window.setZero();
  const int64_t lo = std::max<int64_t>(0, features.window_start);
  const int64_t hi = std::min<int64_t>(audio.cols(), features.window_start + n);
  if (hi > lo) {
    window.middleCols(lo - features.window_start, hi - lo) = audio.middleCols(lo, hi - lo);
  }

  // Spectral gating per channel against that channel's noise statistics (in place), so that
  // mel and GCC-PHAT both see the gated window.
  if (e.gate) {
    for (int c = 0; c < e.channels; ++c) {
      float* row = window.row(c).data();
      e.gate->Apply(row, n, c, row);
    }
  }

  // The waveform representation: samples [first_frame, first_frame + frames) of the window,
  // (1 x frames) per channel.
  if (request.mel && e.waveform) {
    features.mel.resize(static_cast<size_t>(e.channels));
    for (int c = 0; c < e.channels; ++c) {
      features.mel[c] = window.row(c).segment(first_frame, frames);
    }
  } else if (request.mel) {
    // Power mel (n_mels x frames) per channel, optionally log10(power + 1e-10).
    features.mel.resize(static_cast<size_t>(e.channels));
    for (int c = 0; c < e.channels; ++c) {
      e.mel->Compute(window.row(c).data(), n, first_frame, frames, &features.mel[c]);
      if (e.config.log_mel) {
        features.mel[c] = features.mel[c].unaryExpr(
            [](float p) { return static_cast<float>(std::log10(static_cast<double>(p) + 1e-10)); });
      }
    }
  }

  // GCC-PHAT (pairs x lags) on the same window, or on its centre span of gcc_samples
  if (request.gcc) {
    e.gcc->Compute(window.middleCols(n / 2 - e.gcc_samples / 2, e.gcc_samples), &features.gcc);
  }
  return features;
}

}  // namespace sonicboom::dsp
