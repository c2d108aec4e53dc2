#include "sonicboom/acoustics/daq.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::acoustics {
namespace {


// entry c of a per-channel list, or the scalar when the list is empty
double PerChannel(const std::vector<double>& list, double scalar, int c) {
  return list.empty() ? scalar : list[static_cast<size_t>(c)];
}

void CheckChannelList(const std::vector<double>& list, const char* key, int channels) {
  if (!list.empty() && static_cast<int>(list.size()) != channels) {
    throw ConfigError(fmt::format("daq.{} has {} entries; it needs one per microphone ({}) or none",
                                  key, list.size(), channels));
  }
}

}  // namespace

void DaqConfig::Serialize(Archive* a) {
  a->Visit("sensitivity_v_per_strain", &sensitivity_v_per_strain, Bounds::Positive());
  a->Visit("gain_mismatch_db", &gain_mismatch_db, Bounds::Closed(0.0, 20.0));
  a->Visit("input_resistance_ohm", &input_resistance_ohm, Bounds::Positive());
  a->Visit("disc_capacitance_f", &disc_capacitance_f, Bounds::Positive());
  a->Visit("preamp_noise_v", &preamp_noise_v, Bounds::NonNegative());
  a->Visit("full_scale_v", &full_scale_v, Bounds::Positive());
  a->Visit("adc_bits", &adc_bits, Bounds::Closed(8, 32));
  a->Visit("output_bits", &output_bits, Bounds::Closed(8, 32));
  a->Visit("channel_gain_db", &channel_gain_db, Bounds::Closed(-60.0, 60.0));
  a->Visit("channel_input_resistance_ohm", &channel_input_resistance_ohm, Bounds::Positive());
  a->Visit("channel_capacitance_f", &channel_capacitance_f, Bounds::Positive());
  a->Visit("channel_preamp_noise_v", &channel_preamp_noise_v, Bounds::NonNegative());
}

void DaqConfig::Validate(int channels) const {
  CheckChannelList(channel_gain_db, "channel_gain_db", channels);
  CheckChannelList(channel_input_resistance_ohm, "channel_input_resistance_ohm", channels);
  CheckChannelList(channel_capacitance_f, "channel_capacitance_f", channels);
  CheckChannelList(channel_preamp_noise_v, "channel_preamp_noise_v", channels);
  if (output_bits > adc_bits) {
    throw ConfigError(
        fmt::format("daq.output_bits = {} exceeds daq.adc_bits = {}", output_bits, adc_bits));
  }
}

double DaqConfig::highpass_hz(int channel) const {
  const double r = PerChannel(channel_input_resistance_ohm, input_resistance_ohm, channel);
  const double c = PerChannel(channel_capacitance_f, disc_capacitance_f, channel);
  return 1.0 / (2 * kPi * r * c);
}

void NoiseConfig::Serialize(Archive* a) {
  a->Visit("ambient_rms_v", &ambient_rms_v, Bounds::NonNegative());
  a->Visit("motor_rms_v_per_rad_s", &motor_rms_v_per_rad_s, Bounds::NonNegative());
  a->Visit("motor_base_hz", &motor_base_hz, Bounds::Positive());
  a->Visit("motor_harmonics", &motor_harmonics, Bounds::Closed(0, 64));
  a->Visit("foliage_force_rms_n", &foliage_force_rms_n, Bounds::NonNegative());
  a->Visit("foliage_low_hz", &foliage_low_hz, Bounds::Positive());
  a->Visit("foliage_high_hz", &foliage_high_hz, Bounds::Positive());
  a->Visit("wav_files", &wav_files);
  a->Visit("wav_gain", &wav_gain, Bounds::NonNegative());
}

void NoiseConfig::Validate() const {
  if (!(foliage_low_hz < foliage_high_hz)) {
    throw ConfigError(
        fmt::format("noise.foliage_low_hz = {} must be below noise.foliage_high_hz = {}",
                    foliage_low_hz, foliage_high_hz));
  }
}

