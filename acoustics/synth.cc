#include "sonicboom/acoustics/synth.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::acoustics {
namespace {

constexpr double kPi = std::numbers::pi;

// round to nearest (ties to even) without a libm call; |x| < 2^51
inline double RoundFast(double x) {
  constexpr double kMagic = 6755399441055744.0;  // 1.5 * 2^52
  return (x + kMagic) - kMagic;
}

// one precomputed mode: recursion pole, drive and sensor factors
struct ModeBank {
  double frequency_hz;
  double pole_re, pole_im;     // exp((-sigma + i omega_d) T)
  double decay_per_sample;     // sigma T
  double response_scale;       // T / (omega_d M)
  double wavenumber_m;         // k = m pi / L
  int n;
  double drive_w;              // W: radial part of the shape
  double strain_factor;        // surface strain per unit modal amplitude, aperture included
  Eigen::VectorXd mic_axial;   // (mics) sin(k x_i)
};

}  // namespace

void SynthConfig::Serialize(Archive* a) {
  a->VisitChoice("model", &model, {"modal-closed-form"});
  a->Visit("max_frequency_hz", &max_frequency_hz, Bounds::NonNegative());
  a->Visit("band_factor", &band_factor, Bounds::Open(0.0, 100.0));
  a->Visit("decay_floor_db", &decay_floor_db, Bounds::Open(-300.0, 0.0));
  a->Visit("force_substeps", &force_substeps, Bounds::Closed(1, 1024));
}

void DaqConfig::Serialize(Archive* a) {
  a->Visit("sensitivity_v_per_strain", &sensitivity_v_per_strain, Bounds::Positive());
  a->Visit("gain_mismatch_db", &gain_mismatch_db, Bounds::Closed(0.0, 20.0));
  a->Visit("input_resistance_ohm", &input_resistance_ohm, Bounds::Positive());
  a->Visit("disc_capacitance_f", &disc_capacitance_f, Bounds::Positive());
  a->Visit("preamp_noise_v", &preamp_noise_v, Bounds::NonNegative());
  a->Visit("full_scale_v", &full_scale_v, Bounds::Positive());
  a->Visit("adc_bits", &adc_bits, Bounds::Closed(8, 32));
  a->Visit("output_bits", &output_bits, Bounds::Closed(8, 32));
}

double DaqConfig::highpass_hz() const {
  return 1.0 / (2 * kPi * input_resistance_ohm * disc_capacitance_f);
}

void NoiseConfig::Serialize(Archive* a) {
  a->Visit("ambient_rms_v", &ambient_rms_v, Bounds::NonNegative());
  a->Visit("motor_rms_v_per_rad_s", &motor_rms_v_per_rad_s, Bounds::NonNegative());
  a->Visit("motor_base_hz", &motor_base_hz, Bounds::Positive());
  a->Visit("motor_harmonics", &motor_harmonics, Bounds::Closed(0, 64));
}

HertzImpact SolveHertzImpact(const ContactEvent& contact, const TubeConfig& tube,
                             const MaterialConfig& material) {
  // effective modulus and radius of a rod crossing the tube (crossed cylinders, R_e = sqrt(R1 R2))
  const double inv_e = (1 - material.poisson_ratio * material.poisson_ratio) /
                           material.youngs_modulus_pa +
                       (1 - contact.striker_poisson_ratio * contact.striker_poisson_ratio) /
                           contact.striker_youngs_modulus_pa;
  const double e_star = 1.0 / inv_e;
  const double r_e = std::sqrt(contact.striker_radius_m * tube.outer_radius_m);
  HertzImpact impact;
  impact.stiffness_n_m15 = 4.0 / 3.0 * e_star * std::sqrt(r_e);
  const double m = contact.effective_mass_kg, v = contact.normal_speed_m_s;
  impact.max_compression_m = std::pow(5 * m * v * v / (4 * impact.stiffness_n_m15), 0.4);
  impact.peak_force_n = impact.stiffness_n_m15 * std::pow(impact.max_compression_m, 1.5);
  impact.duration_s = 2.9432 * impact.max_compression_m / v;
  impact.impulse_ns = 0.5436 * impact.peak_force_n * impact.duration_s;
  return impact;
}

