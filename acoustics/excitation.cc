// The excitation stage of a strike's render (internal/render_stages.h): the sample's view of its
// draws, and the record's episodes as forces on the wall, each impact solved against the wall of
// the rung that renders.
#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "internal/render_stages.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::acoustics {
namespace {

// the draws of a sample with none: the configured set-up
const Variation& Configured() {
  static const Variation nominal;
  return nominal;
}

// the striker of a contact under a draw: tip radius and modulus replaced, rigid mass and
// approach speed scaled (a struck rod keeps its beam modes)
ContactEvent DrawnContact(const ContactEvent& contact, const StrikerDraw& s) {
  ContactEvent c = contact;
  if (s.radius_m > 0) c.striker_radius_m = s.radius_m;
  if (s.youngs_modulus_pa > 0) c.striker_youngs_modulus_pa = s.youngs_modulus_pa;
  if (c.beam_length_m <= 0) c.effective_mass_kg *= s.mass_scale;
  c.normal_speed_m_s *= s.speed_scale;
  return c;
}

// a foliage rustle: band-passed noise (two-pole resonators at the band edges' geometric mean)
// under a Hann envelope over the brush, scaled to rms_n; one sample per audio sample
std::vector<double> RustleForce(double duration_s, double fs, double rms_n, double low_hz,
                                double high_hz, Rng* rng) {
  const int64_t n = std::max<int64_t>(static_cast<int64_t>(duration_s * fs), 1);
  std::vector<double> f(static_cast<size_t>(n));
  // RBJ band-pass biquad (constant peak gain) centred at sqrt(lo hi), bandwidth hi - lo
  const double f0 = std::sqrt(low_hz * high_hz);
  const double w0 = 2 * kPi * std::min(f0, 0.45 * fs) / fs;
  const double q = f0 / (high_hz - low_hz);
  const double alpha = std::sin(w0) / (2 * q);
  const double a0 = 1 + alpha;
  const double b0 = alpha / a0, b2 = -alpha / a0, a1 = -2 * std::cos(w0) / a0,
               a2 = (1 - alpha) / a0;
  double x1 = 0, x2 = 0, y1 = 0, y2 = 0, sum_sq = 0;
  for (int64_t k = 0; k < n; ++k) {
    const double x = rng->NoiseSample();
    const double y = b0 * x + b2 * x2 - a1 * y1 - a2 * y2;
    x2 = x1;
    x1 = x;
    y2 = y1;
    y1 = y;
    const double env = std::sin(kPi * (k + 0.5) / n);
    f[static_cast<size_t>(k)] = y * env * env;
    sum_sq += f[static_cast<size_t>(k)] * f[static_cast<size_t>(k)];
  }
  const double scale = sum_sq > 0 ? rms_n / std::sqrt(sum_sq / n) : 0.0;
  for (double& v : f) v *= scale;
  return f;
}

// a press: its mean force (impulse / duration) with 5 ms raised-cosine ramps, per audio sample
std::vector<double> PressForce(double duration_s, double mean_force_n, double fs) {
  const int64_t n = std::max<int64_t>(static_cast<int64_t>(duration_s * fs), 1);
  const double ramp = std::min(0.005 * fs, 0.5 * n);
  std::vector<double> f(static_cast<size_t>(n));
  for (int64_t k = 0; k < n; ++k) {
    const double edge = std::min<double>(k + 0.5, n - k - 0.5);
    const double w = edge >= ramp ? 1.0 : 0.5 - 0.5 * std::cos(kPi * edge / ramp);
    f[static_cast<size_t>(k)] = mean_force_n * w;
  }
  return f;
}


// the striker: the struck rod's beam modes, or a rigid body of the contact's effective mass
DrivingPoint StrikerOf(const ContactEvent& contact, double beam_max_frequency_hz) {
  DrivingPoint striker;
  if (contact.beam_length_m <= 0) {
    striker.rigid_mass_kg = contact.effective_mass_kg;
    return striker;
  }
  BeamSpec beam;
  beam.length_m = contact.beam_length_m;
  beam.flexural_rigidity_n_m2 = contact.beam_flexural_rigidity_n_m2;
  beam.linear_density_kg_m = contact.beam_linear_density_kg_m;
  beam.contact_from_clamp_m = contact.beam_contact_from_clamp_m;
  beam.clamped_both_ends = contact.beam_clamped_both_ends;
  beam.loss_factor = contact.beam_loss_factor;
  striker = BeamDrivingPoint(beam, beam_max_frequency_hz);
  // a contact is far shorter than the rod's fundamental period: that mode acts as a free mass
  // (its modal mass at the contact) that carries the approach and separates; the higher modes
  // ring in the contact
  if (striker.phi.size() > 0) {
    striker.rigid_mass_kg = 1.0 / (striker.phi[0] * striker.phi[0]);
    const Eigen::Index rest = striker.phi.size() - 1;
    striker.omega_rad_s = striker.omega_rad_s.tail(rest).eval();
    striker.zeta = striker.zeta.tail(rest).eval();
    striker.phi = striker.phi.tail(rest).eval();
  }
  return striker;
}

}  // namespace

