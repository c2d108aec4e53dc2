#include "sonicboom/acoustics/synth.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <limits>
#include <mutex>
#include <numbers>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "sonicboom/acoustics/closed_form_bank.h"
#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/acoustics/fd_render.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_fd.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/shell_ritz.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::acoustics {
namespace {

// the default grid (2.5 mm) has >= 6 points per bending wavelength up to about here
constexpr double kDefaultModeBandHz = 20000.0;

}  // namespace

double SynthConfig::ModeBandHz(double sample_rate_hz) const {
  return mode_band_hz > 0 ? mode_band_hz
                          : std::min(0.95 * 0.5 * sample_rate_hz, kDefaultModeBandHz);
}

std::string SynthConfig::ModeCacheDir() const {
  return mode_cache_dir.empty() ? DefaultModeCacheDir() : mode_cache_dir;
}

void SynthConfig::Serialize(Archive* a) {
  a->Visit("model", &model);
  a->Visit("max_frequency_hz", &max_frequency_hz, Bounds::NonNegative());
  a->Visit("mode_count", &mode_count, Bounds::Closed(0, 20000));
  a->Visit("band_factor", &band_factor, Bounds::Open(0.0, 100.0));
  a->Visit("decay_floor_db", &decay_floor_db, Bounds::Open(-300.0, 0.0));
  a->Visit("force_substeps", &force_substeps, Bounds::Closed(1, 1024));
  a->Visit("residual", &residual);
  a->Visit("mode_band_hz", &mode_band_hz, Bounds::NonNegative());
  a->Visit("fd_oversampling", &fd_oversampling, Bounds::Closed(0, 4096));
  a->Visit("mode_cache_dir", &mode_cache_dir);
  a->Visit("contact", &contact);
}

HertzImpact SolveHertzImpact(const ContactEvent& contact, const TubeConfig& tube,
                             const MaterialConfig& material) {
  // effective modulus and radius of a rod crossing the tube (crossed cylinders, R_e = sqrt(R1 R2))
  const double inv_e =
      (1 - material.poisson_ratio * material.poisson_ratio) / material.youngs_modulus_pa +
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
  AcousticModelConfig c;
  double widest_band_hz{0.0};
  double limit_band_hz{0.0};  // the configured limit (max_frequency_hz or 0.95 Nyquist)
  double mode_band_hz{0.0};   // modes solved to here (modal and fd); 0: closed form

  // the band played for a first closure of t_c s on a structure whose frequencies are scaled by
  // frequency_scale (a randomized material; 1: as solved), Hz
  double Band(double contact_duration_s, double frequency_scale) const {
    const double widest =
        mode_band_hz > 0 ? std::min(limit_band_hz, mode_band_hz * frequency_scale) : limit_band_hz;
    if (c.synth.max_frequency_hz > 0) return widest;
    return std::min(widest, ContactBandHz(c.synth.band_factor, contact_duration_s));
  }
  // modal-closed-form
  std::unique_ptr<ClosedFormBank> closed_form;
  // modal and fd: the discretized shell, its modes, and the FD solver
  std::unique_ptr<ShellModel> shell;
  std::unique_ptr<ShellModalBank> bank;
  // the structure pool: each variant's shell, its Ritz modes' bank and its drawn values
  struct Variant {
    std::unique_ptr<ShellModel> shell;
    std::unique_ptr<ShellModalBank> bank;
    std::vector<double> values;
  };
  std::vector<Variant> pool;
  std::unique_ptr<ShellFd> fd;
  Eigen::MatrixXd sensor_rows;  // (mics x dofs) fd only
  std::unique_ptr<DaqChain> daq;

  // the structure pool from the base modes (with shapes): variants drawn, Ritz modes, banks
  void BuildPool(const ShellModes& base_modes, double placement_margin_m);
  // the first contact's strain by the closed-form modes, (mics x T)
  Eigen::MatrixXd ClosedFormStrain(const ContactEvent& contact, const HertzImpact& impact,
                                   RenderedStrike* out) const;
};

