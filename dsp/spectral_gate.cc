#include "sonicboom/dsp/spectral_gate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "internal/fftw_util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::dsp {
namespace {

namespace fftw = internal::fftw;

// librosa amplitude_to_db's amin: magnitudes below it count as it (-400 dB); in power, its square
constexpr double kAminPower = 1e-40;

// Throws ConfigError unless lo <= value <= hi (both finite bounds optional through infinities).
void CheckRange(const char* name, double value, double lo, double hi) {
  if (!(value >= lo && value <= hi)) {
    throw ConfigError(
        fmt::format("spectral gate: {} must be in [{}, {}], got {}", name, lo, hi, value));
  }
}

// Sum of the taps m + 1 - |j| of a triangle of half width m centred on i that fall inside
// [0, length): the border normalization of the mask smoothing.
double TapsInside(int64_t m, int64_t i, int64_t length) {
  double inside = 0.0;
  const int64_t lo = std::max(-m, -i), hi = std::min(m, length - 1 - i);
  for (int64_t j = lo; j <= hi; ++j) inside += static_cast<double>(m + 1 - std::abs(j));
  return inside;
}

}  // namespace

struct SpectralGate::Impl {
  // Mask smoothing in exact arithmetic. The binary mask b(k, f) in {0, 1} is smoothed by integer
  // triangles, C(k, f) = sum_i (n_f + 1 - |i|) b(k + i, f) over frequency, then
  // T(k, p) = sum_j (n_t + 1 - |j|) C(k, p + j) over time (zero outside the spectrogram), in Count:
  // int32_t when the whole kernel's sum fits, else double (integers, exact below 2^53).
  template <typename Count>
  struct Counts {
    std::vector<Count> curvature;    // one frame's second difference of C over frequency
    std::vector<Count> ring;         // C of the last min(2 n_t + 3, frames) frames (bins each)
    std::vector<Count> zeros;        // C outside the spectrogram (bins)
    std::vector<Count> step, total;  // per bin: T(k, p) - T(k, p - 1) and T(k, p)
  };

  // Per-call scratch: one frame and its masked spectrum (FFTW-aligned), the STFT of the call and
  // its binary mask, the smoothing counts, the overlap-add accumulator; and what depends only on
  // the signal length, kept for the next call of the same length. Grown, never shrunk.
  struct Scratch {
    fftw::Array<double> frame;
    fftw::Array<fftw_complex> spectrum;
    fftw::Array<fftw_complex> spectra;  // the STFT: frames columns of `stride` (bins used)
    std::vector<double> power;          // |X|^2 of one frame (bins)
    std::vector<double> above;          // 1.0 where it exceeds the threshold, else 0.0
    std::vector<double> threshold;      // per bin: the power to exceed (< 0: every frame)
    std::vector<int32_t> mask;          // b: frames rows of mask_stride (MaskRow), padded
    Counts<int32_t> narrow;             // the counts, int32_t or double (narrow_counts)
    Counts<double> wide;
    std::vector<double> overlap_add;         // padded output samples ((frames - 1) hop + n_fft)
    std::vector<double> time_norm;           // per frame: 1 / triangle taps inside
    std::vector<double> inverse_window_sum;  // per output sample
    int64_t cached_n{-1};                    // signal length of the two above
  };

  SpectralGateConfig config;
  double sample_rate_hz{0.0};
  int channels{0};
  int64_t n_fft{0};
  int64_t hop{0};
  int64_t half{0};       // centre padding, n_fft / 2
  int64_t bins{0};       // n_fft / 2 + 1
  int64_t stride{0};     // STFT column stride: bins rounded up to 64 bytes (FFTW alignment kept)
  int64_t freq_bins{0};  // kernel half widths
  int64_t time_frames{0};
  int64_t mask_stride{0};           // binary mask row: bins, 2 n_f + 2 zeros before and n_f after
  bool narrow_counts{true};         // the kernel's sum (n_f + 1)^2 (n_t + 1)^2 fits int32_t
  std::vector<double> window;       // periodic Hann (n_fft)
  std::vector<double> ola_window;   // window / n_fft: inverse FFT scale and synthesis window
  Eigen::MatrixXd threshold_db;     // (channels x bins)
  Eigen::MatrixXd threshold_power;  // (channels x bins): 10^(threshold_db / 10)
  std::vector<double> keep_freq_norm;  // per bin: prop_decrease / (the triangle's taps inside)
  fftw::Plan forward;                  // r2c, n_fft
  fftw::Plan inverse;                  // c2r, n_fft
  std::unique_ptr<fftw::ScratchPool<Scratch>> pool;

