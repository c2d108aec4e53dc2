#include "sonicboom/acoustics/spectral_gate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <vector>

#include "internal/fftw_util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
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

}  // namespace

struct SpectralGate::Impl {
  // Per-call scratch: one frame and its spectrum (FFTW-aligned), the STFT of the call, the rings
  // and running sums of the streaming pass, the overlap-add accumulator; and what depends only
  // on the signal length, kept for the next call of the same length. Grown, never shrunk.
  struct Scratch {
    fftw::Array<double> frame;
    fftw::Array<fftw_complex> spectrum;
    std::vector<double> power;                  // |X|^2 of one frame (bins)
    std::vector<double> pass_power;             // per bin: power to exceed (< 0: all pass)
    std::vector<std::complex<double>> spectra;  // the STFT (bins x frames, frame-major)
    std::vector<double> line;                   // one frame's mask, zero-padded
    std::vector<double> freq_boxes;             // its frequency box sums
    std::vector<double> smoothed;               // last n_t + 2 frequency-smoothed masks (ring)
    std::vector<double> boxes;                  // last n_t + 2 time box sums (ring)
    std::vector<double> box_run, mask_run;      // running sums over time (bins)
    std::vector<double> overlap_add;            // n_fft samples from the current frame on
    std::vector<double> time_norm;              // per frame: 1 / triangle taps inside
    std::vector<double> inverse_window_sum;     // per output sample
    int64_t cached_n{-1};                       // signal length of the two above
  };

  SpectralGateConfig config;
  double sample_rate_hz{0.0};
  int channels{0};
  int64_t n_fft{0};
  int64_t hop{0};
  int64_t half{0};       // centre padding, n_fft / 2
  int64_t bins{0};       // n_fft / 2 + 1
  int64_t freq_bins{0};  // kernel half widths
  int64_t time_frames{0};
  std::vector<double> window;       // periodic Hann (n_fft)
  Eigen::MatrixXd threshold_db;     // (channels x bins)
  Eigen::MatrixXd threshold_power;  // (channels x bins): 10^(threshold_db / 10)
  std::vector<double> freq_norm;    // per bin: 1 / sum of the triangle's taps inside [0, bins)
  fftw::Plan forward;               // r2c, n_fft
  fftw::Plan inverse;               // c2r, n_fft
  std::unique_ptr<fftw::ScratchPool<Scratch>> pool;

  std::unique_ptr<Scratch> MakeScratch() const {
    auto s = std::make_unique<Scratch>();
    s->frame = fftw::Array<double>(n_fft);
    s->spectrum = fftw::Array<fftw_complex>(bins);
    const size_t b = static_cast<size_t>(bins);
    s->power.assign(b, 0.0);
    s->pass_power.assign(b, 0.0);
    s->smoothed.assign(b * static_cast<size_t>(time_frames + 2), 0.0);
    s->boxes.assign(b * static_cast<size_t>(time_frames + 2), 0.0);
    s->box_run.assign(b, 0.0);
    s->mask_run.assign(b, 0.0);
    s->line.assign(b + 2 * static_cast<size_t>(freq_bins + 1), 0.0);
    s->freq_boxes.assign(b + static_cast<size_t>(freq_bins + 1), 0.0);
    s->overlap_add.assign(static_cast<size_t>(n_fft), 0.0);
    return s;
  }

  // Spectrum of frame f of x (n samples) into s.spectrum: padded samples [f hop, f hop + n_fft)
  // of the centred, reflect-padded signal, times the window.
  void Transform(const float* x, int64_t n, int64_t f, Scratch& s) const {
    double* frame = s.frame.data();
    fftw::WindowedFrame(x, n, f * hop - half, window.data(), n_fft, frame);
    fftw_execute_dft_r2c(forward.get(), frame, s.spectrum.data());
  }
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
  // border normalization over frequency: the triangle's taps n + 1 - |i| inside [0, bins)
  g.freq_norm.assign(static_cast<size_t>(g.bins), 0.0);
  for (int64_t k = 0; k < g.bins; ++k) {
    double inside = 0.0;
    const int64_t lo = std::max(-g.freq_bins, -k), hi = std::min(g.freq_bins, g.bins - 1 - k);
    for (int64_t i = lo; i <= hi; ++i) inside += static_cast<double>(g.freq_bins + 1 - std::abs(i));
    g.freq_norm[static_cast<size_t>(k)] = 1.0 / inside;
  }

