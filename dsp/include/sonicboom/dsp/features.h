#pragma once
/// Strike features as the paper computes them, with the published code's faults fixed
/// (docs/reference.md, "Onset and window" to "Faults we fix"): onset from an all-channel energy
/// envelope, a window around it, stationary spectral gating against a reference noise clip
/// (spectral_gate.h), power mel spectrograms and GCC-PHAT without circular wrap-around.
/// DSP blocks are configured once (FFT plans, filterbanks) and computed many times.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/dsp/spectral_gate.h"

namespace sonicboom::dsp {

/// The audio input of a network: a mel spectrogram per channel (the paper), or the window's
/// samples themselves, one row per channel, which keep arrival times and phase to the sample
/// (n_fft, hop, n_mels, f_min_hz, f_max_hz and log_mel are then unused).
enum class AudioRepresentation { kMel, kWaveform };
inline constexpr EnumName<AudioRepresentation> kAudioRepresentationNames[] = {
    {AudioRepresentation::kMel, "mel"}, {AudioRepresentation::kWaveform, "waveform"}};
inline std::span<const EnumName<AudioRepresentation>> EnumNames(AudioRepresentation) {
  return kAudioRepresentationNames;
}

struct FeatureConfig {
  double window_s{1.5};  // analysis window, onset at its centre
  AudioRepresentation audio_representation{AudioRepresentation::kMel};
  int64_t n_fft{512};    // mel STFT size = window length (periodic Hann)
  int64_t hop{128};
  int64_t n_mels{50};  // HTK mel, norm none
  double f_min_hz{0.0};
  double f_max_hz{0.0};      // 0 = Nyquist
  bool log_mel{false};       // paper: power mel, no log; log10(power + 1e-10) when true
  int64_t gcc_max_lag{441};  // lags -max..+max samples (883 values)
  double gcc_window_s{0.0};  // GCC-PHAT over this span centred on the onset (the centre
                             // of the window); 0 = the whole window (the paper)
  // band-limited GCC-PHAT: edges of contiguous bands (cos^2 weights in log frequency, half
  // power at the edges); each pair gives one row per band. Empty = one full-band row per pair
  std::vector<double> gcc_bands_hz;
  double onset_frame_s{0.0029};  // energy-envelope frame (~128 samples at 44.1 kHz)
  double onset_threshold{0.1};   // fraction of the envelope peak that marks the onset
  // stationary spectral gating of the window against a reference noise clip (spectral_gate.h),
  // per channel, before mel/GCC-PHAT; noisereduce's defaults (docs/reference.md, "Spectral gating")
  bool gating{true};
  double gating_n_std{2.5};             // threshold: mean + n_std * std of the noise dB, per bin
  int64_t gating_n_fft{1024};           // gate STFT size (periodic Hann), <= window samples
  int64_t gating_hop{256};              // in [1, gating_n_fft / 2]
  double gating_freq_smooth_hz{500.0};  // mask smoothing span (5 bins each side at 44.1 kHz)
  double gating_time_smooth_s{0.05};    // mask smoothing span (8 frames each side)
  double gating_prop_decrease{1.0};     // 1: gated bins removed; 0: gate is a no-op
  // reference noise clip: a WAV (hardware: a no-contact recording at the audio rate, one
  // channel per mic); empty = rendered from the noise model (experiments ReferenceNoiseClip)
  std::string gating_noise_wav;