struct DaqChain::Impl {
  DaqConfig daq;
  NoiseConfig noise;
  int channels{0};
  double fs{0.0};
  int64_t record_samples{0};
  Eigen::VectorXd preamp_noise_v;           // (channels)
  std::vector<Eigen::MatrixXf> recordings;  // each (channels x frames), full scale units
};

DaqChain::DaqChain(const DaqConfig& daq, const NoiseConfig& noise, int channels,
                   double sample_rate_hz, int64_t record_samples)
    : impl_(std::make_unique<Impl>()) {
  daq.Validate(channels);
  noise.Validate();
  Impl& m = *impl_;
  m.daq = daq;
  m.noise = noise;
  m.channels = channels;
  m.fs = sample_rate_hz;
  m.record_samples = record_samples;
  // first-order high-pass of disc capacitance into the preamp input, per channel: below Nyquist
  m.preamp_noise_v.resize(channels);
  for (int c = 0; c < channels; ++c) {
    const double fc = daq.highpass_hz(c);
    if (!(fc < 0.5 * sample_rate_hz)) {
      throw ConfigError(
          fmt::format("daq: channel {} high-pass corner {} Hz (1 / 2 pi R C) is not "
                      "below the Nyquist frequency {} Hz",
                      c, fc, 0.5 * sample_rate_hz));
    }
    m.preamp_noise_v[c] = PerChannel(daq.channel_preamp_noise_v, daq.preamp_noise_v, c);
  }
  // recorded background: checked and held in memory once
  for (const std::string& path : noise.wav_files) {
    AudioClip clip = ReadWav(path);
    if (std::abs(clip.sample_rate_hz - sample_rate_hz) > 1e-6) {
      throw ConfigError(
          fmt::format("noise.wav_files: {} is sampled at {} Hz; audio.sample_rate_hz "
                      "is {} Hz (resample it first)",
                      path, clip.sample_rate_hz, sample_rate_hz));
    }
    if (clip.channels() != 1 && clip.channels() != channels) {
      throw ConfigError(fmt::format("noise.wav_files: {} has {} channels; it needs 1 or {}", path,
                                    clip.channels(), channels));
    }
    if (clip.frames() < record_samples) {
      throw ConfigError(
          fmt::format("noise.wav_files: {} has {} frames, shorter than one record "
                      "({} frames)",
                      path, clip.frames(), record_samples));
    }
    if (clip.channels() == 1) clip.samples = clip.samples.replicate(channels, 1).eval();
    m.recordings.push_back(std::move(clip.samples));
  }
}

DaqChain::~DaqChain() = default;

const DaqConfig& DaqChain::daq() const {
  return impl_->daq;
}

namespace {

// mains hum over n samples at fs: harmonics k = 1.. of f0 with amplitudes 1/k and the given
// phases, scaled to rms_v (harmonics at or above Nyquist left out); volts
Eigen::ArrayXd HumSignal(int64_t n, double fs, double f0_hz, double rms_v,
                         const std::vector<double>& phase_rad) {
  Eigen::ArrayXd hum = Eigen::ArrayXd::Zero(n);
  double power = 0.0;  // mean square of the unit-scaled sum
  for (size_t h = 0; h < phase_rad.size(); ++h) {
    const double k = static_cast<double>(h + 1);
    if (k * f0_hz >= 0.5 * fs) break;
    const double amp = 1.0 / k;
    power += 0.5 * amp * amp;
    // unit phasor advanced by hand each sample
    const double w = 2 * kPi * k * f0_hz / fs;
    const double sr = std::cos(w), si = std::sin(w);
    double pr = std::cos(phase_rad[h]), pi = std::sin(phase_rad[h]);
    for (int64_t t = 0; t < n; ++t) {
      hum[t] += amp * pi;
      const double r = pr * sr - pi * si;
      pi = pr * si + pi * sr;
      pr = r;
    }
  }
  if (power > 0.0) hum *= rms_v / std::sqrt(power);
  return hum;
}

// One second-order section (direct form I): y = b0 x + b1 x1 + b2 x2 - a1 y1 - a2 y2.
struct Section {
  double b0, b1, b2, a1, a2;
  void Run(Eigen::Ref<Eigen::ArrayXd> x) const {
    double x1 = 0, x2 = 0, y1 = 0, y2 = 0;
    for (Eigen::Index k = 0; k < x.size(); ++k) {
      const double y = b0 * x[k] + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
      x2 = x1;
      x1 = x[k];
      y2 = y1;
      y1 = y;
      x[k] = y;
    }
  }
};

// the disc's RC high-pass at corner fc (bilinear, first order), in place
void FirstOrderHighPass(double fc, double fs, Eigen::Ref<Eigen::ArrayXd> v) {
  const double kk = std::tan(kPi * fc / fs);
  const double b0 = 1.0 / (1.0 + kk), a1 = (kk - 1.0) / (kk + 1.0);
  double x_prev = 0, y_prev = 0;
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    const double x = v[k];
    const double y = b0 * (x - x_prev) - a1 * y_prev;
    x_prev = x;
    y_prev = y;
    v[k] = y;
  }
}