  template <typename Count>
  void MakeCounts(Counts<Count>& c) const {
    const size_t b = static_cast<size_t>(bins);
    c.curvature.assign(b + static_cast<size_t>(freq_bins), 0);
    c.zeros.assign(b, 0);
    c.step.assign(b, 0);
    c.total.assign(b, 0);
  }

  std::unique_ptr<Scratch> MakeScratch() const {
    auto s = std::make_unique<Scratch>();
    s->frame = fftw::Array<double>(n_fft);
    s->spectrum = fftw::Array<fftw_complex>(bins);
    const size_t b = static_cast<size_t>(bins);
    s->power.assign(b, 0.0);
    s->above.assign(b, 0.0);
    s->threshold.assign(b, 0.0);
    if (narrow_counts) {
      MakeCounts(s->narrow);
    } else {
      MakeCounts(s->wide);
    }
    return s;
  }

  // Spectrum of frame f of x (n samples) into spectrum (bins, FFTW-aligned): padded samples
  // [f hop, f hop + n_fft) of the centred, reflect-padded signal, times the window.
  void Transform(const float* x, int64_t n, int64_t f, fftw_complex* spectrum, Scratch& s) const {
    double* frame = s.frame.data();
    fftw::WindowedFrame(x, n, f * hop - half, window.data(), n_fft, frame);
    fftw_execute_dft_r2c(forward.get(), frame, spectrum);
  }

  // b(0, f): row f of the binary mask, b(k, f) at [k] for k in [-2 n_f - 2, bins + n_f)
  int32_t* MaskRow(Scratch& s, int64_t f) const {
    return s.mask.data() + f * mask_stride + 2 * freq_bins + 2;
  }

  template <typename Count>
  void Synthesize(Scratch& s, Counts<Count>& c, int64_t n, float* out) const;
};