  g.window = fftw::PeriodicHann(g.n_fft);
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
      g.Transform(row.data(), t_noise, f, s);
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

int SpectralGate::channels() const { return impl_->channels; }
int64_t SpectralGate::frames(int64_t n) const { return 1 + n / impl_->hop; }
int64_t SpectralGate::freq_smooth_bins() const { return impl_->freq_bins; }
int64_t SpectralGate::time_smooth_frames() const { return impl_->time_frames; }
const Eigen::MatrixXd& SpectralGate::threshold_db() const { return impl_->threshold_db; }
const SpectralGateConfig& SpectralGate::config() const { return impl_->config; }

void SpectralGate::Apply(const float* x, int64_t n, int channel, float* out) const {
  const Impl& g = *impl_;
  if (channel < 0 || channel >= g.channels) {
    throw Error(fmt::format("spectral gate: channel {} out of range [0, {})", channel, g.channels));
  }
  if (n < 1) throw Error(fmt::format("spectral gate: empty signal (n = {})", n));
  for (int64_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i])) {
      throw Error(fmt::format("spectral gate: non-finite sample ({}) at index {} of channel {}",
                              x[i], i, channel));
    }
  }
  auto lease = g.pool->Acquire();
  Impl::Scratch& s = *lease;
  const int64_t bins = g.bins, hop = g.hop, n_fft = g.n_fft;
  const int64_t nf = g.freq_bins, nt = g.time_frames;
  const int64_t frames = 1 + n / hop;
  // what depends on the length only: the time-border normalization of the smoothing and the
  // summed squared window of the overlap-add, per output sample
  if (s.cached_n != n) {
    s.time_norm.resize(static_cast<size_t>(frames));
    for (int64_t p = 0; p < frames; ++p) {
      double inside = 0.0;
      const int64_t lo = std::max(-nt, -p), hi = std::min(nt, frames - 1 - p);
      for (int64_t j = lo; j <= hi; ++j) inside += static_cast<double>(nt + 1 - std::abs(j));
      s.time_norm[static_cast<size_t>(p)] = 1.0 / inside;
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

  // pass 1: the STFT (kept for pass 2, so that x is read completely before out is written) and
  // its peak power, for the top_db floor of the dB spectrogram
  const size_t stft_size = static_cast<size_t>(bins * frames);
  if (s.spectra.size() < stft_size) s.spectra.resize(stft_size);
  double peak_power = kAminPower;
  for (int64_t f = 0; f < frames; ++f) {
    g.Transform(x, n, f, s);
    std::complex<double>* column = s.spectra.data() + f * bins;
    for (int64_t k = 0; k < bins; ++k) {
      const double re = s.spectrum[k][0], im = s.spectrum[k][1];
      column[k] = {re, im};
      s.power[k] = re * re + im * im;
    }
    peak_power =
        std::max(peak_power, Eigen::Map<const Eigen::ArrayXd>(s.power.data(), bins).maxCoeff());
  }
  // a bin passes when dB = max(10 log10(max(|X|^2, amin^2)), peak_dB - top_db) > threshold:
  // compared in power (monotone); where the floor itself exceeds the threshold every frame passes
  const double floor_db = 10.0 * std::log10(peak_power) - g.config.top_db;
  for (int64_t k = 0; k < bins; ++k) {
    s.pass_power[k] = floor_db > g.threshold_db(channel, k) ? -1.0 : g.threshold_power(channel, k);
  }
  const double keep = g.config.prop_decrease, base = 1.0 - g.config.prop_decrease;

  // pass 2, streaming over frames. Mask smoothing is separable, and a triangle of half width n
  // is two running boxes of n + 1 taps: over frequency within a frame, and over time as
  // box(q) = sum of smoothed(q .. q + n_t), mask(p) = sum of box(p - n_t .. p), updated by one
  // column entering and one leaving (rings of n_t + 2 columns). Outside the spectrogram the mask
  // is zero; each output is divided by the same sums over ones (the taps inside). Frame p's mask
  // is complete once frame p + n_t is in; then its masked spectrum goes through the inverse FFT
  // into the overlap-add, and the samples no later frame reaches go out.
  auto spectrum_of = [&](int64_t f) { return s.spectra.data() + f * bins; };
  auto smoothed_slot = [&](int64_t f) { return s.smoothed.data() + (f % (nt + 2)) * bins; };
  auto box_slot = [&](int64_t q) { return s.boxes.data() + ((q + nt) % (nt + 2)) * bins; };
  double* box_run = s.box_run.data();
  double* mask_run = s.mask_run.data();
  std::fill(box_run, box_run + bins, 0.0);
  std::fill(mask_run, mask_run + bins, 0.0);
  std::fill(s.overlap_add.begin(), s.overlap_add.end(), 0.0);
  const double scale = 1.0 / static_cast<double>(n_fft);
  for (int64_t q = -nt; q < frames; ++q) {
    // frame q + n_t: binary mask, smoothed over frequency, into the ring
    const int64_t f = q + nt;
    if (f < frames) {
      const std::complex<double>* spectrum = spectrum_of(f);
      // binary mask, zero-padded by nf + 1 bins on both sides: mask[k] at padded[k + nf + 1]
      double* padded = s.line.data();
      for (int64_t k = 0; k < bins; ++k) {
        // |X|^2 written out: std::norm goes through abs (hypot) without -ffast-math
        const double power =
            spectrum[k].real() * spectrum[k].real() + spectrum[k].imag() * spectrum[k].imag();
        const bool pass = std::max(power, kAminPower) > s.pass_power[k];
        padded[k + nf + 1] = (pass ? keep : 0.0) + base;
      }
      // box[b] = sum of mask[b .. b + nf] for b in [-nf - 1, bins), at boxes[b + nf + 1];
      // then m[k] = sum of box[k - nf .. k] (one add per value on each running chain)
      double* boxes = s.freq_boxes.data();
      double run = 0.0;
      boxes[0] = 0.0;
      for (int64_t b = -nf; b < bins; ++b) {
        run += padded[b + 2 * nf + 1] - padded[b + nf];
        boxes[b + nf + 1] = run;
      }
      double* m = smoothed_slot(f);
      run = 0.0;
      for (int64_t b = -nf; b < 0; ++b) run += boxes[b + nf + 1];
      for (int64_t k = 0; k < bins; ++k) {
        run += boxes[k + nf + 1] - boxes[k];
        m[k] = run * g.freq_norm[k];
      }
      for (int64_t k = 0; k < bins; ++k) box_run[k] += m[k];
    }
    // box(q) = box(q - 1) + smoothed(q + n_t) - smoothed(q - 1)
    if (q >= 1) {
      const double* leaving = smoothed_slot(q - 1);
      for (int64_t k = 0; k < bins; ++k) box_run[k] -= leaving[k];
    }
    // mask(q) = mask(q - 1) + box(q) - box(q - n_t - 1); box(q) replaces box(q - n_t - 2)
    double* box = box_slot(q);
    if (q >= 1) {
      const double* leaving = box_slot(q - nt - 1);
      for (int64_t k = 0; k < bins; ++k) mask_run[k] += box_run[k] - leaving[k];
    } else {
      for (int64_t k = 0; k < bins; ++k) mask_run[k] += box_run[k];
    }
    std::copy(box_run, box_run + bins, box);
    if (q < 0) continue;

    // frame q: masked spectrum -> inverse FFT -> windowed overlap-add
    const std::complex<double>* spectrum = spectrum_of(q);
    const double norm = s.time_norm[q];
    for (int64_t k = 0; k < bins; ++k) {
      const double mask = mask_run[k] * norm;
      s.spectrum[k][0] = spectrum[k].real() * mask;
      s.spectrum[k][1] = spectrum[k].imag() * mask;
    }
    fftw_execute_dft_c2r(g.inverse.get(), s.spectrum.data(), s.frame.data());
    double* acc = s.overlap_add.data();  // padded samples q hop .. q hop + n_fft
    for (int64_t k = 0; k < n_fft; ++k) acc[k] += s.frame[k] * g.window[k] * scale;
    // samples no later frame reaches are finished: normalize, trim the centre padding
    const int64_t done = q + 1 < frames ? hop : n_fft;
    for (int64_t k = 0; k < done; ++k) {
      const int64_t i = q * hop + k - g.half;
      if (i >= 0 && i < n) out[i] = static_cast<float>(acc[k] * s.inverse_window_sum[i]);
    }
    std::copy(acc + hop, acc + n_fft, acc);
    std::fill(acc + n_fft - hop, acc + n_fft, 0.0);
  }
}

}  // namespace sonicboom::acoustics