  void Serialize(Archive* a);
  /// GCC-PHAT's span in seconds: gcc_window_s, or window_s when that is 0.
  double gcc_span_s() const { return gcc_window_s > 0.0 ? gcc_window_s : window_s; }
};

/// Features of one strike. Shapes: mel (C x n_mels x frames, or C x 1 x samples for the
/// waveform representation), gcc (C(C-1)/2 x 2*max_lag+1).
struct StrikeFeatures {
  int64_t onset_sample{0};     // onset in the input record, samples
  int64_t window_start{0};     // first input sample of the window (may be negative: zero-padded)
  int64_t mel_first_frame{0};  // frame of the whole-window spectrogram that mel[c] starts at
  std::vector<Eigen::MatrixXf> mel;  // per channel (audio_rows x frames); empty when not requested
  Eigen::MatrixXf gcc;               // (pairs x bands, lags), pairs in itertools.combinations
                                     // order, bands within a pair; 0 x 0 when not requested
};

/// What one FeatureExtractor::Compute call produces; the rest is not computed. The default is
/// everything, as datasets store it; a localizer asks only for what its model reads. The gate
/// runs when mel or GCC-PHAT is asked for, always over the whole window, so that a part equals
/// the same part of the whole.
struct FeatureRequest {
  bool mel{true};
  bool gcc{true};
  int64_t mel_first_frame{0};  // first frame of the whole-window spectrogram
  int64_t mel_frames{-1};      // frames from mel_first_frame; -1: through the last frame
};

/// Row-major float matrix: one contiguous row per channel.
using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// The gate parameters of a feature config (the gating_* keys).
SpectralGateConfig GatingConfig(const FeatureConfig& config);

/// Computes StrikeFeatures from a (C x T) record: onset, window, spectral gating (when enabled),
/// mel per channel, GCC-PHAT. Immutable after construction; Compute is const and thread-safe
/// (per-call scratch comes from an internal per-thread pool).
class FeatureExtractor {
 public:
  /// Without gating.
  FeatureExtractor(const FeatureConfig& config, double sample_rate_hz, int channels);
  /// Gates every window against `noise_clip` ((channels x T) reference noise at the same rate,
  /// T >= gating_n_fft) when config.gating is true and noise_clip is not null; otherwise no
  /// gating. Throws ConfigError naming the key or the clip's problem (channel count, length,
  /// non-finite values).
  FeatureExtractor(const FeatureConfig& config, double sample_rate_hz, int channels,
                   const Eigen::MatrixXf* noise_clip);
  ~FeatureExtractor();
  FeatureExtractor(const FeatureExtractor&) = delete;
  FeatureExtractor& operator=(const FeatureExtractor&) = delete;

  /// Features of a (C x T) record; `request` picks the parts (all by default). Throws Error
  /// for a wrong channel count or a mel frame range outside [0, mel_frames()].
  StrikeFeatures Compute(const Eigen::MatrixXf& audio, const FeatureRequest& request = {}) const;