SpectralGate::SpectralGate(const SpectralGateConfig& config, const Eigen::MatrixXf& noise_clip,
                           double sample_rate_hz)
    : impl_(std::make_unique<Impl>()) {
  if (!(sample_rate_hz > 0.0 && std::isfinite(sample_rate_hz))) {
    throw ConfigError(
        fmt::format("spectral gate: sample rate must be > 0 Hz, got {}", sample_rate_hz));
  }
  if (config.n_fft < 2) {
    throw ConfigError(fmt::format("spectral gate: n_fft must be >= 2, got {}", config.n_fft));
  }
  if (config.hop < 1 || config.hop > config.n_fft / 2) {
    throw ConfigError(fmt::format("spectral gate: hop must be in [1, n_fft / 2 = {}], got {}",
                                  config.n_fft / 2, config.hop));
  }
  if (!std::isfinite(config.n_std)) {
    throw ConfigError(fmt::format("spectral gate: n_std must be finite, got {}", config.n_std));
  }
  CheckRange("freq_smooth_hz", config.freq_smooth_hz, 0.0, sample_rate_hz / 2.0);
  CheckRange("time_smooth_s", config.time_smooth_s, 0.0, 60.0);
  CheckRange("prop_decrease", config.prop_decrease, 0.0, 1.0);
  if (!(config.top_db > 0.0)) {
    throw ConfigError(fmt::format("spectral gate: top_db must be > 0, got {}", config.top_db));
  }
  if (noise_clip.rows() < 1) {
    throw ConfigError("spectral gate: the noise clip has no channels");
  }
  if (noise_clip.cols() < config.n_fft) {
    throw ConfigError(
        fmt::format("spectral gate: the noise clip has {} samples, shorter than one "
                    "STFT frame (n_fft = {})",
                    noise_clip.cols(), config.n_fft));
  }
  for (Eigen::Index t = 0; t < noise_clip.cols(); ++t) {
    for (Eigen::Index c = 0; c < noise_clip.rows(); ++c) {
      if (!std::isfinite(noise_clip(c, t))) {
        throw ConfigError(
            fmt::format("spectral gate: the noise clip has a non-finite value ({}) "
                        "at channel {} sample {}",
                        noise_clip(c, t), c, t));
      }
    }
  }

  Impl& g = *impl_;
  g.config = config;
  g.sample_rate_hz = sample_rate_hz;
  g.channels = static_cast<int>(noise_clip.rows());
  g.n_fft = config.n_fft;
  g.hop = config.hop;
  g.half = config.n_fft / 2;
  g.bins = config.n_fft / 2 + 1;

  // smoothing spans in bins and frames as noisereduce derives them: the span over
  // fs / (n_fft / 2) (twice the bin spacing) and over the hop duration, rounded down
  g.freq_bins = static_cast<int64_t>(std::floor(
      config.freq_smooth_hz / (sample_rate_hz / (static_cast<double>(config.n_fft) / 2.0))));
  g.time_frames = static_cast<int64_t>(
      std::floor((config.time_smooth_s * 1000.0) /
                 ((static_cast<double>(config.hop) / sample_rate_hz) * 1000.0)));
  // border normalization over frequency: the triangle's taps n + 1 - |i| inside [0, bins), with
  // the mask's share prop_decrease folded in
  g.keep_freq_norm.assign(static_cast<size_t>(g.bins), 0.0);
  for (int64_t k = 0; k < g.bins; ++k) {
    g.keep_freq_norm[static_cast<size_t>(k)] =
        config.prop_decrease * (1.0 / TapsInside(g.freq_bins, k, g.bins));
  }
  // the smoothed counts are at most the kernel's sum: int32_t when that fits
  const double taps_f = static_cast<double>(g.freq_bins + 1);
  const double taps_t = static_cast<double>(g.time_frames + 1);
  g.narrow_counts =
      taps_f * taps_f * taps_t * taps_t <= static_cast<double>(std::numeric_limits<int32_t>::max());
  g.stride = (g.bins + 3) / 4 * 4;  // 4 complex values = 64 bytes
  g.mask_stride = g.bins + 3 * g.freq_bins + 2;

  g.window = fftw::PeriodicHann(g.n_fft);
  g.ola_window.resize(g.window.size());
  for (size_t k = 0; k < g.window.size(); ++k) {
    g.ola_window[k] = g.window[k] / static_cast<double>(g.n_fft);
  }
  fftw::PlanRealTransforms(g.n_fft, &g.forward, &g.inverse);
  const Impl* self = impl_.get();
  g.pool =
      std::make_unique<fftw::ScratchPool<Impl::Scratch>>([self] { return self->MakeScratch(); });

  // noise statistics per channel: dB spectrogram of the whole clip, floored at top_db below its
  // peak, then mean and (population) standard deviation over frames per bin
  const int64_t t_noise = noise_clip.cols();
  const int64_t frames = 1 + t_noise / g.hop;
  g.threshold_db.resize(g.channels, g.bins);
  g.threshold_power.resize(g.channels, g.bins);
  auto lease = g.pool->Acquire();
  Impl::Scratch& s = *lease;
  std::vector<float> row(static_cast<size_t>(t_noise));
  Eigen::MatrixXd db(g.bins, frames);
  for (int c = 0; c < g.channels; ++c) {
    for (int64_t t = 0; t < t_noise; ++t) row[static_cast<size_t>(t)] = noise_clip(c, t);
    for (int64_t f = 0; f < frames; ++f) {
      g.Transform(row.data(), t_noise, f, s.spectrum.data(), s);
      for (int64_t k = 0; k < g.bins; ++k) {
        const double re = s.spectrum[k][0], im = s.spectrum[k][1];
        db(k, f) = 10.0 * std::log10(std::max(re * re + im * im, kAminPower));
      }
    }
    const double floor_db = db.maxCoeff() - config.top_db;
    db = db.cwiseMax(floor_db);
    for (int64_t k = 0; k < g.bins; ++k) {
      const double mean = db.row(k).mean();
      const double var = (db.row(k).array() - mean).square().mean();
      const double threshold = mean + config.n_std * std::sqrt(var);
      g.threshold_db(c, k) = threshold;
      g.threshold_power(c, k) = std::pow(10.0, threshold / 10.0);
    }
  }
}

SpectralGate::~SpectralGate() = default;

int SpectralGate::channels() const {
  return impl_->channels;
}
int64_t SpectralGate::frames(int64_t n) const {
  return 1 + n / impl_->hop;
}
int64_t SpectralGate::freq_smooth_bins() const {
  return impl_->freq_bins;
}
int64_t SpectralGate::time_smooth_frames() const {
  return impl_->time_frames;
}
const Eigen::MatrixXd& SpectralGate::threshold_db() const {
  return impl_->threshold_db;
}
const SpectralGateConfig& SpectralGate::config() const {
  return impl_->config;
}