SampleView SampleView::Of(const Variation* draws, const ContactEvent& first,
                          const AcousticModelConfig& config) {
  const Variation& v = draws != nullptr ? *draws : Configured();
  SampleView view{v.structure, v.striker, v.chain, DrawnContact(first, v.striker),
                  VariedMaterial(config.material, v.structure), {}, 0, 0.0};
  // the rigid-wall Hertz impact: the closed-form rung's pulse, and the contact band's first guess
  view.impact = SolveHertzImpact(view.contact, config.tube, view.material);
  // the span: the whole record, or as long after the first contact as the features read
  const AudioConfig& audio = config.audio;
  view.frames = audio.num_samples();
  view.end_s = audio.record_duration_s;
  if (config.synth.render_span == RenderSpan::kFeatures) {
    view.end_s = std::min(view.end_s, first.time_s + config.synth.span_after_contact_s);
    view.frames = std::clamp<int64_t>(std::llround(view.end_s * audio.sample_rate_hz), 1,
                                      view.frames);
  }
  if (!std::isfinite(view.impact.duration_s) || view.impact.duration_s <= 0) {
    throw NumericalError(
        fmt::format("contact of speed {} m/s and mass {} kg has no finite "
                    "Hertz duration",
                    view.contact.normal_speed_m_s, view.contact.effective_mass_kg));
  }
  return view;
}

double BandRule::operator()(double contact_duration_s, double frequency_scale) const {
  const double widest =
      mode_band_hz > 0 ? std::min(limit_hz, mode_band_hz * frequency_scale) : limit_hz;
  if (fixed) return widest;
  return std::min(widest, std::max(kLowestBandHz, ContactBandHz(band_factor, contact_duration_s)));
}

Excitation Excite(const AcousticModelConfig& config, const SampleView& view,
                  std::span<const ContactEpisode> episodes, uint64_t sample_seed,
                  const ExcitationWall& wall) {
  const double fs = config.audio.sample_rate_hz;
  const ContactConfig& solve = config.synth.contact;
  const ContactEvent& contact = view.contact;
  const DrivingPoint striker = StrikerOf(contact, solve.beam_max_frequency_hz);
  Excitation ex;
  // solves an impact (or hands it to the FD run, where the rigid-wall Hertz pulse's duration
  // stands in for it until then)
  auto play_contact = [&](double time_s, double z_m, double theta_rad, double speed_m_s,
                          double tube_side_kg, const DrivingPoint& other) {
    if (wall.closes_impacts) {
      ex.fd_impacts.push_back({time_s, z_m, theta_rad, speed_m_s, tube_side_kg, other,
                               view.impact.stiffness_n_m15});
      ContactForce pending;
      pending.duration_s = pending.first_closure_s = view.impact.duration_s;
      return pending;
    }
    // a rigid wall is a held half-space: no modes, no rigid motion
    DrivingPoint at;
    if (wall.modes_at) {
      at = wall.modes_at(z_m, theta_rad, wall.contact_band_hz);
      at.rigid_mass_kg =
          tube_side_kg > 0 ? tube_side_kg : std::numeric_limits<double>::infinity();
    }
    ContactForce cf =
        SolveContact(at, other, view.impact.stiffness_n_m15, speed_m_s, time_s, fs, solve);
    ex.forces.push_back({z_m, theta_rad, cf.first_sample, std::move(cf.force_n)});
    return cf;
  };
  ex.first = play_contact(contact.time_s, contact.z_m, contact.theta_rad,
                          contact.normal_speed_m_s, contact.robot_side_mass_kg, striker);
  // the other episodes of the record: bounces and later impacts, presses, brushes
  const NoiseConfig& noise = config.noise;
  Rng rng(sample_seed, Stream::kAcoustics);
  for (const ContactEpisode& e : episodes) {
    if (e.time_s >= view.end_s) continue;  // after the span: not heard
    const bool is_first = std::abs(e.time_s - contact.time_s) < 0.5 / fs;
    if (e.kind == ContactEpisode::Kind::kBrush) {
      if (noise.foliage_force_rms_n <= 0) continue;
      const double half = 0.49 * config.tube.length_m;
      const double z = std::clamp(e.z_m, -half, half);
      // a brushed point in a hole has no wall to act on: its rustle is not played (the check is
      // made here, before the force reaches the bank or the FD grid, which refuse it)
      if (wall.shell != nullptr && !wall.shell->AcceptsForce(z, e.theta_rad)) continue;
      ex.forces.push_back({z, e.theta_rad, static_cast<int64_t>(std::floor(e.time_s * fs)),
                           RustleForce(e.duration_s, fs, noise.foliage_force_rms_n,
                                       noise.foliage_low_hz, noise.foliage_high_hz, &rng)});
      continue;
    }
    if (e.kind == ContactEpisode::Kind::kPress && e.duration_s > 0) {
      // the impact that opened the press is played below (or above, as the first contact)
      const double start_s = e.time_s + (is_first ? ex.first.duration_s : 0.0);
      ex.forces.push_back({e.z_m, e.theta_rad, static_cast<int64_t>(std::floor(start_s * fs)),
                           PressForce(e.duration_s, e.impulse_Ns / e.duration_s, fs)});
    }
    if (is_first || !(e.normal_speed_m_s > 1e-4) || !(e.effective_mass_kg > 0)) continue;
    // a bounce or later impact: the same striker, its own speed and point
    DrivingPoint other = striker;
    if (contact.beam_length_m <= 0) other.rigid_mass_kg = e.effective_mass_kg * view.striker.mass_scale;
    play_contact(e.time_s, e.z_m, e.theta_rad, e.normal_speed_m_s * view.striker.speed_scale,
                 contact.robot_side_mass_kg, other);
  }
  return ex;
}

}  // namespace sonicboom::acoustics
