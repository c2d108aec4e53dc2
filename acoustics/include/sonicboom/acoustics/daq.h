#pragma once
/// The converter end of the signal chain, shared by every vibration model: piezo volts from
/// surface strain with per-channel sensitivity, structure-borne background (motor and gear tones
/// tied to joint speed, ambient floor, recorded noise from WAV files), the first-order high-pass
/// of disc capacitance into the preamp input, preamp noise, and a clipping 24-bit converter with
/// 16-bit output (in the order of docs/physics.md, "Sensor and DAQ chain"). Configured once
/// (filters, recordings loaded); Convert is const and allocates only its output.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/core/archive.h"

namespace sonicboom::acoustics {

/// Piezo disc, preamp and converter. Per-channel lists override the scalar for that channel;
/// an empty list means every channel takes the scalar.
struct DaqConfig {
  double sensitivity_v_per_strain{2000.0};  // open-circuit volts per unit surface strain
  double gain_mismatch_db{1.0};        // per-channel gain spread (std dev, dB), drawn per strike
  double input_resistance_ohm{1.0e6};  // with the disc capacitance sets the high-pass
  double disc_capacitance_f{16e-9};
  double preamp_noise_v{2e-5};  // white, rms
  double full_scale_v{1.0};     // ADC full scale
  int64_t adc_bits{24};
  int64_t output_bits{16};  // the paper's recordings were 16-bit PCM
  // per channel (mics entries each, or empty)
  std::vector<double> channel_gain_db;  // fixed gain offsets; replaces the random mismatch
  std::vector<double> channel_input_resistance_ohm;
  std::vector<double> channel_capacitance_f;
  std::vector<double> channel_preamp_noise_v;

  void Serialize(Archive* a);
  /// Throws ConfigError naming the key when a per-channel list does not have `channels` entries.
  void Validate(int channels) const;
  /// High-pass corner of channel c, Hz: 1 / (2 pi R C).
  double highpass_hz(int channel = 0) const;
};

/// Background vibration picked up by the discs.
struct NoiseConfig {
  double ambient_rms_v{3e-5};          // broadband floor, rms
  double motor_rms_v_per_rad_s{3e-3};  // motor and gear tones, rms per rad/s of joint speed
  double motor_base_hz{110.0};         // fundamental of the gear tones
  int64_t motor_harmonics{8};
  // foliage brushing (canopy scenes): a random radial force at the brushed point
  double foliage_force_rms_n{0.05};  // rms force while leaves sweep the tube
  double foliage_low_hz{200.0};      // band of the rustle force
  double foliage_high_hz{4000.0};
  // recorded background: WAV files at the audio rate, 1 channel (to all) or one per mic, in
  // converter full-scale units; each strike takes one file and offset from its seed
  std::vector<std::string> wav_files;
  double wav_gain{1.0};  // scale applied to the recording

  void Serialize(Archive* a);
  void Validate() const;
};

/// Immutable converter chain for `channels` mics at the audio rate; thread-safe to share.
class DaqChain {
 public:
  /// Loads the noise recordings; throws ConfigError naming the file when one cannot be read, has
  /// the wrong sample rate or channel count, or is shorter than one record.
  DaqChain(const DaqConfig& daq, const NoiseConfig& noise, int channels, double sample_rate_hz,
           int64_t record_samples);
  ~DaqChain();
  DaqChain(const DaqChain&) = delete;
  DaqChain& operator=(const DaqChain&) = delete;

  /// strain (channels x T, surface strain) -> audio (channels x T, full scale 1, quantized to
  /// output_bits). joint_speed_rad_s is sampled at joint_speed_rate_hz from the record start (may
  /// be empty). Returns whether any sample clipped. Throws NumericalError on a non-finite sample.
  /// chain: this sample's draw of the sensor chain (bonding, gains, high-pass corners, noise
  /// floor, hum, record level, full scale); default-constructed = as configured.
  bool Convert(const Eigen::MatrixXd& strain, std::span<const double> joint_speed_rad_s,
               double joint_speed_rate_hz, uint64_t sample_seed, Eigen::MatrixXf* audio,
               const ChainDraw& chain = {}) const;

  const DaqConfig& daq() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Sample indices reserved for the spectral gate's reference noise clip: record r of the clip
/// has seed SampleSeed(seed, kReferenceNoiseIndex - r), r < kReferenceNoiseRecords. No dataset
/// sample has them (indices are stored as int64 >= 0, and dataset.first_index <= 1e15).
inline constexpr uint64_t kReferenceNoiseIndex = ~uint64_t{0};
/// The input high-pass at highpass_hz of chain.highpass_order, then chain's anti-alias low-pass
/// (none when chain.lowpass_hz is 0), in place on one channel's samples at fs (bilinear
/// sections: first order, or second-order Butterworth). Throws ConfigError naming the keys when a
/// corner is not below Nyquist.
void ApplyChainFilters(double highpass_hz, const ChainDraw& chain, double fs,
                       Eigen::Ref<Eigen::ArrayXd> v);

inline constexpr int64_t kReferenceNoiseRecords = 8;

/// The noise model's no-contact recording, (channels x kReferenceNoiseRecords * frames): each
/// record is the chain on zero strain with the motor at joint_speed_rad_s (sampled at
/// joint_speed_rate_hz; empty: no motor), and draws its own per-strike channel gains and tone
/// phases from SampleSeed(seed, kReferenceNoiseIndex - r). Deterministic in its arguments.
Eigen::MatrixXf NoiseModelClip(const DaqChain& daq, int channels, int64_t frames,
                               std::span<const double> joint_speed_rad_s,
                               double joint_speed_rate_hz, uint64_t seed);

}  // namespace sonicboom::acoustics