void SpectralGate::Apply(const float* x, int64_t n, int channel, float* out) const {
  const Impl& g = *impl_;
  if (channel < 0 || channel >= g.channels) {
    throw Error(fmt::format("spectral gate: channel {} out of range [0, {})", channel, g.channels));
  }
  if (n < 1) throw Error(fmt::format("spectral gate: empty signal (n = {})", n));
  // all finite (a vectorized test: NaN fails the comparison), else find the first that is not
  int non_finite = 0;
  for (int64_t i = 0; i < n; ++i) {
    non_finite |= !(std::abs(x[i]) <= std::numeric_limits<float>::max());
  }
  if (non_finite != 0) {
    for (int64_t i = 0; i < n; ++i) {
      if (!std::isfinite(x[i])) {
        throw Error(fmt::format("spectral gate: non-finite sample ({}) at index {} of channel {}",
                                x[i], i, channel));
      }
    }
  }
  auto lease = g.pool->Acquire();
  Impl::Scratch& s = *lease;
  const int64_t bins = g.bins, hop = g.hop, n_fft = g.n_fft, nt = g.time_frames;
  const int64_t frames = 1 + n / hop;
  // what depends on the length only: the time-border normalization of the smoothing and the
  // summed squared window of the overlap-add, per output sample
  if (s.cached_n != n) {
    s.time_norm.resize(static_cast<size_t>(frames));
    for (int64_t p = 0; p < frames; ++p) {
      s.time_norm[static_cast<size_t>(p)] = 1.0 / TapsInside(nt, p, frames);
    }
    s.inverse_window_sum.assign(static_cast<size_t>(n), 0.0);
    for (int64_t f = 0; f < frames; ++f) {
      for (int64_t k = 0; k < n_fft; ++k) {
        const int64_t i = f * hop + k - g.half;
        if (i >= 0 && i < n) s.inverse_window_sum[i] += g.window[k] * g.window[k];
      }
    }
    for (double& sum : s.inverse_window_sum) {
      sum = sum > std::numeric_limits<double>::min() ? 1.0 / sum : 1.0;
    }
    s.cached_n = n;
  }

  // pass 1: the STFT, straight into s.spectra (kept for pass 2, so that x is read completely
  // before out is written), and its binary mask. A bin passes when
  // dB = max(10 log10(max(|X|^2, amin^2)), peak_dB - top_db) > threshold: compared in power
  // (monotone), first without the top_db floor (which needs the peak power of the whole call):
  // max(|X|^2, amin^2) > t is |X|^2 > t, or always where t < amin^2 (then -1)
  if (s.spectra.size() < g.stride * frames) {
    s.spectra = fftw::Array<fftw_complex>(g.stride * frames);
  }
  if (s.mask.size() < static_cast<size_t>(g.mask_stride * frames)) {
    s.mask.resize(static_cast<size_t>(g.mask_stride * frames), 0);  // the padding stays zero
  }
  double* power = s.power.data();
  double* above = s.above.data();
  double* threshold = s.threshold.data();
  for (int64_t k = 0; k < bins; ++k) {
    const double t = g.threshold_power(channel, k);
    threshold[k] = t < kAminPower ? -1.0 : t;
  }
  double peak_power = kAminPower;
  for (int64_t f = 0; f < frames; ++f) {
    fftw_complex* spectrum = s.spectra.data() + f * g.stride;
    g.Transform(x, n, f, spectrum, s);
    // |X|^2 written out: std::norm goes through abs (hypot) without -ffast-math
    for (int64_t k = 0; k < bins; ++k) {
      power[k] = spectrum[k][0] * spectrum[k][0] + spectrum[k][1] * spectrum[k][1];
    }
    peak_power = std::max(peak_power, Eigen::Map<const Eigen::ArrayXd>(power, bins).maxCoeff());
    // through a double 0 / 1, which GCC vectorizes (a comparison into integers it does not)
    for (int64_t k = 0; k < bins; ++k) above[k] = power[k] > threshold[k] ? 1.0 : 0.0;
    int32_t* mask = g.MaskRow(s, f);
    for (int64_t k = 0; k < bins; ++k) mask[k] = static_cast<int32_t>(above[k]);
  }
  // then the floor: where it exceeds the threshold, every frame passes
  const double floor_db = 10.0 * std::log10(peak_power) - g.config.top_db;
  for (int64_t k = 0; k < bins; ++k) {
    if (floor_db > g.threshold_db(channel, k)) {
      for (int64_t f = 0; f < frames; ++f) g.MaskRow(s, f)[k] = 1;
    }
  }

  if (g.narrow_counts) {
    g.Synthesize(s, s.narrow, n, out);
  } else {
    g.Synthesize(s, s.wide, n, out);
  }
}