Eigen::MatrixXd StrikeSynthesizer::Impl::ClosedFormStrain(const ContactEvent& contact,
                                                          const HertzImpact& impact,
                                                          RenderedStrike* out) const {
  const double fs = c.audio.sample_rate_hz;
  const double T = 1.0 / fs;
  const int64_t num_frames = c.audio.num_samples();
  // contact force at audio rate: Hertz pulse, averaged over substeps within each sample
  const int64_t k_first = static_cast<int64_t>(std::floor(contact.time_s * fs));
  const int64_t k_last = static_cast<int64_t>(std::ceil((contact.time_s + impact.duration_s) * fs));
  std::vector<double> force(std::max<int64_t>(k_last - k_first + 1, 1));  // N, per sample
  const int64_t sub = c.synth.force_substeps;
  for (size_t j = 0; j < force.size(); ++j) {
    double acc = 0;
    for (int64_t s = 0; s < sub; ++s) {
      const double t = (k_first + static_cast<double>(j) + (s + 0.5) / sub) * T;
      acc += HertzForce(impact, t - contact.time_s);
    }
    force[j] = acc / sub;
  }
  const ForceInput input{contact.z_m, contact.theta_rad, k_first, std::move(force)};
  return closed_form->Render(std::span<const ForceInput>(&input, 1), out->band_hz, num_frames,
                             &out->modes_used);
}

namespace {

// how far the randomized placement can move a disc's edge (offset plus growth), m
double PlacementMargin(const AcousticModelConfig& c) {
  const RandomizeConfig& r = c.randomize;
  if (!r.mic_placement()) return 0.0;
  const auto largest = [](const std::vector<double>& range) {
    return range.empty() ? 0.0 : std::max(std::abs(range[0]), std::abs(range[1]));
  };
  const double grow = r.disc_diameter_m.empty()
                          ? 0.0
                          : std::max(0.0, 0.5 * (r.disc_diameter_m[1] - c.mics.disc_diameter_m));
  return largest(r.mic_z_offset_m) +
         c.tube.outer_radius_m * largest(r.mic_theta_offset_deg) * kPi / 180.0 + grow;
}

}  // namespace

void StrikeSynthesizer::Impl::BuildPool(const ShellModes& base_modes, double placement_margin_m) {
  const int64_t count = c.randomize.structure_variants;
  pool.resize(static_cast<size_t>(count));
  // the projector is made only when some variant is not in the cache
  std::once_flag made;
  std::unique_ptr<ShellRitzProjector> projector;
  const auto get_projector = [&]() -> const ShellRitzProjector& {
    std::call_once(made,
                   [&] { projector = std::make_unique<ShellRitzProjector>(*shell, base_modes); });
    return *projector;
  };
  const std::vector<int64_t> rows = ShellModalBank::RowsRead(*shell, c.mics, placement_margin_m);
  const std::string cache = c.synth.ModeCacheDir();
  // each variant alone: its draws, its shell, Ritz modes to the base band, its bank
  tbb::parallel_for(int64_t{0}, count, [&](int64_t v) {
    const StructureVariant draw =
        DrawStructure(c.randomize, c.shell, c.material.poisson_ratio, c.seed, v);
    MaterialConfig material = c.material;
    material.poisson_ratio = draw.poisson_ratio;
    Variant& out = pool[static_cast<size_t>(v)];
    out.shell = std::make_unique<ShellModel>(c.tube, material, draw.shell);
    const ModeRows modes =
        CachedRitzModes(get_projector, *shell, *out.shell, mode_band_hz, rows, cache);
    out.bank = std::make_unique<ShellModalBank>(*out.shell, modes, c.mics, c.audio.sample_rate_hz,
                                                c.synth.decay_floor_db, c.synth.residual,
                                                placement_margin_m);
    out.values = draw.values;
  });
}