  int64_t window_samples() const;  // round(window_s * fs)
  int64_t mel_frames() const;      // 1 + window_samples / hop (centred, reflect-padded), or
                                   // window_samples for the waveform representation
  int64_t audio_rows() const;      // n_mels, or 1 for the waveform representation
  int64_t frame_hop() const;       // input samples between frames: hop, or 1 for a waveform
  int64_t gcc_lags() const;        // 2 * gcc_max_lag + 1
  int64_t gcc_rows() const;        // pairs x bands (bands = 1 without gcc_bands_hz)
  int64_t gcc_samples() const;     // GCC-PHAT span: round(config.gcc_span_s() * fs)
  int channels() const;
  /// The gate applied to each window, or null when gating is off.
  const SpectralGate* gate() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Lower-level blocks, exposed for tests and the hardware path.

/// Power mel spectrogram of one channel, torchaudio.transforms.MelSpectrogram semantics:
/// periodic Hann, center=True with reflect padding, power 2, HTK mel, norm none.
class MelSpectrogram {
 public:
  MelSpectrogram(int64_t n_fft, int64_t hop, int64_t n_mels, double f_min_hz, double f_max_hz,
                 double sample_rate_hz);
  ~MelSpectrogram();
  MelSpectrogram(const MelSpectrogram&) = delete;
  MelSpectrogram& operator=(const MelSpectrogram&) = delete;
  int64_t Frames(int64_t n) const;  // 1 + n / hop
  /// x: n samples; out: (n_mels x Frames(n)), resized if needed.
  void Compute(const float* x, int64_t n, Eigen::MatrixXf* out) const;
  /// Frames [first_frame, first_frame + frames) of the same spectrogram only; out:
  /// (n_mels x frames). Throws Error unless 0 <= first_frame <= first_frame + frames <= Frames(n).
  void Compute(const float* x, int64_t n, int64_t first_frame, int64_t frames,
               Eigen::MatrixXf* out) const;
  /// (n_mels x n_fft/2+1) triangular filterbank.
  const Eigen::MatrixXf& filterbank() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// GCC-PHAT of all channel pairs over a window of n samples, zero-padded to avoid circular
/// wrap-around. Row p is pair p in combinations order; column j is lag (j - max_lag) samples;
/// a positive lag means the first channel of the pair receives later. Computed in single
/// precision. With bands, the PHAT-weighted cross spectrum is weighted by each band in turn
/// (cos^2 in log frequency): row p * bands + b is pair p in band b.
class GccPhat {
 public:
  GccPhat(int64_t n, int64_t max_lag, int channels);
  /// band_edges_hz: contiguous band edges at sample_rate_hz (empty: the full band). Throws
  /// ConfigError naming features.gcc_bands_hz for bad edges.
  GccPhat(int64_t n, int64_t max_lag, int channels, double sample_rate_hz,
          const std::vector<double>& band_edges_hz);
  /// Rows of the output: pairs x bands.
  int64_t rows() const;
  ~GccPhat();
  GccPhat(const GccPhat&) = delete;
  GccPhat& operator=(const GccPhat&) = delete;
  /// window: (C x n); out: (rows() x 2*max_lag+1), resized if needed.
  void Compute(const Eigen::Ref<const RowMatrixXf>& window, Eigen::MatrixXf* out) const;
  /// FFT size: the smallest multiple of 512 >= n + max_lag whose other prime factors are 2, 3
  /// and 5 (the PHAT weights, and so the output, depend on it).
  int64_t fft_size() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Onset: first frame where the all-channel energy envelope exceeds threshold * its peak and
/// stands kOnsetOverFloorDb above the record's median frame (the noise floor: at 20-25 dB
/// peak-to-noise the floor's own frames reach threshold * peak, and the window centred on the
/// first of them missed the strike). Returns the onset in samples.
inline constexpr double kOnsetOverFloorDb = 6.0;
int64_t DetectOnset(const Eigen::MatrixXf& audio, double sample_rate_hz, double frame_s,
                    double threshold);

/// The rule CheckStrike applies (docs/robustness.md, "No strike"). A strike is an impulse: on
/// some channel (about its mean) its peak stands min_db above the channel's noise RMS, and it
/// rises: within rise_window_s of its onset the channel reaches within near_peak_db of the
/// loudest it gets in the follow_window_s after the onset, a level min_db above the RMS of the
/// pre_window_s before the onset (a motor ramp or mains hum does not: their level just before is
/// within a few dB of their peaks, and a ramp keeps rising). The peak is the strike's own, not
/// the record's: an arm motion louder than the strike elsewhere in the record does not hide it.
struct StrikeRule {
  // 17 dB: Gaussian noise over 88 200 samples x 6 channels peaks at about 5 sigma (14 dB), and
  // reaches 7.1 sigma (17 dB) in under one record in a million; a strike 20 dB above the noise
  // stays above 17 dB with its one sample of noise against it in 99.8 % of records
  double min_db{17.0};
  double rise_window_s{0.005};   // a contact of up to 5 ms reaches its force peak in 2.5 ms
  double near_peak_db{6.0};      // the first arrival against later reflections' build-up
  // the strike's own peak: the loudest this long after its onset (a strike has rung down by
  // then; a motor ramp of 0.1 s or more has not reached its top)
  double follow_window_s{0.1};
  double pre_window_s{0.02};     // the level before the onset (one 50 Hz period)
  double noise_frame_s{0.02};    // the noise RMS: the median of these frames' RMS values
  double min_after_s{0.02};      // record left after the onset (a strike cut off at the end)
  double hop_s{0.0005};          // onsets tried every hop_s
};

/// Whether a record holds a strike at all, by `rule` (audio: C x T at sample_rate_hz); the
/// strike is the first onset that passes (a later swell is not it). Noise, hum or arm motion
/// alone, DC alone, or a strike cut off at the record's end (or one in its first pre_window_s)
/// fail, with `reason` giving the measured dB or the time left, and the rule.
struct StrikeCheck {
  bool found{false};
  double peak_to_noise_db{0.0};  // the loudest channel's peak over its noise RMS, dB (amplitude)
  // the strike's rise: the peak its onset window reaches over the RMS before it, dB; when none
  // passes, the best rise of the channels whose peak stands min_db above their noise (0: none)
  double rise_db{0.0};
  int channel{-1};          // the channel that rises first (-1: no strike)
  int64_t onset_sample{0};  // its onset: the window's first sample reaching half its peak
  std::string reason;       // empty when found
};
StrikeCheck CheckStrike(const Eigen::MatrixXf& audio, double sample_rate_hz,
                        const StrikeRule& rule = {});

}  // namespace sonicboom::dsp