// Pass 2, streaming over frames: the mask of frame p is base + keep T(k, p) freq_norm[k]
// time_norm[p] (the normalized triangle smoothing of base + keep b, mathematically; with the
// counts exact, the only rounding is in that product), then the masked spectrum goes through the
// inverse FFT into the overlap-add, and the samples no later frame reaches go out. A triangle of
// half width m has second difference +1, -2, +1 at offsets -m - 1, 0, m + 1, so the counts are
// two running sums over frequency within a frame (C), and two over time per bin (T), with frame
// p + n_t entering, p - 1 in the middle, p - n_t - 2 leaving (a ring of 2 n_t + 3 columns).
template <typename Count>
void SpectralGate::Impl::Synthesize(Scratch& s, Counts<Count>& c, int64_t n, float* out) const {
  const int64_t nf = freq_bins, nt = time_frames;
  const int64_t frames = 1 + n / hop;
  const int64_t ring = std::min(2 * nt + 3, frames);
  if (c.ring.size() < static_cast<size_t>(ring * bins)) {
    c.ring.resize(static_cast<size_t>(ring * bins));
  }
  // C of frame f (bins): a ring slot inside the spectrogram, zeros outside
  auto counts_of = [&](int64_t f) {
    return f >= 0 && f < frames ? c.ring.data() + (f % ring) * bins : c.zeros.data();
  };
  Count* step = c.step.data();
  Count* total = c.total.data();
  std::fill(step, step + bins, Count{0});
  std::fill(total, total + bins, Count{0});
  const int64_t padded_length = (frames - 1) * hop + n_fft;
  if (s.overlap_add.size() < static_cast<size_t>(padded_length)) {
    s.overlap_add.resize(static_cast<size_t>(padded_length));
  }
  const double base = 1.0 - config.prop_decrease;

  for (int64_t p = -nt; p < frames; ++p) {
    // frame p + n_t: C over frequency, into the ring
    const int64_t f = p + nt;
    if (f < frames) {
      // C(k) - 2 C(k - 1) + C(k - 2) for k in [-nf, bins), at [k + nf] (C is zero below -nf)
      const int32_t* b = MaskRow(s, f);
      Count* curvature = c.curvature.data();
      for (int64_t k = -nf; k < bins; ++k) {
        curvature[k + nf] = static_cast<Count>(b[k + nf] - 2 * b[k - 1] + b[k - nf - 2]);
      }
      // two running sums: E(k) = C(k) - C(k - 1), then C(k)
      Count e = 0, sum = 0;
      for (int64_t k = 0; k < nf; ++k) sum += e += curvature[k];
      Count* counts = counts_of(f);
      for (int64_t k = 0; k < bins; ++k) counts[k] = sum += e += curvature[k + nf];
    }
    // T(k, p) over time, the same recurrence per bin (both zero for p < -nt)
    const Count* entering = counts_of(p + nt);
    const Count* centre = counts_of(p - 1);
    const Count* leaving = counts_of(p - nt - 2);
    for (int64_t k = 0; k < bins; ++k) {
      step[k] += entering[k] - 2 * centre[k] + leaving[k];
      total[k] += step[k];
    }
    if (p < 0) continue;

    // frame p: masked spectrum -> inverse FFT -> windowed overlap-add (1 / n_fft in the window)
    const fftw_complex* spectrum = s.spectra.data() + p * stride;
    const double norm = s.time_norm[p];
    for (int64_t k = 0; k < bins; ++k) {
      const double mask = base + keep_freq_norm[k] * norm * static_cast<double>(total[k]);
      s.spectrum[k][0] = spectrum[k][0] * mask;
      s.spectrum[k][1] = spectrum[k][1] * mask;
    }
    fftw_execute_dft_c2r(inverse.get(), s.spectrum.data(), s.frame.data());
    // padded samples p hop .. p hop + n_fft; the first n_fft - hop of them earlier frames reached
    double* acc = s.overlap_add.data() + p * hop;
    const double* frame = s.frame.data();
    const int64_t reached = p == 0 ? 0 : n_fft - hop;
    for (int64_t k = 0; k < reached; ++k) acc[k] += frame[k] * ola_window[k];
    for (int64_t k = reached; k < n_fft; ++k) acc[k] = frame[k] * ola_window[k];
    // samples no later frame reaches are finished: normalize, trim the centre padding
    const int64_t done = p * hop + (p + 1 < frames ? hop : n_fft) - half;
    for (int64_t i = std::max<int64_t>(p * hop - half, 0); i < std::min(done, n); ++i) {
      out[i] = static_cast<float>(s.overlap_add[i + half] * s.inverse_window_sum[i]);
    }
  }
}

}  // namespace sonicboom::dsp