// bilinear second-order Butterworth high-pass at corner fc; the low-pass of either order
Section ButterworthHighPass(double fc, double fs) {
  const double kk = std::tan(kPi * fc / fs);
  const double n = 1 / (1 + std::numbers::sqrt2 * kk + kk * kk);
  return {n, -2 * n, n, 2 * (kk * kk - 1) * n, (1 - std::numbers::sqrt2 * kk + kk * kk) * n};
}
Section LowPass(double fc, double fs, int order) {
  const double kk = std::tan(kPi * fc / fs);
  if (order == 1) return {kk / (1 + kk), kk / (1 + kk), 0, (kk - 1) / (kk + 1), 0};
  const double n = 1 / (1 + std::numbers::sqrt2 * kk + kk * kk);
  return {kk * kk * n, 2 * kk * kk * n, kk * kk * n, 2 * (kk * kk - 1) * n,
          (1 - std::numbers::sqrt2 * kk + kk * kk) * n};
}

}  // namespace

void ApplyChainFilters(double highpass_hz, const ChainDraw& chain, double fs,
                       Eigen::Ref<Eigen::ArrayXd> v) {
  for (const double fc : {highpass_hz, chain.lowpass_hz}) {
    if (fc > 0.0 && !(fc < 0.5 * fs)) {
      throw ConfigError(fmt::format("the sensor chain's filter corner {} Hz (randomize.highpass_hz "
                                    "or randomize.lowpass_hz) is not below the Nyquist frequency "
                                    "{} Hz",
                                    fc, 0.5 * fs));
    }
  }
  if (chain.highpass_order == 1) {
    FirstOrderHighPass(highpass_hz, fs, v);
  } else {
    ButterworthHighPass(highpass_hz, fs).Run(v);
  }
  if (chain.lowpass_hz > 0.0) LowPass(chain.lowpass_hz, fs, chain.lowpass_order).Run(v);
}

