// The rungs of the ladder (internal/render_stages.h), one class each, and the one factory that
// makes the rung acoustics.model names: the closed-form tube, the shell's numerical modes (with
// the structure pool), and the FD grid of the same shell.
#include <algorithm>
#include <cmath>
#include <mutex>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "internal/render_stages.h"
#include "sonicboom/acoustics/closed_form_bank.h"
#include "sonicboom/acoustics/shell_fd.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/shell_ritz.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {

const std::vector<double>& VibrationRenderer::StructureValues(int64_t) const {
  SONICBOOM_DEMAND(false && "a rung without a structure pool");
  static const std::vector<double> none;
  return none;
}

Eigen::MatrixXd VibrationRenderer::PlayImpacts(std::span<const FdImpact>, int64_t) const {
  throw Error("VibrationRenderer::PlayImpacts: only the FD rung closes its own contact");
}

DrivingPoint VibrationRenderer::WallAt(double, double, double) const {
  throw Error("VibrationRenderer::WallAt: only the modal rung has a modal wall");
}

namespace {

// the closed-form and FD rungs play the configured structure only
void RequireNominal(const SampleView& view) {
  if (!view.structure.Nominal()) {
    throw ConfigError(
        "randomize: material, structure and placement ranges need acoustics.model = "
        "modal (the numerical modes vary exactly or by projection; the fd and "
        "closed-form rungs do not)");
  }
}

// the first contact's figures in a rendered strike
void Report(const ContactForce& first, RenderedStrike* out) {
  out->impulse_ns = first.impulse_ns;
  out->duration_s = first.duration_s;
  out->peak_force_n = first.peak_force_n;
  out->touches = first.touches;
}

// acoustics.model = modal-closed-form: the first contact's rigid-wall Hertz pulse on the ideal
// simply supported tube's Flügge modes (no episodes, no seam)
class ClosedFormRenderer final : public VibrationRenderer {
 public:
  ClosedFormRenderer(const AcousticModelConfig& c, const BandRule& band)
      : VibrationRenderer(band),
        c_(c),
        bank_(c.tube, c.material, c.mics, c.audio.sample_rate_hz, band.limit_hz,
              c.synth.decay_floor_db) {}

  int64_t mode_count() const override { return bank_.families(); }
  Eigen::MatrixXd PlayForces(std::span<const ForceInput> forces, double band_hz,
                             int64_t frames) const override {
    return bank_.Render(forces, band_hz, frames);
  }
  int64_t ModesPlayed(double band_hz) const override {
    return bank_.FrequenciesHz(band_hz).size();
  }
  Eigen::VectorXd FrequenciesHz() const override { return bank_.FrequenciesHz(band_.limit_hz); }

  Eigen::MatrixXd Play(const SampleView& view, std::span<const ContactEpisode>, uint64_t,
                       RenderedStrike* out) const override {
    RequireNominal(view);
    const HertzImpact& impact = view.impact;
    out->impulse_ns = impact.impulse_ns;
    out->duration_s = impact.duration_s;
    out->peak_force_n = impact.peak_force_n;
    out->touches = 1;
    out->forces_played = 1;
    out->band_hz = band_(impact.duration_s);
    const ForceInput pulse = Pulse(view);
    return bank_.Render(std::span<const ForceInput>(&pulse, 1), out->band_hz,
                        view.frames, &out->modes_used);
  }

 private:
  // the Hertz pulse at audio rate, each sample the mean over force_substeps points within it
  ForceInput Pulse(const SampleView& view) const;
  AcousticModelConfig c_;
  ClosedFormBank bank_;
};

ForceInput ClosedFormRenderer::Pulse(const SampleView& view) const {
  const ContactEvent& contact = view.contact;
  const double fs = c_.audio.sample_rate_hz;
  const double T = 1.0 / fs;
  const int64_t k_first = static_cast<int64_t>(std::floor(contact.time_s * fs));
  const int64_t k_last =
      static_cast<int64_t>(std::ceil((contact.time_s + view.impact.duration_s) * fs));
  std::vector<double> force(std::max<int64_t>(k_last - k_first + 1, 1));  // N, per sample
  const int64_t sub = c_.synth.force_substeps;
  for (size_t j = 0; j < force.size(); ++j) {
    double acc = 0;
    for (int64_t s = 0; s < sub; ++s) {
      const double t = (k_first + static_cast<double>(j) + (s + 0.5) / sub) * T;
      acc += HertzForce(view.impact, t - contact.time_s);
    }
    force[j] = acc / sub;
  }
  return ForceInput{contact.z_m, contact.theta_rad, k_first, std::move(force)};
}

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

// acoustics.model = modal: the discretized shell's numerical modes, and the structure pool's
// variants (Ritz projections of them); the one rung that follows a drawn structure
class ModalRenderer final : public VibrationRenderer {
 public:
  ModalRenderer(const AcousticModelConfig& c, const BandRule& band);

