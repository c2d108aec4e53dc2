#pragma once
/// Strike audio: Hertz contact force -> modal tube vibration -> piezo strain at six discs
/// -> disc/preamp high-pass, gain mismatch, noise -> 24-bit ADC with clipping -> 16-bit output.
/// The model (modes, sensor gains, filters) is built once and shared across threads; Render
/// is const and depends only on its inputs and the sample seed.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// Vibration model fidelity.
struct SynthConfig {
  std::string model{"modal-closed-form"};  // ideal simply-supported shell, Flügge modes
  double max_frequency_hz{0.0};            // mode band; 0 = derive from the contact (and Nyquist)
  double band_factor{3.0};                 // auto band = band_factor x first spectral minimum (1.8 / t_c)
  double decay_floor_db{-100.0};           // a mode stops once it decayed this far
  int64_t force_substeps{8};               // force averaged over this many points per sample

  void Serialize(Archive* a);
};

/// Piezo disc, preamp and converter.
struct DaqConfig {
  double sensitivity_v_per_strain{2000.0}; // open-circuit volts per unit surface strain
  double gain_mismatch_db{1.0};            // per-channel gain spread (std dev, dB)
  double input_resistance_ohm{1.0e6};      // with the disc capacitance sets the high-pass
  double disc_capacitance_f{16e-9};
  double preamp_noise_v{2e-5};             // white, rms
  double full_scale_v{1.0};                // ADC full scale
  int64_t adc_bits{24};
  int64_t output_bits{16};                 // the paper's recordings were 16-bit PCM

  void Serialize(Archive* a);
  double highpass_hz() const;
};

/// Background vibration picked up by the discs.
struct NoiseConfig {
  double ambient_rms_v{3e-5};              // broadband floor, rms
  double motor_rms_v_per_rad_s{3e-3};      // motor and gear tones, rms per rad/s of joint speed
  double motor_base_hz{110.0};             // fundamental of the gear tones
  int64_t motor_harmonics{8};

  void Serialize(Archive* a);
};

/// The Hertz impact of a striker on the wall (rigid target): physics.md §1.6.
struct HertzImpact {
  double stiffness_n_m15{0.0};             // K in F = K delta^1.5
  double max_compression_m{0.0};
  double peak_force_n{0.0};
  double duration_s{0.0};
  double impulse_ns{0.0};                  // 0.5436 F_max t_c
};
HertzImpact SolveHertzImpact(const ContactEvent& contact, const TubeConfig& tube,
                             const MaterialConfig& material);
/// Force of that impact at time t after first touch (F_max sin^1.5(pi t / t_c)), N.
double HertzForce(const HertzImpact& impact, double t_s);

/// Result of rendering one strike.
struct RenderedStrike {
  Eigen::MatrixXf audio;                   // (mics x T), full scale 1, quantized to output_bits
  bool clipped{false};
  double impulse_ns{0.0};
  double duration_s{0.0};
  double peak_force_n{0.0};
  double band_hz{0.0};                     // mode band used
  int64_t modes_used{0};
};

/// Immutable acoustic model of one tube + sensor set-up.
class StrikeSynthesizer {
 public:
  StrikeSynthesizer(const TubeConfig& tube, const MaterialConfig& material,
                    const MicArrayConfig& mics, const AudioConfig& audio, const SynthConfig& synth,
                    const DaqConfig& daq, const NoiseConfig& noise);
  ~StrikeSynthesizer();
  StrikeSynthesizer(const StrikeSynthesizer&) = delete;
  StrikeSynthesizer& operator=(const StrikeSynthesizer&) = delete;

  /// Renders one record. joint_speed_rad_s is sampled at joint_speed_rate_hz from the record start.
  RenderedStrike Render(const ContactEvent& contact, std::span<const double> joint_speed_rad_s,
                        double joint_speed_rate_hz, uint64_t sample_seed) const;

  /// Modes in the model's widest band (for inspection).
  int64_t mode_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::acoustics