bool DaqChain::Convert(const Eigen::MatrixXd& strain, std::span<const double> joint_speed_rad_s,
                       double joint_speed_rate_hz, uint64_t sample_seed, Eigen::MatrixXf* audio,
                       const ChainDraw& chain) const {
  const Impl& m = *impl_;
  SONICBOOM_DEMAND(strain.rows() == m.channels);
  const int64_t num_frames = strain.cols();
  const double T = 1.0 / m.fs;
  Rng rng(sample_seed, Stream::kDaq);
  Rng noise_rng(sample_seed, Stream::kNoise);

  // motor and gear tones (volts per unit channel gain, T samples), following the joint speed:
  // each harmonic a unit phasor advanced by one rotation per sample
  const int64_t harmonics = m.noise.motor_harmonics;
  std::vector<double> phase(harmonics), channel_gain(m.channels);
  for (auto& p : phase) p = noise_rng.Uniform(0, 2 * kPi);
  for (auto& g : channel_gain) g = noise_rng.Uniform(0.5, 1.5);
  Eigen::ArrayXd motor = Eigen::ArrayXd::Zero(num_frames);
  if (harmonics > 0 && m.noise.motor_rms_v_per_rad_s > 0 && !joint_speed_rad_s.empty()) {
    const double tone_amp = std::sqrt(2.0 / harmonics) * m.noise.motor_rms_v_per_rad_s;
    // phasors as (re, im) pairs rotated by hand (std::complex products call a NaN-safe helper)
    std::vector<double> pr(harmonics), pi(harmonics), sr(harmonics), si(harmonics);
    for (int64_t hm = 0; hm < harmonics; ++hm) {
      pr[hm] = std::cos(phase[hm]);
      pi[hm] = std::sin(phase[hm]);
      const double w = 2 * kPi * m.noise.motor_base_hz * (hm + 1) * T;
      sr[hm] = std::cos(w);
      si[hm] = std::sin(w);
    }
    const double rate = T * joint_speed_rate_hz;  // joint-speed rows per audio sample
    const size_t last = joint_speed_rad_s.size() - 1;
    for (int64_t k = 0; k < num_frames; ++k) {
      const double pos = k * rate;
      const size_t idx = std::min(static_cast<size_t>(pos), last);
      const size_t nxt = std::min(idx + 1, last);
      const double frac = std::clamp(pos - static_cast<double>(idx), 0.0, 1.0);
      const double speed = (1 - frac) * joint_speed_rad_s[idx] + frac * joint_speed_rad_s[nxt];
      double sum = 0.0;
      for (int64_t hm = 0; hm < harmonics; ++hm) {
        sum += pi[hm];
        const double r = pr[hm] * sr[hm] - pi[hm] * si[hm];
        pi[hm] = pr[hm] * si[hm] + pi[hm] * sr[hm];
        pr[hm] = r;
      }
      motor[k] = tone_amp * speed * sum;
    }
  }

  // recorded background (already through a real DAQ): one file and offset per strike
  const Eigen::MatrixXf* rec = nullptr;
  int64_t rec_offset = 0, rec_span = 0;
  if (!m.recordings.empty()) {
    rec = &m.recordings[noise_rng.UniformInt(m.recordings.size())];
    rec_span = std::min<int64_t>(num_frames, rec->cols());
    rec_offset = static_cast<int64_t>(
        noise_rng.UniformInt(static_cast<uint64_t>(rec->cols() - rec_span + 1)));
  }

  // this sample's sensor chain: hum, record level and converter full scale
  Eigen::ArrayXd hum;
  if (chain.hum_rms_v > 0.0) {
    hum = HumSignal(num_frames, m.fs, chain.hum_hz, chain.hum_rms_v, chain.hum_phase_rad);
  }
  const double level = std::pow(10.0, chain.record_level_db / 20.0);
  const double full_scale_v = m.daq.full_scale_v * chain.full_scale_scale;

  const double adc_step = 1.0 / (std::ldexp(1.0, static_cast<int>(m.daq.adc_bits) - 1) - 1);
  const double out_step = 1.0 / (std::ldexp(1.0, static_cast<int>(m.daq.output_bits) - 1) - 1);
  audio->resize(m.channels, num_frames);
  bool clipped = false;
  // the piezo volts of every channel through its input filters (T x C, a channel a column)
  Eigen::ArrayXXd filtered(num_frames, m.channels);
  for (int i = 0; i < m.channels; ++i) {
    // piezo volts with the channel's gain (a fixed offset, or a mismatch drawn per strike)
    const size_t ci = static_cast<size_t>(i);
    double gain_db = 0.0;
    if (!chain.channel_gain_db.empty()) {
      gain_db = chain.channel_gain_db[ci];
    } else {
      gain_db = m.daq.channel_gain_db.empty() ? rng.Normal() * m.daq.gain_mismatch_db
                                              : m.daq.channel_gain_db[ci];
    }
    const double bonding = chain.sensitivity_scale.empty() ? 1.0 : chain.sensitivity_scale[ci];
    auto v = filtered.col(i);
    v = strain.row(i).transpose().array() *
            (m.daq.sensitivity_v_per_strain * bonding * std::pow(10.0, gain_db / 20.0)) +
        channel_gain[ci] * motor;
    const double corner_hz = chain.highpass_hz.empty() ? m.daq.highpass_hz(i)
                                                        : chain.highpass_hz[ci];
    ApplyChainFilters(corner_hz, chain, m.fs, v);
  }
  // a floor set by the strike's level: its peak over all channels, this many dB above the rms
  const double floor_by_peak_v =
      chain.peak_to_noise_db >= 0.0
          ? filtered.abs().maxCoeff() * std::pow(10.0, -chain.peak_to_noise_db / 20.0)
          : -1.0;
  Eigen::ArrayXd v(num_frames);  // one channel's volts, contiguous
  for (int i = 0; i < m.channels; ++i) {
    const size_t ci = static_cast<size_t>(i);
    // the ambient floor and the preamp noise are white, so they join after the input filters as
    // one draw (the 10 Hz corner removes a negligible part of white noise)
    const double noise_v = floor_by_peak_v >= 0.0       ? floor_by_peak_v
                           : chain.noise_floor_v >= 0.0 ? chain.noise_floor_v
                               : std::hypot(m.noise.ambient_rms_v, m.preamp_noise_v[i]);
    for (int64_t k = 0; k < num_frames; ++k) {
      v[k] = filtered(k, i) + noise_v * noise_rng.NoiseSample();
    }
    // mains hum picked up by the channel's cable, then the record level of the whole channel
    if (hum.size() > 0) v += chain.hum_channel_scale[ci] * hum;
    if (level != 1.0) v *= level;
    if (rec != nullptr) {
      v.head(rec_span) +=
          rec->row(i).segment(rec_offset, rec_span).transpose().cast<double>().array() *
          (m.noise.wav_gain * full_scale_v);
    }
    // converter: clip at full scale, quantize to the ADC, then to the output word length
    v /= full_scale_v;
    if (!v.isFinite().all()) {
      Eigen::Index k = 0;
      while (std::isfinite(v[k])) ++k;
      throw NumericalError(fmt::format("non-finite audio at mic {} sample {}", i, k));
    }
    if ((v.abs() >= 1.0).any()) clipped = true;
    v = v.max(-1.0).min(1.0);
    // round to nearest by the 1.5 * 2^52 trick, vectorized (|v| <= 2^31 steps here)
    constexpr double kMagic = 6755399441055744.0;
    v = ((v * (1.0 / adc_step) + kMagic) - kMagic) * (adc_step / out_step);
    v = ((v + kMagic) - kMagic) * out_step;
    audio->row(i) = v.cast<float>().transpose().matrix();
  }
  return clipped;
}

Eigen::MatrixXf NoiseModelClip(const DaqChain& daq, int channels, int64_t frames,
                               std::span<const double> joint_speed_rad_s,
                               double joint_speed_rate_hz, uint64_t seed) {
  // kReferenceNoiseRecords records end to end, each with its own draw of the sensor chain
  Eigen::MatrixXf clip(channels, kReferenceNoiseRecords * frames);
  Eigen::MatrixXf audio;
  for (int64_t r = 0; r < kReferenceNoiseRecords; ++r) {
    daq.Convert(Eigen::MatrixXd::Zero(channels, frames), joint_speed_rad_s, joint_speed_rate_hz,
                SampleSeed(seed, kReferenceNoiseIndex - r), &audio);
    clip.middleCols(r * frames, frames) = audio;
  }
  return clip;
}

}  // namespace sonicboom::acoustics