  int64_t mode_count() const override { return bank_->modes(); }
  Eigen::MatrixXd PlayForces(std::span<const ForceInput> forces, double band_hz,
                             int64_t frames) const override {
    return bank_->Render(forces, ModesPlayed(band_hz), frames);
  }
  int64_t ModesPlayed(double band_hz) const override { return ModesOf(*bank_, band_hz, {}); }
  DrivingPoint WallAt(double z_m, double theta_rad, double band_hz) const override {
    return bank_->WallAt(z_m, theta_rad, band_hz);
  }
  Eigen::VectorXd FrequenciesHz() const override { return bank_->frequencies_hz(); }
  Eigen::VectorXd GridFrequenciesHz() const override { return grid_omega_ / (2.0 * kPi); }
  int64_t dofs() const override { return shell_->dofs(); }
  int64_t structure_variants() const override { return static_cast<int64_t>(pool_.size()); }
  const std::vector<double>& StructureValues(int64_t variant) const override {
    SONICBOOM_DEMAND(variant >= 0 && variant < structure_variants());
    return pool_[static_cast<size_t>(variant)].values;
  }

  Eigen::MatrixXd Play(const SampleView& view, std::span<const ContactEpisode> episodes,
                       uint64_t sample_seed, RenderedStrike* out) const override;

 private:
  // the modes a bank plays for band_hz on a structure: acoustics.mode_count, or those below it
  int64_t ModesOf(const ShellModalBank& bank, double band_hz,
                  const StructureDraw& structure) const {
    return c_.synth.mode_count > 0 ? std::min(c_.synth.mode_count, bank.modes())
                                   : bank.ModesBelow(band_hz, structure);
  }
  // the structure pool from the base modes (with shapes): variants drawn, Ritz modes, banks
  void BuildPool(const ShellModes& base_modes, double placement_margin_m);
  struct Variant {
    std::unique_ptr<ShellModel> shell;
    std::unique_ptr<ShellModalBank> bank;
    std::vector<double> values;
  };
  AcousticModelConfig c_;
  std::unique_ptr<ShellModel> shell_;
  std::unique_ptr<ShellModalBank> bank_;
  Eigen::VectorXd grid_omega_;  // (modes) as the grid solved them, rad/s
  std::vector<Variant> pool_;
};

ModalRenderer::ModalRenderer(const AcousticModelConfig& c, const BandRule& band)
    : VibrationRenderer(band), c_(c) {
  shell_ = std::make_unique<ShellModel>(c.tube, c.material, c.shell);
  // its modes to band_.mode_band_hz (from the cache when solved before)
  const ShellModes modes =
      CachedShellModes(*shell_, band_.mode_band_hz, 0, true, c.synth.ModeCacheDir());
  grid_omega_ = modes.omega_rad_s;
  const double margin = PlacementMargin(c);
  bank_ = std::make_unique<ShellModalBank>(*shell_, modes, c.mics, c.audio.sample_rate_hz,
                                           c.synth.decay_floor_db, c.synth.residual, margin);
  if (c.randomize.structure()) BuildPool(modes, margin);
}

void ModalRenderer::BuildPool(const ShellModes& base_modes, double placement_margin_m) {
  const int64_t count = c_.randomize.structure_variants;
  pool_.resize(static_cast<size_t>(count));
  // the projector is made only when some variant is not in the cache
  std::once_flag made;
  std::unique_ptr<ShellRitzProjector> projector;
  const auto get_projector = [&]() -> const ShellRitzProjector& {
    std::call_once(made,
                   [&] { projector = std::make_unique<ShellRitzProjector>(*shell_, base_modes); });
    return *projector;
  };
  const std::vector<int64_t> rows = ShellModalBank::RowsRead(*shell_, c_.mics, placement_margin_m);
  const std::string cache = c_.synth.ModeCacheDir();
  // each variant alone: its draws, its shell, Ritz modes to the base band, its bank
  tbb::parallel_for(int64_t{0}, count, [&](int64_t v) {
    const StructureVariant draw = DrawStructure(
        c_.randomize, {c_.tube, c_.shell, c_.mics, c_.material.poisson_ratio}, c_.seed, v);
    MaterialConfig material = c_.material;
    material.poisson_ratio = draw.poisson_ratio;
    Variant& out = pool_[static_cast<size_t>(v)];
    out.shell = std::make_unique<ShellModel>(c_.tube, material, draw.shell);
    const ModeRows modes =
        CachedRitzModes(get_projector, *shell_, *out.shell, band_.mode_band_hz, rows, cache);
    out.bank = std::make_unique<ShellModalBank>(*out.shell, modes, c_.mics,
                                                c_.audio.sample_rate_hz, c_.synth.decay_floor_db,
                                                c_.synth.residual, placement_margin_m);
    out.values = draw.values;
  });
}

Eigen::MatrixXd ModalRenderer::Play(const SampleView& view, std::span<const ContactEpisode> episodes,
                                uint64_t sample_seed, RenderedStrike* out) const {
  // the structure this sample is played on: the configured one or a variant of the pool
  const int64_t variant = view.structure.structure_variant;
  SONICBOOM_DEMAND(variant < structure_variants());
  const Variant* drawn = variant >= 0 ? &pool_[static_cast<size_t>(variant)] : nullptr;
  const ShellModalBank& bank = drawn != nullptr ? *drawn->bank : *bank_;
  const double scale = view.structure.frequency_scale();
  // the wall at each contact: its modes in the band the rigid-wall pulse suggests
  ExcitationWall wall;
  if (c_.synth.contact.wall == ContactWall::kCoupled) {
    wall.modes_at = [&](double z_m, double theta_rad, double band_hz) {
      return bank.WallAt(z_m, theta_rad, band_hz, view.structure);
    };
  }
  wall.shell = drawn != nullptr ? drawn->shell.get() : shell_.get();
  wall.contact_band_hz = band_(view.impact.duration_s, scale);
  const Excitation ex = Excite(c_, view, episodes, sample_seed, wall);
  out->forces_played = static_cast<int64_t>(ex.forces.size());
  Report(ex.first, out);
  // vibration: the band the first contact excites, or the configured count (the first closure
  // sets it: a chatter's later touches are softer and no shorter)
  out->band_hz = band_(ex.first.first_closure_s, scale);
  out->modes_used = ModesOf(bank, out->band_hz, view.structure);
  return bank.Render(ex.forces, out->modes_used, view.frames, view.structure);
}

// acoustics.model = fd: the same shell stepped on its grid, impacts closed against the grid
// itself when the wall yields (acoustics.contact.wall = coupled); needs no modes
class FdRenderer final : public VibrationRenderer {
 public:
  FdRenderer(const AcousticModelConfig& c, const BandRule& band)
      : VibrationRenderer(band),
        c_(c),
        shell_(c.tube, c.material, c.shell),
        fd_(shell_, c.audio.sample_rate_hz, c.synth.fd_oversampling),
        sensor_rows_(shell_.SensorRows(c.mics)) {}