StrikeSynthesizer::StrikeSynthesizer(const AcousticModelConfig& config)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  config.tube.Validate();
  config.mics.Validate(config.tube);
  m.c = config;
  const AudioConfig& audio = config.audio;
  const SynthConfig& synth = config.synth;

  // widest band: the configured limit, never above 0.95 Nyquist
  const double nyquist = 0.5 * audio.sample_rate_hz;
  m.widest_band_hz = synth.max_frequency_hz > 0 ? synth.max_frequency_hz : 0.95 * nyquist;
  m.limit_band_hz = m.widest_band_hz;
  if (m.widest_band_hz >= nyquist) {
    throw ConfigError(
        fmt::format("acoustics.max_frequency_hz = {} must be below the Nyquist frequency {} Hz "
                    "(audio.sample_rate_hz / 2): modes above it alias",
                    synth.max_frequency_hz, nyquist));
  }
  m.daq = std::make_unique<DaqChain>(config.daq, config.noise, config.mics.count(),
                                     audio.sample_rate_hz, audio.num_samples());
  if (synth.model == VibrationModel::kModalClosedForm) {
    m.closed_form =
        std::make_unique<ClosedFormBank>(m.c.tube, m.c.material, m.c.mics, m.c.audio.sample_rate_hz,
                                         m.widest_band_hz, m.c.synth.decay_floor_db);
    return;
  }

  // the discretized shell
  config.shell.Validate(config.tube);
  m.shell = std::make_unique<ShellModel>(config.tube, config.material, config.shell);
  if (synth.model == VibrationModel::kFd) {
    // the FD rung steps the grid itself and closes its impacts against it: no modes to solve
    if (config.randomize.structure()) {
      throw ConfigError(
          fmt::format("randomize.structure_variants = {} needs acoustics.model = modal (the "
                      "variants are Ritz projections of its modes), not fd",
                      config.randomize.structure_variants));
    }
    m.fd = std::make_unique<ShellFd>(*m.shell, audio.sample_rate_hz, synth.fd_oversampling);
    m.sensor_rows = m.shell->SensorRows(config.mics);
    return;
  }
  // its modes (from the cache when solved before)
  // modes to the configured band; by default what the grid resolves (20 kHz) below Nyquist
  const double mode_band = synth.ModeBandHz(config.audio.sample_rate_hz);
  if (mode_band >= nyquist) {
    throw ConfigError(
        fmt::format("acoustics.mode_band_hz = {} must be below the Nyquist frequency "
                    "{} Hz",
                    synth.mode_band_hz, nyquist));
  }
  const std::string cache = synth.ModeCacheDir();
  const ShellModes modes = CachedShellModes(*m.shell, mode_band, 0, true, cache);
  m.widest_band_hz = std::min(m.widest_band_hz, mode_band);
  m.mode_band_hz = mode_band;
  const double margin = PlacementMargin(config);
  m.bank = std::make_unique<ShellModalBank>(*m.shell, modes, config.mics, audio.sample_rate_hz,
                                            synth.decay_floor_db, synth.residual, margin);
  if (config.randomize.structure()) {
    if (synth.model != VibrationModel::kModal) {
      throw ConfigError(
          fmt::format("randomize.structure_variants = {} needs acoustics.model = "
                      "modal (the variants are Ritz projections of its modes), not {}",
                      config.randomize.structure_variants, NameOf(synth.model)));
    }
    m.BuildPool(modes, margin);
  }
}

StrikeSynthesizer::~StrikeSynthesizer() = default;

int64_t StrikeSynthesizer::structure_variants() const {
  return static_cast<int64_t>(impl_->pool.size());
}

const std::vector<double>& StrikeSynthesizer::StructureValues(int64_t variant) const {
  SONICBOOM_DEMAND(variant >= 0 && variant < structure_variants());
  return impl_->pool[static_cast<size_t>(variant)].values;
}

int64_t StrikeSynthesizer::mode_count() const {
  if (impl_->bank) return impl_->bank->modes();
  return impl_->closed_form ? impl_->closed_form->families() : 0;
}

double StrikeSynthesizer::BandFor(double contact_duration_s) const {
  return impl_->Band(contact_duration_s, 1.0);
}

namespace {

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

}  // namespace

