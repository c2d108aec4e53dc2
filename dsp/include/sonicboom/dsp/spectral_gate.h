#pragma once
/// Stationary spectral gating against a reference noise clip: the reference pipeline's
/// noisereduce.reduce_noise(stationary=True) step (docs/reference.md, "Spectral gating"), with
/// per-channel noise statistics. Per frequency bin the threshold is mean + n_std * std (over the
/// clip's frames) of the clip's STFT magnitude in dB; a signal bin passes when its dB exceeds the
/// threshold; the binary mask is smoothed by a normalized triangular kernel over frequency x time,
/// multiplies the STFT, and the inverse STFT gives the gated signal. Configured once (FFT plans,
/// thresholds, kernel); Apply is const, thread-safe and allocation-free in steady state.

#include <Eigen/Core>
#include <cstdint>
#include <memory>

namespace sonicboom::dsp {

/// Gate parameters (the features.gating_* keys, see FeatureConfig). Defaults: noisereduce's.
struct SpectralGateConfig {
  int64_t n_fft{1024};           // STFT size = window length (periodic Hann), centred, reflect pad
  int64_t hop{256};              // in [1, n_fft / 2]
  double n_std{2.5};             // threshold = mean_dB + n_std * std_dB of the noise, per bin
  double freq_smooth_hz{500.0};  // mask smoothing: floor(hz / (fs / (n_fft / 2))) bins each side
  double time_smooth_s{0.05};    // mask smoothing: floor(s * fs / hop) frames each side
  double prop_decrease{1.0};     // mask = prop * binary + (1 - prop): 1 removes gated bins, 0 = off
  double top_db{80.0};           // dB = max(20 log10(max(|X|, 1e-20)), peak_dB - top_db), per
                                 // spectrogram (librosa amplitude_to_db, ref 1)
};

/// Spectral gate for `channels` channels; channel c is gated against row c of the noise clip.
///
/// Conventions: STFT as librosa/torch with center=True and reflect padding, 1 + n / hop frames;
/// the inverse is overlap-add with the same window, normalized by the summed squared window, so a
/// mask of ones reproduces the input to round-off. The smoothing kernel is the outer product of
/// two triangles (2 n_f + 1 bins by 2 n_t + 1 frames, n_f and n_t from the smoothing spans as
/// noisereduce derives them: 5 bins and 8 frames at 44.1 kHz, 1024 / 256, 500 Hz, 50 ms),
/// normalized to sum 1. At the spectrogram's borders (lowest and highest bins, first and last
/// frames) it is renormalized over the taps that fall inside, so that a mask of ones stays ones;
/// noisereduce convolves with zero padding there instead, which attenuates those bins even
/// when everything passes (bin 0 to 0.58).
class SpectralGate {
 public:
  /// noise_clip: (channels x T) reference noise, T >= n_fft samples, finite. Throws ConfigError
  /// naming the parameter or the problem with the clip (too short, no channels, non-finite).
  SpectralGate(const SpectralGateConfig& config, const Eigen::MatrixXf& noise_clip,
               double sample_rate_hz);
  ~SpectralGate();
  SpectralGate(const SpectralGate&) = delete;
  SpectralGate& operator=(const SpectralGate&) = delete;

  /// Gates x (n >= 1 samples) against channel `channel`'s noise statistics into out (n samples;
  /// out may equal x). Throws Error for a channel out of range, n < 1, or a non-finite sample.
  void Apply(const float* x, int64_t n, int channel, float* out) const;

  int channels() const;
  int64_t frames(int64_t n) const;     // STFT frames of n samples: 1 + n / hop
  int64_t freq_smooth_bins() const;    // n_f: kernel half width in bins
  int64_t time_smooth_frames() const;  // n_t: kernel half width in frames
  /// Threshold per channel and frequency bin, dB: (channels x n_fft / 2 + 1).
  const Eigen::MatrixXd& threshold_db() const;
  const SpectralGateConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::dsp