  int64_t mode_count() const override { return 0; }
  Eigen::MatrixXd PlayForces(std::span<const ForceInput> forces, double,
                             int64_t frames) const override {
    return FdRender(shell_, fd_, forces, sensor_rows_, frames, c_.synth.decay_floor_db);
  }
  int64_t ModesPlayed(double) const override { return 0; }
  Eigen::MatrixXd PlayImpacts(std::span<const FdImpact> impacts, int64_t frames) const override {
    return FdRender(shell_, fd_, {}, impacts, c_.synth.contact, sensor_rows_, frames,
                    c_.synth.decay_floor_db)
        .strain;
  }
  int64_t dofs() const override { return shell_.dofs(); }
  int64_t oversampling() const override { return fd_.oversampling(); }

  Eigen::MatrixXd Play(const SampleView& view, std::span<const ContactEpisode> episodes,
                       uint64_t sample_seed, RenderedStrike* out) const override {
    RequireNominal(view);
    ExcitationWall wall;
    wall.closes_impacts = c_.synth.contact.wall == ContactWall::kCoupled;
    wall.shell = &shell_;
    Excitation ex = Excite(c_, view, episodes, sample_seed, wall);
    out->forces_played = static_cast<int64_t>(ex.forces.size() + ex.fd_impacts.size());
    out->modes_used = 0;
    FdRun run = FdRender(shell_, fd_, ex.forces, ex.fd_impacts, c_.synth.contact, sensor_rows_,
                         view.frames, c_.synth.decay_floor_db);
    if (wall.closes_impacts) ex.first = std::move(run.impacts.front());
    Report(ex.first, out);
    out->band_hz = band_(ex.first.first_closure_s);
    return std::move(run.strain);
  }