namespace {

// the striker of a contact under a variation: tip radius and modulus replaced, rigid mass and
// approach speed scaled (a struck rod keeps its beam modes)
ContactEvent VariedContact(const ContactEvent& contact, const Variation& v) {
  ContactEvent c = contact;
  if (v.striker_radius_m > 0) c.striker_radius_m = v.striker_radius_m;
  if (v.striker_youngs_modulus_pa > 0) c.striker_youngs_modulus_pa = v.striker_youngs_modulus_pa;
  if (c.beam_length_m <= 0) c.effective_mass_kg *= v.striker_mass_scale;
  c.normal_speed_m_s *= v.speed_scale;
  return c;
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

// whether a variation changes the structure the sample is played on (material, pool variant,
// mic placement), which only the numerical modal rung can follow
bool VariesStructure(const Variation* variation) {
  if (variation == nullptr) return false;
  const bool placed = !variation->mic_z_offset_m.empty() ||
                      !variation->mic_theta_offset_deg.empty() ||
                      !variation->disc_diameter_m.empty();
  return variation->frequency_scale() != 1.0 || variation->density_scale != 1.0 ||
         variation->loss_factor > 0.0 || variation->structure_variant >= 0 || placed;
}

}  // namespace

RenderedStrike StrikeSynthesizer::Render(const ContactEvent& given_contact,
                                         std::span<const ContactEpisode> episodes,
                                         std::span<const double> joint_speed_rad_s,
                                         double joint_speed_rate_hz, uint64_t sample_seed,
                                         const Variation* variation) const {
  const Impl& m = *impl_;
  const double fs = m.c.audio.sample_rate_hz;
  const int64_t num_frames = m.c.audio.num_samples();
  RenderedStrike out;
  const bool varied_structure = VariesStructure(variation);
  if (varied_structure && m.c.synth.model != VibrationModel::kModal) {
    throw ConfigError(
        "randomize: material, structure and placement ranges need acoustics.model = "
        "modal (the numerical modes vary exactly or by projection; the fd and "
        "closed-form rungs do not)");
  }
  // the structure this sample is played on: the configured one or a variant of the pool
  const ShellModalBank* bank = m.bank.get();
  const ShellModel* shell = m.shell.get();
  if (variation != nullptr && variation->structure_variant >= 0) {
    SONICBOOM_DEMAND(variation->structure_variant < static_cast<int64_t>(m.pool.size()));
    bank = m.pool[static_cast<size_t>(variation->structure_variant)].bank.get();
    shell = m.pool[static_cast<size_t>(variation->structure_variant)].shell.get();
  }
  const ContactEvent contact =
      variation != nullptr ? VariedContact(given_contact, *variation) : given_contact;
  const MaterialConfig material =
      variation != nullptr ? VariedMaterial(m.c.material, *variation) : m.c.material;

  // the rigid-wall Hertz impact: closed-form rung's pulse, and the contact band's first guess
  const HertzImpact impact = SolveHertzImpact(contact, m.c.tube, material);
  if (!std::isfinite(impact.duration_s) || impact.duration_s <= 0) {
    throw NumericalError(
        fmt::format("contact of speed {} m/s and mass {} kg has no finite "
                    "Hertz duration",
                    contact.normal_speed_m_s, contact.effective_mass_kg));
  }
  Eigen::MatrixXd strain;
  const auto t0 = std::chrono::steady_clock::now();
  if (m.closed_form) {
    out.impulse_ns = impact.impulse_ns;
    out.duration_s = impact.duration_s;
    out.peak_force_n = impact.peak_force_n;
    out.touches = 1;
    out.forces_played = 1;
    out.band_hz = BandFor(impact.duration_s);
    strain = m.ClosedFormStrain(contact, impact, &out);
  } else {
    const DrivingPoint striker = StrikerOf(contact, m.c.synth.contact.beam_max_frequency_hz);
    // the wall at the contact: its modes in the band the rigid-wall pulse suggests
    const double frequency_scale = varied_structure ? variation->frequency_scale() : 1.0;
    const double contact_band = m.Band(impact.duration_s, frequency_scale);
    // the fd rung with a yielding wall closes its impacts against the FD grid itself, in the run
    const bool fd_wall = m.fd && m.c.synth.contact.wall == ContactWall::kCoupled;
    std::vector<ForceInput> forces;
    std::vector<FdImpact> fd_impacts;
    // solves an impact (or hands it to the FD run, where the rigid-wall Hertz pulse's duration
    // stands in for it until then)
    auto play_contact = [&](double time_s, double z_m, double theta_rad, double speed_m_s,
                            double tube_side_kg, const DrivingPoint& other) {
      if (fd_wall) {
        fd_impacts.push_back({time_s, z_m, theta_rad, speed_m_s, tube_side_kg, other,
                              impact.stiffness_n_m15});
        ContactForce pending;
        pending.duration_s = pending.first_closure_s = impact.duration_s;
        return pending;
      }
      // a rigid wall is a held half-space: no modes, no rigid motion
      DrivingPoint wall;
      if (m.c.synth.contact.wall == ContactWall::kCoupled) {
        wall = bank->WallAt(z_m, theta_rad, contact_band, varied_structure ? variation : nullptr);
        wall.rigid_mass_kg =
            tube_side_kg > 0 ? tube_side_kg : std::numeric_limits<double>::infinity();
      }
      ContactForce cf = SolveContact(wall, other, impact.stiffness_n_m15, speed_m_s, time_s, fs,
                                     m.c.synth.contact);
      forces.push_back({z_m, theta_rad, cf.first_sample, std::move(cf.force_n)});
      return cf;
    };
    ContactForce first =
        play_contact(contact.time_s, contact.z_m, contact.theta_rad, contact.normal_speed_m_s,
                     contact.robot_side_mass_kg, striker);
    // the other episodes of the record: bounces and later impacts, presses, brushes
    Rng rng(sample_seed, Stream::kAcoustics);
    for (const ContactEpisode& e : episodes) {
      const bool is_first = std::abs(e.time_s - contact.time_s) < 0.5 / fs;
      if (e.kind == ContactEpisode::Kind::kBrush) {
        if (m.c.noise.foliage_force_rms_n <= 0) continue;
        const double z = std::clamp(e.z_m, -0.49 * m.c.tube.length_m, 0.49 * m.c.tube.length_m);
        // a brushed point in a hole has no wall to act on: its rustle is not played (the
        // check is made here, before the force reaches the bank or the FD grid, which refuse it)
        if (shell != nullptr && !shell->AcceptsForce(z, e.theta_rad)) continue;
        forces.push_back({z, e.theta_rad, static_cast<int64_t>(std::floor(e.time_s * fs)),
                          RustleForce(e.duration_s, fs, m.c.noise.foliage_force_rms_n,
                                      m.c.noise.foliage_low_hz, m.c.noise.foliage_high_hz, &rng)});
        continue;
      }
      if (e.kind == ContactEpisode::Kind::kPress && e.duration_s > 0) {
        // the impact that opened the press is played below (or above, as the first contact)
        const double start_s = e.time_s + (is_first ? first.duration_s : 0.0);
        forces.push_back({e.z_m, e.theta_rad, static_cast<int64_t>(std::floor(start_s * fs)),
                          PressForce(e.duration_s, e.impulse_Ns / e.duration_s, fs)});
      }
      if (is_first || !(e.normal_speed_m_s > 1e-4) || !(e.effective_mass_kg > 0)) continue;
      // a bounce or later impact: the same striker, its own speed and point
      DrivingPoint other = striker;
      const double mass_scale = variation != nullptr ? variation->striker_mass_scale : 1.0;
      const double speed_scale = variation != nullptr ? variation->speed_scale : 1.0;
      if (contact.beam_length_m <= 0) other.rigid_mass_kg = e.effective_mass_kg * mass_scale;
      play_contact(e.time_s, e.z_m, e.theta_rad, e.normal_speed_m_s * speed_scale,
                   contact.robot_side_mass_kg, other);
    }
    out.forces_played = static_cast<int64_t>(forces.size() + fd_impacts.size());

    if (m.fd) {
      out.modes_used = 0;
      FdRun run = FdRender(*m.shell, *m.fd, forces, fd_impacts, m.c.synth.contact, m.sensor_rows,
                           num_frames, m.c.synth.decay_floor_db);
      strain = std::move(run.strain);
      if (fd_wall) first = std::move(run.impacts.front());
    }
    out.impulse_ns = first.impulse_ns;
    out.duration_s = first.duration_s;
    out.peak_force_n = first.peak_force_n;
    out.touches = first.touches;
    // vibration: the band the first contact excites, or the configured count
    // (the first closure sets it: a chatter's later touches are softer and no shorter)
    out.band_hz = m.Band(first.first_closure_s, frequency_scale);
    if (!m.fd) {
      const Variation* structure = varied_structure ? variation : nullptr;
      out.modes_used = m.c.synth.mode_count > 0 ? std::min(m.c.synth.mode_count, bank->modes())
                                                : bank->ModesBelow(out.band_hz, structure);
      strain = bank->Render(forces, out.modes_used, num_frames, structure);
    }
  }
  out.vibration_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // piezo, background, converter
  out.clipped = m.daq->Convert(strain, joint_speed_rad_s, joint_speed_rate_hz, sample_seed,
                               &out.audio, variation);
  return out;
}

}  // namespace sonicboom::acoustics