double HertzForce(const HertzImpact& impact, double t_s) {
  if (t_s <= 0.0 || t_s >= impact.duration_s) return 0.0;
  return impact.peak_force_n * std::pow(std::sin(kPi * t_s / impact.duration_s), 1.5);
}

struct StrikeSynthesizer::Impl {
  TubeConfig tube;
  MaterialConfig material;
  MicArrayConfig mics;
  AudioConfig audio;
  SynthConfig synth;
  DaqConfig daq;
  NoiseConfig noise;
  std::vector<ModeBank> modes;     // ascending frequency, up to the widest band
  double widest_band_hz{0.0};
  Eigen::VectorXd mic_theta_rad;   // (mics)
};

StrikeSynthesizer::StrikeSynthesizer(const TubeConfig& tube, const MaterialConfig& material,
                                     const MicArrayConfig& mics, const AudioConfig& audio,
                                     const SynthConfig& synth, const DaqConfig& daq,
                                     const NoiseConfig& noise)
    : impl_(std::make_unique<Impl>()) {
  tube.Validate();
  mics.Validate(tube);
  impl_->tube = tube;
  impl_->material = material;
  impl_->mics = mics;
  impl_->audio = audio;
  impl_->synth = synth;
  impl_->daq = daq;
  impl_->noise = noise;

  // widest band: the configured limit, never above 0.95 Nyquist
  const double nyquist = 0.5 * audio.sample_rate_hz;
  impl_->widest_band_hz = synth.max_frequency_hz > 0 ? synth.max_frequency_hz : 0.95 * nyquist;
  if (impl_->widest_band_hz >= nyquist) {
    throw NumericalError(fmt::format(
        "acoustics.max_frequency_hz = {} must be below the Nyquist frequency {} Hz "
        "(audio.sample_rate_hz / 2): modes above it alias",
        synth.max_frequency_hz, nyquist));
  }

  // modes and their per-mode constants
  const double T = 1.0 / audio.sample_rate_hz;
  const double R = tube.mid_radius_m();
  const double h = tube.wall_thickness_m;
  const double rho_h = material.density_kg_m3 * h;
  const double zeta = 0.5 * material.loss_factor;
  const int num_mics = mics.count();
  impl_->mic_theta_rad.resize(num_mics);
  for (int i = 0; i < num_mics; ++i) impl_->mic_theta_rad[i] = mics.theta_deg[i] * kPi / 180.0;
  for (const ShellMode& sm : SimplySupportedModes(tube, material, impl_->widest_band_hz)) {
    if (std::abs(sm.w) < 1e-9) continue;  // no radial part: a normal force cannot excite it
    ModeBank mb;
    mb.frequency_hz = sm.frequency_hz;
    const double omega = 2 * kPi * sm.frequency_hz;
    const double sigma = zeta * omega;
    const double omega_d = omega * std::sqrt(1 - zeta * zeta);
    const std::complex<double> pole = std::exp(std::complex<double>(-sigma * T, omega_d * T));
    mb.pole_re = pole.real();
    mb.pole_im = pole.imag();
    mb.decay_per_sample = sigma * T;
    // modal mass of one member of the pair: rho h R (L / 2) pi (2 pi for n = 0), unit-norm shape
    const double modal_mass = rho_h * R * 0.5 * tube.length_m * (sm.n == 0 ? 2 * kPi : kPi);
    mb.response_scale = T / (omega_d * modal_mass);
    mb.wavenumber_m = sm.m * kPi / tube.length_m;
    mb.n = sm.n;
    mb.drive_w = sm.w;
    // outer-surface strain eps_x + eps_th: membrane (-lambda U + n V + W) / R plus bending
    const double lambda = mb.wavenumber_m * R;
    const double membrane = (-lambda * sm.u + sm.n * sm.v + sm.w) / R;
    const double bending = 0.5 * h * sm.w * (lambda * lambda + sm.n * sm.n) / (R * R);
    // disc aperture: 2 J1(x) / x with x = k_t d / 2
    const double k_t = std::hypot(mb.wavenumber_m, sm.n / tube.outer_radius_m);
    const double x = 0.5 * k_t * mics.disc_diameter_m;
    const double aperture = x < 1e-6 ? 1.0 : 2 * std::cyl_bessel_j(1.0, x) / x;
    mb.strain_factor = (membrane + bending) * aperture;
    mb.mic_axial.resize(num_mics);
    for (int i = 0; i < num_mics; ++i) {
      mb.mic_axial[i] = std::sin(mb.wavenumber_m * (mics.z_m[i] + 0.5 * tube.length_m));
    }
    impl_->modes.push_back(std::move(mb));
  }
}