 private:
  AcousticModelConfig c_;
  ShellModel shell_;
  ShellFd fd_;
  Eigen::MatrixXd sensor_rows_;  // (mics x dofs)
};

// The most modes a modal rung solves for: about 7x the default tube's 715 plate-estimated
// bending modes below 20 kHz; the solve's cost grows faster than the count.
constexpr double kMostModes = 5000.0;

// A fixed band (max_frequency_hz, mode_band_hz) is 0 (derived) or at least kLowestBandHz.
void RequireAudibleBand(const char* key, double band_hz) {
  if (band_hz > 0.0 && band_hz < kLowestBandHz) {
    throw ConfigError(fmt::format(
        "acoustics.{} = {} Hz lies below {} Hz: a band that low holds at most the tube's lowest "
        "ring modes and no wavefront (0 derives the band from the contact)",
        key, band_hz, kLowestBandHz));
  }
}

// Bending modes of the wall below band_hz, by the thin plate's asymptotic count
// N = A f sqrt(rho h / D) / 2 over the wall's mid surface A: a modal solve refuses a tube that
// would hold more than kMostModes (a wall too thin for its band) instead of running for hours.
void RequireSolvableModeCount(const AcousticModelConfig& c, double band_hz) {
  const TubeConfig& t = c.tube;
  const MaterialConfig& m = c.material;
  const double area_m2 = 2.0 * kPi * t.mid_radius_m() * t.length_m;
  const double rigidity = m.youngs_modulus_pa * std::pow(t.wall_thickness_m, 3) /
                          (12.0 * (1.0 - m.poisson_ratio * m.poisson_ratio));
  const double modes =
      0.5 * area_m2 * band_hz * std::sqrt(m.density_kg_m3 * t.wall_thickness_m / rigidity);
  if (modes > kMostModes) {
    throw ConfigError(fmt::format(
        "this tube holds about {:.0f} bending modes below {:.0f} Hz (the modes solved), more than "
        "the {:.0f} a modal solve takes (tube.wall_thickness_m = {} m, tube.length_m = {} m, "
        "tube.outer_radius_m = {} m, material.youngs_modulus_pa = {} Pa, material.density_kg_m3 "
        "= {}); thicken the wall, shorten the tube, lower acoustics.max_frequency_hz or use "
        "acoustics.model = fd",
        modes, band_hz, kMostModes, t.wall_thickness_m, t.length_m, t.outer_radius_m,
        m.youngs_modulus_pa, m.density_kg_m3));
  }
}

}  // namespace

std::unique_ptr<VibrationRenderer> MakeVibrationRenderer(const AcousticModelConfig& config) {
  const SynthConfig& synth = config.synth;
  const double nyquist = 0.5 * config.audio.sample_rate_hz;
  // the widest band: the configured limit, never above 0.95 Nyquist
  RequireAudibleBand("max_frequency_hz", synth.max_frequency_hz);
  RequireAudibleBand("mode_band_hz", synth.mode_band_hz);
  BandRule band;
  band.limit_hz = synth.max_frequency_hz > 0 ? synth.max_frequency_hz : 0.95 * nyquist;
  band.fixed = synth.max_frequency_hz > 0;
  band.band_factor = synth.band_factor;
  if (band.limit_hz >= nyquist) {
    throw ConfigError(
        fmt::format("acoustics.max_frequency_hz = {} must be below the Nyquist frequency {} Hz "
                    "(audio.sample_rate_hz / 2): modes above it alias",
                    synth.max_frequency_hz, nyquist));
  }
  if (synth.render_span == RenderSpan::kFeatures && !(synth.span_after_contact_s > 0.0)) {
    throw ConfigError(
        "acoustics.render_span = features needs the features' span (derived from "
        "features.window_s by the pipeline: generate, rerender, fidelity)");
  }
  if (synth.model == VibrationModel::kModalClosedForm) {
    RequireSolvableModeCount(config, band.limit_hz);
    return std::make_unique<ClosedFormRenderer>(config, band);
  }
  // the discretized shell's rungs
  config.shell.Validate(config.tube);
  if (config.randomize.structure() && synth.model != VibrationModel::kModal) {
    throw ConfigError(
        fmt::format("randomize.structure_variants = {} needs acoustics.model = modal (the "
                    "variants are Ritz projections of its modes), not {}",
                    config.randomize.structure_variants, NameOf(synth.model)));
  }
  // the FD rung steps the grid itself and closes its impacts against it: no modes to solve
  if (synth.model == VibrationModel::kFd) return std::make_unique<FdRenderer>(config, band);
  // modes to the configured band; by default what the grid resolves (20 kHz) below Nyquist
  band.mode_band_hz = SolvedModeBandHz(synth, config.audio.sample_rate_hz, config.randomize);
  if (band.mode_band_hz >= nyquist) {
    throw ConfigError(fmt::format(
        "acoustics.mode_band_hz = {} must be below the Nyquist frequency {} Hz",
        synth.mode_band_hz, nyquist));
  }
  RequireSolvableModeCount(config, band.mode_band_hz);
  return std::make_unique<ModalRenderer>(config, band);
}

}  // namespace sonicboom::acoustics