StrikeSynthesizer::~StrikeSynthesizer() = default;

int64_t StrikeSynthesizer::mode_count() const { return static_cast<int64_t>(impl_->modes.size()); }

RenderedStrike StrikeSynthesizer::Render(const ContactEvent& contact,
                                         std::span<const double> joint_speed_rad_s,
                                         double joint_speed_rate_hz, uint64_t sample_seed) const {
  const Impl& m = *impl_;
  const double fs = m.audio.sample_rate_hz;
  const double T = 1.0 / fs;
  const int64_t num_frames = m.audio.num_samples();
  const int num_mics = m.mics.count();
  RenderedStrike out;

  // contact force at audio rate: Hertz pulse, averaged over substeps within each sample
  const HertzImpact impact = SolveHertzImpact(contact, m.tube, m.material);
  if (!std::isfinite(impact.duration_s) || impact.duration_s <= 0) {
    throw NumericalError(fmt::format("contact of speed {} m/s and mass {} kg has no finite "
                                     "Hertz duration",
                                     contact.normal_speed_m_s, contact.effective_mass_kg));
  }
  out.impulse_ns = impact.impulse_ns;
  out.duration_s = impact.duration_s;
  out.peak_force_n = impact.peak_force_n;
  const int64_t k_first = static_cast<int64_t>(std::floor(contact.time_s * fs));
  const int64_t k_last = static_cast<int64_t>(std::ceil((contact.time_s + impact.duration_s) * fs));
  std::vector<double> force(std::max<int64_t>(k_last - k_first + 1, 1));  // N, per sample
  const int64_t sub = m.synth.force_substeps;
  for (size_t j = 0; j < force.size(); ++j) {
    double acc = 0;
    for (int64_t s = 0; s < sub; ++s) {
      const double t = (k_first + static_cast<double>(j) + (s + 0.5) / sub) * T;
      acc += HertzForce(impact, t - contact.time_s);
    }
    force[j] = acc / sub;
  }

  // band the strike can excite: a multiple of the pulse's first spectral minimum (1.8 / t_c)
  out.band_hz = m.synth.max_frequency_hz > 0
                    ? m.widest_band_hz
                    : std::min(m.widest_band_hz, m.synth.band_factor * 1.8 / impact.duration_s);

  // modal superposition: strain at each mic, (mics x T) in double
  Eigen::MatrixXd strain = Eigen::MatrixXd::Zero(num_mics, num_frames);
  const double x_c = contact.z_m + 0.5 * m.tube.length_m;
  const double floor_ln = std::abs(m.synth.decay_floor_db) / 20.0 * std::log(10.0);
  Eigen::VectorXd gain(num_mics);
  for (const ModeBank& mb : m.modes) {
    if (mb.frequency_hz > out.band_hz) break;
    ++out.modes_used;
    // drive at the contact and pickup at each mic (the degenerate pair collapses to cos n dtheta)
    const double drive = mb.drive_w * std::sin(mb.wavenumber_m * x_c);
    for (int i = 0; i < num_mics; ++i) {
      gain[i] = mb.response_scale * drive * mb.strain_factor * mb.mic_axial[i] *
                std::cos(mb.n * (m.mic_theta_rad[i] - contact.theta_rad));
    }
    // complex one-pole recursion z[k] = p z[k-1] + F[k]; q = Im(z) T / (omega_d M)
    const int64_t k_end =
        std::min<int64_t>(num_frames, k_last + 1 + static_cast<int64_t>(floor_ln / mb.decay_per_sample));
    double zr = 0, zi = 0;
    for (int64_t k = std::max<int64_t>(k_first, 0); k < k_end; ++k) {
      const int64_t j = k - k_first;
      const double f = j < static_cast<int64_t>(force.size()) ? force[j] : 0.0;
      const double nr = zr * mb.pole_re - zi * mb.pole_im + f;
      zi = zr * mb.pole_im + zi * mb.pole_re;
      zr = nr;
      strain.col(k) += gain * zi;
    }
  }

  // piezo volts with per-channel gain mismatch, plus structure-borne noise
  Rng rng(sample_seed, Stream::kDaq);
  Eigen::MatrixXd volts(num_mics, num_frames);
  for (int i = 0; i < num_mics; ++i) {
    const double g = m.daq.sensitivity_v_per_strain *
                     std::pow(10.0, rng.Normal() * m.daq.gain_mismatch_db / 20.0);
    volts.row(i) = strain.row(i) * g;
  }
  Rng noise_rng(sample_seed, Stream::kNoise);
  // motor and gear tones follow the joint speed; each channel picks them up with its own gain
  const int64_t harmonics = m.noise.motor_harmonics;
  std::vector<double> phase(harmonics), channel_gain(num_mics);
  for (auto& p : phase) p = noise_rng.Uniform(0, 2 * kPi);
  for (auto& g : channel_gain) g = noise_rng.Uniform(0.5, 1.5);
  const double tone_amp =
      harmonics > 0 ? std::sqrt(2.0 / harmonics) * m.noise.motor_rms_v_per_rad_s : 0.0;
  // each harmonic is a unit phasor advanced by one rotation per sample
  std::vector<std::complex<double>> phasor(harmonics), step(harmonics);
  for (int64_t hm = 0; hm < harmonics; ++hm) {
    phasor[hm] = std::polar(1.0, phase[hm]);
    step[hm] = std::polar(1.0, 2 * kPi * m.noise.motor_base_hz * (hm + 1) * T);
  }
  for (int64_t k = 0; k < num_frames; ++k) {
    double speed = 0.0;
    if (!joint_speed_rad_s.empty()) {
      const double pos = k * T * joint_speed_rate_hz;
      const size_t idx = std::min(static_cast<size_t>(pos), joint_speed_rad_s.size() - 1);
      const size_t nxt = std::min(idx + 1, joint_speed_rad_s.size() - 1);
      const double frac = std::clamp(pos - static_cast<double>(idx), 0.0, 1.0);
      speed = (1 - frac) * joint_speed_rad_s[idx] + frac * joint_speed_rad_s[nxt];
    }
    double motor = 0.0;
    for (int64_t hm = 0; hm < harmonics; ++hm) {
      motor += phasor[hm].imag();
      phasor[hm] *= step[hm];
    }
    motor *= tone_amp * speed;
    for (int i = 0; i < num_mics; ++i) {
      volts(i, k) += channel_gain[i] * motor + m.noise.ambient_rms_v * noise_rng.NoiseSample();
    }
  }

  // first-order high-pass of disc capacitance into the preamp input (bilinear), preamp noise
  const double kk = std::tan(kPi * m.daq.highpass_hz() / fs);
  const double b0 = 1.0 / (1.0 + kk), a1 = (kk - 1.0) / (kk + 1.0);
  for (int i = 0; i < num_mics; ++i) {
    double x_prev = 0, y_prev = 0;
    for (int64_t k = 0; k < num_frames; ++k) {
      const double x = volts(i, k);
      const double y = b0 * (x - x_prev) - a1 * y_prev;
      x_prev = x;
      y_prev = y;
      volts(i, k) = y + m.daq.preamp_noise_v * noise_rng.NoiseSample();
    }
  }

  // converter: clip at full scale, quantize to the ADC, then to the output word length
  const double adc_step = 1.0 / (std::ldexp(1.0, static_cast<int>(m.daq.adc_bits) - 1) - 1);
  const double out_step = 1.0 / (std::ldexp(1.0, static_cast<int>(m.daq.output_bits) - 1) - 1);
  out.audio.resize(num_mics, num_frames);
  for (int64_t k = 0; k < num_frames; ++k) {
    for (int i = 0; i < num_mics; ++i) {
      double x = volts(i, k) / m.daq.full_scale_v;
      if (!std::isfinite(x)) {
        throw NumericalError(fmt::format("non-finite audio at mic {} sample {}", i, k));
      }
      if (std::abs(x) >= 1.0) {
        out.clipped = true;
        x = std::clamp(x, -1.0, 1.0);
      }
      x = RoundFast(x / adc_step) * adc_step;
      out.audio(i, k) = static_cast<float>(RoundFast(x / out_step) * out_step);
    }
  }
  return out;
}

}  // namespace sonicboom::acoustics
