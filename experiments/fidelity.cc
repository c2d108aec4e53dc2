// The fidelity ladder measured: every rung of the vibration model renders the same strikes (the
// same contact forces), and is timed and compared against the reference solid (solid/), a model
// of another theory and discretization converged apart (docs/reference_model.md).
#include <CLI/CLI.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <numeric>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/fidelity_ladder.h"
#include "internal/fidelity_metrics.h"
#include "internal/fidelity_strikes.h"
#include "internal/reference.h"
#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/acoustics/ladder.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/hardware/npy.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_response.h"

namespace sonicboom::experiments {

// what the ladder asks of a rung, whichever model renders it (declared in
// internal/fidelity_ladder.h)
class LadderRung {
 public:
  virtual ~LadderRung() = default;
  /// (mics x samples) sensor strain of the strike from rest: its forces, or (a rung that closes
  /// its own contact) its impact.
  virtual Eigen::MatrixXd Render(std::span<const acoustics::ForceInput> forces,
                                 const acoustics::FdImpact& impact, int64_t samples,
                                 double derived_band_hz) const = 0;
  /// (modes) the frequencies of the modes a render plays, ascending, Hz (empty: not modal).
  virtual Eigen::VectorXd PlayedFrequenciesHz(double derived_band_hz) const = 0;
  /// (modes) the same as its discretization solved them (before a dispersion correction), Hz.
  virtual Eigen::VectorXd GridFrequenciesHz(double derived_band_hz) const {
    return PlayedFrequenciesHz(derived_band_hz);
  }
  virtual int64_t dofs() const = 0;
  /// FD: time steps per audio sample (its cost per sample is constant); 0 for a modal rung.
  virtual int64_t oversampling() const { return 0; }
};

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
// s without `suffix` at its end (as given when it does not end so)
std::string WithoutSuffix(std::string s, std::string_view suffix) {
  if (s.size() > suffix.size() && s.ends_with(suffix)) s.resize(s.size() - suffix.size());
  return s;
}

// how a grid's name marks its dispersion: nothing for the thin plate, ", thick-plate" otherwise
std::string DispersionMark(acoustics::Dispersion d) {
  return d == acoustics::Dispersion::kThin ? "" : ", " + std::string(NameOf(d));
}

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// one grid of the shell
struct Grid {
  std::string name;
  double arc_m, axial_m;
  // the modal rung's dispersion on it (shell.dispersion); empty = the configured one
  std::optional<acoustics::Dispersion> dispersion{};
};

// a rung of the shell (acoustics/ladder.h): modal or FD on one grid
class ShellRung final : public LadderRung {
 public:
  // own_contact: an FD rung that closes the strike's impact against its own wall
  ShellRung(std::unique_ptr<acoustics::VibrationRung> rung, bool own_contact)
      : rung_(std::move(rung)), own_contact_(own_contact) {}
  Eigen::MatrixXd Render(std::span<const acoustics::ForceInput> forces,
                         const acoustics::FdImpact& impact, int64_t samples,
                         double derived_band_hz) const override {
    if (own_contact_) return rung_->RenderImpacts(std::span(&impact, 1), samples);
    return rung_->Render(forces, samples, derived_band_hz);
  }
  Eigen::VectorXd PlayedFrequenciesHz(double derived_band_hz) const override {
    if (rung_->fd()) return {};
    return rung_->FrequenciesHz().head(rung_->ModesPlayed(derived_band_hz));
  }
  Eigen::VectorXd GridFrequenciesHz(double derived_band_hz) const override {
    if (rung_->fd()) return {};
    const Eigen::VectorXd solved = rung_->GridFrequenciesHz();
    if (solved.size() == 0) return PlayedFrequenciesHz(derived_band_hz);  // the closed form
    return solved.head(std::min<Eigen::Index>(solved.size(), rung_->ModesPlayed(derived_band_hz)));
  }
  int64_t dofs() const override { return rung_->dofs(); }
  int64_t oversampling() const override { return rung_->oversampling(); }

 private:
  std::unique_ptr<acoustics::VibrationRung> rung_;
  bool own_contact_;
};

// a rung of the reference solid: its modes below band_hz, each damped by zeta(omega), driven by
// the forces at their points (solid/solid_response.h)
class SolidRung final : public LadderRung {
 public:
  SolidRung(std::shared_ptr<const solid::ReferenceTube> tube, double band_hz, double sample_rate_hz,
            const std::function<double(double)>& zeta_of_omega)
      : tube_(std::move(tube)), sample_rate_hz_(sample_rate_hz) {
    const Eigen::VectorXd& omega = tube_->omega_rad_s();
    modes_ = (omega.array() < 2 * kPi * band_hz).count();
    zeta_.resize(modes_);
    for (Eigen::Index n = 0; n < modes_; ++n) zeta_(n) = std::min(0.5, zeta_of_omega(omega(n)));
  }
  Eigen::MatrixXd Render(std::span<const acoustics::ForceInput> forces,
                         const acoustics::FdImpact& /*impact*/, int64_t samples,
                         double /*derived_band_hz*/) const override {
    const Eigen::VectorXd omega = tube_->omega_rad_s().head(modes_);
    const Eigen::MatrixXd read = tube_->disc_strain().leftCols(modes_);  // (mics x modes)
    Eigen::MatrixXd y = Eigen::MatrixXd::Zero(read.rows(), samples);
    for (const acoustics::ForceInput& f : forces) {
      // a strike pushes the wall inward: against the outward drive of each shape
      const Eigen::VectorXd drive = -tube_->ModalDrive(f.z_m, f.theta_rad).head(modes_);
      y += solid::ForcedResponse(omega, zeta_, read, drive, f.force_n, f.first_sample,
                                 sample_rate_hz_, samples);
    }
    return y;
  }
  Eigen::VectorXd PlayedFrequenciesHz(double /*derived_band_hz*/) const override {
    return tube_->omega_rad_s().head(modes_) / (2 * kPi);
  }
  int64_t dofs() const override { return tube_->model().dofs(); }

 private:
  std::shared_ptr<const solid::ReferenceTube> tube_;
  double sample_rate_hz_;
  Eigen::Index modes_{0};
  Eigen::VectorXd zeta_;  // (modes)
};

// the strikes every rung renders: their contact forces (solved once against the configured
// grid's modal wall), the same strikes as impacts (for a rung that closes its own contact) and
// derived bands
struct LadderStrikes {
  std::vector<std::vector<acoustics::ForceInput>> forces;  // [strike][contact]
  std::vector<acoustics::FdImpact> impacts;                // [strike]
  std::vector<double> derived_band_hz;                     // [strike]
  int64_t window{0};          // samples compared after the start of the record
  int64_t one_second{0};      // samples
  WavefrontWindow wavefront;  // the early wavefront's samples, aligned channel by channel
};

// The yardstick's signals (low-passed to its band), octave energies and mode frequencies.
struct Yardstick {
  double band_hz{0.0};
  std::vector<Eigen::MatrixXd> signal;  // [strike] mics x window
  std::vector<Eigen::VectorXd> bands;   // [strike] octave energies
  Eigen::VectorXd frequencies_hz;       // (modes) ascending
};

// Seconds a rung takes for 1 s of 6 channels of one strike: FD timed on the window and scaled
// (its cost per sample is constant), a modal rung on a whole second, best of nine.
double SecondsPerStrike(const LadderRung& rung, size_t strike, const LadderStrikes& strikes,
                        double window_seconds) {
  if (rung.oversampling() > 0) {
    return window_seconds * static_cast<double>(strikes.one_second) /
           static_cast<double>(strikes.window);
  }
  // the best of 9 renders: a render takes 1-2 ms, and on a busy machine the best of 3 still
  // varied by half between rungs doing the same work
  constexpr int kRenders = 9;
  double best = 1e30;
  for (int rep = 0; rep < kRenders; ++rep) {
    const auto t0 = Clock::now();
    const Eigen::MatrixXd full = rung.Render(strikes.forces[strike], strikes.impacts[strike],
                                             strikes.one_second, strikes.derived_band_hz[strike]);
    best = std::min(best, Seconds(t0));
    if (full.hasNaN()) throw NumericalError("fidelity: NaN in a modal render");
  }
  return best;
}

// Times one rung on every strike and measures it against the yardstick (which the rung becomes
// when the yardstick is still empty). Signals are compared low-passed to the yardstick's band.
RungResult MeasureRung(const RungEntry& entry, const LadderRung& rung, const LadderStrikes& strikes,
                       double fs, double frequency_max_hz, Yardstick* yardstick,
                       std::vector<Eigen::MatrixXd>* signals) {
  RungResult r;
  r.dofs = static_cast<double>(rung.dofs());
  r.oversampling = static_cast<double>(rung.oversampling());
  const size_t n = strikes.forces.size();
  const bool is_yardstick = yardstick->signal.empty();
  std::vector<double> arrivals, delays;  // every channel's, every pair's |error|, us
  std::vector<double> shifts, aligned;   // the same by aligned wavefronts, us
  for (size_t s = 0; s < n; ++s) {
    const auto& f = strikes.forces[s];
    const double band = strikes.derived_band_hz[s];
    const auto start = Clock::now();
    const Eigen::MatrixXd raw = rung.Render(f, strikes.impacts[s], strikes.window, band);
    const double window_seconds = Seconds(start);
    if (!raw.allFinite())
      throw NumericalError(fmt::format("fidelity: {} produced a non-finite signal", entry.name));
    const Eigen::MatrixXd y = LowPass(raw, yardstick->band_hz, fs);
    signals->push_back(y);
    r.ms_per_strike += 1e3 * SecondsPerStrike(rung, s, strikes, window_seconds) / n;
    r.modes += static_cast<double>(rung.PlayedFrequenciesHz(band).size()) / n;
    if (is_yardstick) {
      yardstick->signal.push_back(y);
      yardstick->bands.push_back(OctaveEnergies(y, fs));
    }
    const TimingError t = TimingErrorUs(y, yardstick->signal[s], fs, strikes.wavefront);
    arrivals.insert(arrivals.end(), t.arrival_errors_us.begin(), t.arrival_errors_us.end());
    delays.insert(delays.end(), t.delay_errors_us.begin(), t.delay_errors_us.end());
    shifts.insert(shifts.end(), t.shift_errors_us.begin(), t.shift_errors_us.end());
    aligned.insert(aligned.end(), t.aligned_delay_errors_us.begin(),
                   t.aligned_delay_errors_us.end());
    r.rel_error += RelativeError(y, yardstick->signal[s]) / n;
    r.arrival_us += t.arrival_us / n;
    r.delay_us += t.delay_us / n;
    r.delay_max_us = std::max(r.delay_max_us, t.delay_max_us);
    r.band_error_db += BandEnergyErrorDb(OctaveEnergies(y, fs), yardstick->bands[s]) / n;
  }
  r.arrival_median_us = Median(arrivals);
  r.delay_median_us = Median(delays);
  r.channels = static_cast<int64_t>(arrivals.size());
  r.hops = std::count_if(arrivals.begin(), arrivals.end(), [](double e) { return e > kHopUs; });
  auto mean = [](const std::vector<double>& v) {
    return v.empty() ? 0.0
                     : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  };
  r.shift_us = mean(shifts);
  r.shift_median_us = Median(shifts);
  r.aligned_delay_us = mean(aligned);
  r.aligned_delay_median_us = Median(aligned);
  r.aligned_delay_max_us =
      aligned.empty() ? 0.0 : *std::max_element(aligned.begin(), aligned.end());
  // frequencies: the modes it plays for the widest of the strikes' bands
  const double widest =
      *std::max_element(strikes.derived_band_hz.begin(), strikes.derived_band_hz.end());
  const Eigen::VectorXd played = rung.PlayedFrequenciesHz(widest);
  if (is_yardstick) yardstick->frequencies_hz = played;
  r.frequency = RankedFrequencyError(played, yardstick->frequencies_hz, frequency_max_hz);
  r.grid_frequency = RankedFrequencyError(rung.GridFrequenciesHz(widest), yardstick->frequencies_hz,
                                          frequency_max_hz);
  return r;
}

// The options, the output's directory and the plot script, before any work.
void CheckFidelityOptions(const FidelityOptions& o, double sample_rate_hz) {
  if (o.strikes < 1 || o.strikes > static_cast<int64_t>(std::size(kStrikes))) {
    throw ConfigError(
        fmt::format("--strikes must be in [1, {}], got {}", std::size(kStrikes), o.strikes));
  }
  if (!(o.window_s >= 0.005 && o.window_s <= 1.0)) {
    throw ConfigError(fmt::format("--window-s must be in [0.005, 1], got {}", o.window_s));
  }
  if (!(o.reference_band_hz >= 1000.0 && o.reference_band_hz <= 0.45 * sample_rate_hz)) {
    throw ConfigError(fmt::format(
        "--reference-band must be in [1000, {:.0f}] Hz (0.45 of audio.sample_rate_hz), got {}",
        0.45 * sample_rate_hz, o.reference_band_hz));
  }
  if (!(o.reference_element_m >= 0.005 && o.reference_element_m <= 0.05)) {
    throw ConfigError(fmt::format("--reference-element must be in [0.005, 0.05] m, got {}",
                                  o.reference_element_m));
  }
  if (!o.out.empty()) RequireParentDir(o.out);
  if (!o.plot_script.empty() && !o.out.empty() && !std::filesystem::is_regular_file(o.plot_script))
    throw IoError(
        fmt::format("--plot {}: no such script (--plot \"\" draws no figure)", o.plot_script));
  if (!o.signals_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.signals_dir, ec);
    if (ec || !std::filesystem::is_directory(o.signals_dir))
      throw IoError(fmt::format("--signals {}: cannot make the directory ({})", o.signals_dir,
                                ec ? ec.message() : "not a directory"));
  }
}

// What every rung of one ladder shares, derived once from the config and the options: the
// shell grids, the yardstick's band and mesh, the modes' band and cache, and the damping every
// rung realizes (the FD rung's Rayleigh curve, so that the table measures discretization, theory
// and truncation; the law's own fit error is the section below the table).
struct LadderSettings {
  double fs{0.0};
  Grid configured, fine, coarse, coarser;
  Grid longer;  // the configured arc spacing, twice the axial (a cheaper grid of the same rows)
  double reference_band_hz{0.0};    // the yardstick's modes, and the comparison's low-pass
  double reference_element_m{0.0};  // the yardstick's mesh
  double full_band_hz{0.0};         // the modes every modal rung draws from
  std::string cache;
  MaterialConfig rayleigh_material;
  acoustics::ShellConfig rayleigh_shell;
};

LadderSettings SettingsOf(const SonicBoomConfig& config, const FidelityOptions& o) {
  LadderSettings s;
  s.fs = config.audio.sample_rate_hz;
  const double arc = config.shell.grid_spacing_m, axial = config.shell.AxialSpacing();
  const double finest = o.quick ? 0.005 : std::min(arc, axial);
  s.configured = {"configured", o.quick ? 0.005 : arc, o.quick ? 0.01 : axial};
  s.fine = {"fine", finest, finest};
  s.coarse = {"coarse", 2 * s.configured.arc_m, 2 * s.configured.axial_m};
  s.longer = {"longer", s.configured.arc_m, 2 * s.configured.axial_m};
  s.coarser = {"coarser", 0.01, 0.02};
  s.reference_band_hz = o.quick ? std::min(o.reference_band_hz, 5000.0) : o.reference_band_hz;
  s.reference_element_m = o.quick ? std::max(o.reference_element_m, 0.03) : o.reference_element_m;
  s.full_band_hz = config.acoustics.ModeBandHz(s.fs);
  s.cache = config.acoustics.ModeCacheDir();
  s.rayleigh_material = config.material;
  s.rayleigh_shell = config.shell;
  acoustics::UseFdDamping(config.tube, &s.rayleigh_material, &s.rayleigh_shell);
  return s;
}

// A rung of the shell on `grid` (modal, FD or the closed form, by spec.model), made by the strike
// renderer's factory from the configuration, damped by the shared Rayleigh curve.
std::unique_ptr<acoustics::VibrationRung> BuildShellRung(const SonicBoomConfig& config,
                                                         const LadderSettings& s,
                                                         acoustics::RungSpec spec,
                                                         const Grid& grid) {
  spec.arc_m = grid.arc_m;
  spec.axial_m = grid.axial_m;
  acoustics::AcousticModelConfig base = AcousticModel(config);
  base.material = s.rayleigh_material;
  base.shell = s.rayleigh_shell;
  if (grid.dispersion) base.shell.dispersion = *grid.dispersion;
  return std::make_unique<acoustics::VibrationRung>(base, spec, s.full_band_hz);
}

// The reference solid of the configured structure on elements of element_m, modes to band_hz
// (from the mode cache when there); logs its size and the time it took.
std::shared_ptr<const solid::ReferenceTube> BuildReference(const SonicBoomConfig& config,
                                                           const LadderSettings& s,
                                                           double element_m, std::string* md) {
  solid::SolidMeshConfig mesh;
  mesh.element_arc_m = mesh.element_axial_m = element_m;
  const auto t0 = Clock::now();
  auto tube = std::make_shared<const solid::ReferenceTube>(
      ReferenceTubeOf(config, mesh, s.reference_band_hz, false, s.cache));
  *md += fmt::format(
      "- Reference solid, elements of {:.1f} mm: {} DOFs, {} modes to {:.0f} Hz, "
      "{} in {:.0f} s.\n",
      1e3 * element_m, tube->model().dofs(), tube->omega_rad_s().size(), s.reference_band_hz,
      tube->from_cache() ? "read from the mode cache" : "solved", Seconds(t0));
  return tube;
}

// The rungs, the yardstick first: the reference solid, its cheaper settings, then the shell's
// FD, closed-form and modal rungs on their grids.
std::vector<RungEntry> LadderRungs(const SonicBoomConfig& config, const LadderSettings& s,
                                   std::string* solves_md) {
  const double cut_band = std::min(10000.0, 2.0 / 3.0 * s.reference_band_hz);
  // the solid's modes are damped by the same Rayleigh curve as the shell's rungs
  acoustics::ShellConfig damping_grid = s.rayleigh_shell;
  damping_grid.grid_spacing_m = s.coarser.arc_m;
  damping_grid.axial_spacing_m = s.coarser.axial_m;
  auto damping =
      std::make_shared<const acoustics::ShellModel>(config.tube, s.rayleigh_material, damping_grid);
  const auto zeta = [damping](double w) { return damping->DampingRatio(w); };
  const double fs = s.fs;

  auto yard = BuildReference(config, s, s.reference_element_m, solves_md);
  auto cheap = BuildReference(config, s, 4.0 / 3.0 * s.reference_element_m, solves_md);
  auto solid_rung = [=](std::shared_ptr<const solid::ReferenceTube> tube, double band) {
    return [=] { return std::make_unique<SolidRung>(tube, band, fs, zeta); };
  };
  auto solid_grid = [](const solid::ReferenceTube& t) {
    return fmt::format("solid, h {:.1f} mm, p {}/{}", 1e3 * t.config().mesh.element_arc_m,
                       t.config().mesh.degree_wall, t.config().mesh.degree_thickness);
  };
  auto shell = [&](const acoustics::RungSpec& spec, const Grid& grid, bool own_contact = false) {
    return [&config, &s, spec, grid, own_contact]() -> std::unique_ptr<LadderRung> {
      return std::make_unique<ShellRung>(BuildShellRung(config, s, spec, grid), own_contact);
    };
  };
  // a grid's name, with its dispersion when that is not the thin plate's
  auto grid_name = [&s](const Grid& g) {
    const auto d = g.dispersion.value_or(s.rayleigh_shell.dispersion);
    return fmt::format("shell, {:.1f} x {:.1f} mm{}", 1e3 * g.arc_m, 1e3 * g.axial_m,
                       DispersionMark(d));
  };
  // the same grids with the other dispersion than the configured one
  const auto other = s.rayleigh_shell.dispersion == acoustics::Dispersion::kThin
                         ? acoustics::Dispersion::kThickPlate
                         : acoustics::Dispersion::kThin;
  Grid configured_other = s.configured, fine_other = s.fine, longer_other = s.longer;
  configured_other.dispersion = fine_other.dispersion = longer_other.dispersion = other;
  // the FD rung integrates K as assembled, whatever shell.dispersion says: named as thin
  Grid fd_longer = s.longer, fd_coarse = s.coarse, fd_coarser = s.coarser;
  fd_longer.dispersion = fd_coarse.dispersion = fd_coarser.dispersion =
      acoustics::Dispersion::kThin;
  const auto fd = acoustics::VibrationModel::kFd, modal = acoustics::VibrationModel::kModal;
  auto modal_spec = [&](double band, int64_t count, bool residual) {
    acoustics::RungSpec spec;
    spec.model = modal;
    spec.band_hz = band;
    spec.mode_count = count;
    spec.residual = residual;
    return spec;
  };
  acoustics::RungSpec fd_spec;
  fd_spec.model = fd;
  acoustics::RungSpec closed_spec;
  closed_spec.model = acoustics::VibrationModel::kModalClosedForm;
  const std::string cut = fmt::format("{:.0f} kHz", cut_band / 1000);
  std::vector<RungEntry> rungs{
      {"reference solid (the yardstick)", "solid", solid_grid(*yard),
       solid_rung(yard, s.reference_band_hz)},
      {"reference solid, coarser mesh", "solid", solid_grid(*cheap),
       solid_rung(cheap, s.reference_band_hz)},
      {"reference solid, " + cut, "solid", solid_grid(*yard), solid_rung(yard, cut_band)},
      {"FD", "fd", grid_name(fd_longer), shell(fd_spec, s.longer)},
      {"FD, contact on its own wall", "fd", grid_name(fd_longer), shell(fd_spec, s.longer, true)},
      {"FD", "fd", grid_name(fd_coarse), shell(fd_spec, s.coarse)},
      {"FD", "fd", grid_name(fd_coarser), shell(fd_spec, s.coarser)},
      {"closed form, derived band", "closed-form", "ideal simply supported tube (Flügge)",
       shell(closed_spec, s.configured)},
      {"modal, derived band (default)", "modal", grid_name(s.configured),
       shell(modal_spec(0, 0, true), s.configured)},
      {"modal, all modes", "modal", grid_name(s.configured),
       shell(modal_spec(s.full_band_hz, 0, true), s.configured)},
      {"modal, all modes, no residual", "modal", grid_name(s.configured),
       shell(modal_spec(s.full_band_hz, 0, false), s.configured)},
      {"modal, 10 kHz", "modal", grid_name(s.configured),
       shell(modal_spec(10000, 0, true), s.configured)},
      {"modal, 5 kHz", "modal", grid_name(s.configured),
       shell(modal_spec(5000, 0, true), s.configured)},
      {"modal, 2 kHz", "modal", grid_name(s.configured),
       shell(modal_spec(2000, 0, true), s.configured)},
      {"modal, 100 modes", "modal", grid_name(s.configured),
       shell(modal_spec(0, 100, true), s.configured)},
      {"modal, all modes", "modal", grid_name(s.fine),
       shell(modal_spec(s.full_band_hz, 0, true), s.fine)},
      {"modal, derived band", "modal", grid_name(configured_other),
       shell(modal_spec(0, 0, true), configured_other)},
      {"modal, derived band", "modal", grid_name(s.fine), shell(modal_spec(0, 0, true), s.fine)},
      {"modal, derived band", "modal", grid_name(fine_other),
       shell(modal_spec(0, 0, true), fine_other)},
      {"modal, all modes", "modal", grid_name(fine_other),
       shell(modal_spec(s.full_band_hz, 0, true), fine_other)},
      {"modal, derived band", "modal", grid_name(s.longer),
       shell(modal_spec(0, 0, true), s.longer)},
      {"modal, derived band", "modal", grid_name(longer_other),
       shell(modal_spec(0, 0, true), longer_other)},
      {"modal, derived band", "modal", grid_name(s.coarse),
       shell(modal_spec(0, 0, true), s.coarse)},
      {"modal, derived band", "modal", grid_name(s.coarser),
       shell(modal_spec(0, 0, true), s.coarser)}};
  // a scene that plays a fixed band, on the grid derived from it (shell.grid_spacing_m = 0)
  for (double band : kDerivedGridBandsHz) {
    const FixedBandScene scene = SceneOfBand(config, band);
    acoustics::RungSpec spec = modal_spec(band, 0, true);
    spec.mode_band_hz = scene.solved_band_hz;
    const double spacing_m = scene.config.shell.grid_spacing_m;
    const Grid grid{"derived", spacing_m, spacing_m};
    rungs.push_back({fmt::format("modal, {:.0f} kHz, derived grid", band / 1000), "modal",
                     grid_name(grid), shell(spec, grid)});
  }
  // a rung that coincides with another (--quick: coarse is coarser; a square configured grid is
  // the fine one) is measured once, under its first name
  const auto same = [](const RungEntry& a, const RungEntry& b) {
    return a.grid == b.grid &&
           WithoutSuffix(a.name, " (default)") == WithoutSuffix(b.name, " (default)");
  };
  for (size_t i = 1; i < rungs.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (same(rungs[j], rungs[i])) {
        rungs.erase(rungs.begin() + static_cast<std::ptrdiff_t>(i--));
        break;
      }
    }
  }
  return rungs;
}

// One rung's compared signals as DIR/NN.npy (strikes x mics x samples); its index.json entry.
json WriteSignals(const std::string& dir, size_t index, const RungEntry& rung,
                  const std::vector<Eigen::MatrixXd>& signals) {
  const Eigen::Index mics = signals.front().rows(), samples = signals.front().cols();
  std::vector<double> data;
  data.reserve(signals.size() * static_cast<size_t>(mics * samples));
  for (const Eigen::MatrixXd& y : signals) {
    for (Eigen::Index m = 0; m < mics; ++m)
      for (Eigen::Index t = 0; t < samples; ++t) data.push_back(y(m, t));
  }
  const std::string file = fmt::format("{:02d}.npy", index);
  hardware::WriteNpy(dir + "/" + file, {static_cast<int64_t>(signals.size()), mics, samples}, data);
  return {{"file", file}, {"rung", rung.name}, {"kind", rung.kind}, {"grid", rung.grid}};
}

// An FD rung's frequencies are its grid's: those of the modal rung with the most modes there.
void FrequenciesOfGrids(const std::vector<RungEntry>& rungs, std::vector<RungResult>* results) {
  // a grid's name without its dispersion: every modal rung of it solves the same K
  const std::string thick = DispersionMark(acoustics::Dispersion::kThickPlate);
  const auto grid_only = [&thick](const std::string& g) { return WithoutSuffix(g, thick); };
  for (size_t i = 0; i < rungs.size(); ++i) {
    if (rungs[i].kind != "fd") continue;
    int64_t most = -1;
    for (size_t j = 0; j < rungs.size(); ++j) {
      if (rungs[j].kind == "modal" && grid_only(rungs[j].grid) == grid_only(rungs[i].grid) &&
          (*results)[j].grid_frequency.modes > most) {
        most = (*results)[j].grid_frequency.modes;
        (*results)[i].frequency = (*results)[j].grid_frequency;
        (*results)[i].frequency_of_grid = true;
      }
    }
  }
}

// OUT's JSON beside it, and its Pareto figure drawn from that by the plot script.
void WriteFigure(const FidelityOptions& o, const json& j) {
  const std::filesystem::path out(o.out);
  const std::string json_path = std::filesystem::path(out).replace_extension(".json").string();
  const std::string png_path = (out.parent_path() / (out.stem().string() + "_pareto.png")).string();
  WriteTextAtomic(json_path, j.dump(2) + "\n");
  if (o.plot_script.empty()) return;
  DrawFigure(o.plot_script, "fidelity", json_path, png_path,
             "the table and the JSON are written; --plot \"\" skips the figure");
}

}  // namespace

CommandResult RunFidelity(const GlobalOptions& g, const FidelityOptions& o) {
  const SonicBoomConfig config = ResolveConfig(g.sources);
  const double fs = config.audio.sample_rate_hz;
  CheckFidelityOptions(o, fs);
  if (!o.out.empty()) RefuseWritingOverInputs(g, {o.out}, {{o.plot_script, "--plot"}});
  const double onset_s = 0.001;
  LadderStrikes ladder;
  ladder.one_second = static_cast<int64_t>(std::llround(fs));
  ladder.window = static_cast<int64_t>(std::llround((onset_s + o.window_s) * fs));
  // the early wavefront: the direct wave has passed every disc 2 ms after the onset (it reaches
  // the farthest within about 0.3 ms); shifts beyond 0.3 ms would align another packet
  ladder.wavefront = {.samples = std::min<int64_t>(
                          ladder.window, std::llround((onset_s + kWavefrontAfterOnsetS) * fs)),
                      .max_lag_s = kMaxWavefrontShiftS};
  const LadderSettings settings = SettingsOf(config, o);
  std::string solves_md;
  const std::vector<RungEntry> rungs = LadderRungs(config, settings, &solves_md);

  // the contact forces, solved once against the default rung's wall (the configured grid's
  // modes, the strike's derived band)
  acoustics::RungSpec default_rung;
  default_rung.model = acoustics::VibrationModel::kModal;
  const auto wall = BuildShellRung(config, settings, default_rung, settings.configured);
  for (int64_t s = 0; s < o.strikes; ++s) {
    acoustics::SolvedForce solved = acoustics::SolveRigidStrikeForce(
        StrikeEvent(kStrikes[s], onset_s), *wall, config.tube, config.material, config.acoustics,
        fs, settings.full_band_hz);
    ladder.derived_band_hz.push_back(solved.derived_band_hz);
    ladder.forces.push_back({std::move(solved.force)});
    ladder.impacts.push_back(acoustics::RigidStrikeImpact(StrikeEvent(kStrikes[s], onset_s),
                                                          config.tube, config.material));
  }

  Yardstick yardstick;
  yardstick.band_hz = settings.reference_band_hz;
  const double frequency_max_hz = std::min(10000.0, yardstick.band_hz);
  std::vector<RungResult> results;
  json signal_index = json::array();
  for (size_t i = 0; i < rungs.size(); ++i) {
    const RungEntry& rung = rungs[i];
    spdlog::info("fidelity: {} ({})", rung.name, rung.grid);
    std::vector<Eigen::MatrixXd> signals;  // [strike] (mics x window)
    results.push_back(
        MeasureRung(rung, *rung.build(), ladder, fs, frequency_max_hz, &yardstick, &signals));
    if (!o.signals_dir.empty()) {
      signal_index.push_back(WriteSignals(o.signals_dir, i, rung, signals));
    }
  }
  if (!o.signals_dir.empty()) {
    WriteTextAtomic(o.signals_dir + "/index.json", signal_index.dump(1) + "\n");
  }
  FrequenciesOfGrids(rungs, &results);
  const WholeStrikeSetup whole{&config, settings.configured.arc_m, settings.configured.axial_m,
                               o.quick, o.strikes};
  const WholeStrikeTime whole_time = WholeStrikeMs(whole);
  const double whole_ms = whole_time.ms, whole_vibration_ms = whole_time.vibration_ms;

  // the table
  std::string md = TableHead({.quick = o.quick,
                              .sample_rate_hz = fs,
                              .strikes = o.strikes,
                              .window_s = o.window_s,
                              .frequency_max_hz = frequency_max_hz,
                              .yardstick_band_hz = yardstick.band_hz,
                              .solves_md = solves_md});
  json rows_json = json::array();
  LadderRows(rungs, results, &md, &rows_json);
  md += Recommendations(rungs, results);
  md += fmt::format(
      "\nWhole default strike through `StrikeSynthesizer` (acoustics.model = {}, contact solve "
      "with the rod's bending modes, modal bank, DAQ and noise, {:.1f} s record; the median of 40 "
      "renders): {:.2f} ms per strike = {:.0f} strikes/s on one core, of which the vibration "
      "model {:.2f} ms.\n",
      NameOf(config.acoustics.model), config.audio.record_duration_s, whole_ms, 1e3 / whole_ms,
      whole_vibration_ms);
  const json span_json = RenderSpanSection(whole, &md);
  const json band_json = ModeBandSection(whole, &md);
  const json damping_json = DampingSection(config, &md);
  json j = {{"rungs", rows_json},
            {"strikes", o.strikes},
            {"window_s", o.window_s},
            {"yardstick_band_hz", yardstick.band_hz},
            {"frequency_max_hz", frequency_max_hz},
            {"damping", damping_json},
            {"whole_strike_ms", whole_ms},
            {"whole_strike_vibration_ms", whole_vibration_ms},
            {"render_span", span_json},
            {"mode_band", band_json},
            {"quick", o.quick}};
  if (!o.out.empty()) {
    WriteTextAtomic(o.out, md);
    WriteFigure(o, j);
  }
  return {j.dump(), md};
}

void RegisterFidelity(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<FidelityOptions>();
  auto* fidelity = app.add_subcommand("fidelity",
                                      "time and error of every vibration-model rung "
                                      "against the reference solid");
  fidelity->add_option("--out", o->out, "markdown table (\"\" = print only)");
  fidelity->add_option("--signals", o->signals_dir,
                       "also write every rung's compared signals here (NN.npy: strikes x mics x "
                       "samples; index.json names them)");
  fidelity->add_option("--strikes", o->strikes, "test strikes (1-6)");
  fidelity->add_option("--window-s", o->window_s, "compared signal after the onset, s");
  fidelity->add_option("--reference-band", o->reference_band_hz,
                       "the yardstick's modes up to here, Hz");
  fidelity->add_option("--reference-element", o->reference_element_m,
                       "the yardstick's element size, m");
  fidelity->add_option("--plot", o->plot_script,
                       "script drawing OUT's Pareto figure (\"\" = no figure)");
  fidelity->add_flag("--quick", o->quick, "coarse grids and reference only (a smoke run)");
  fidelity->callback([&g, run, o] { *run = [&g, o] { return RunFidelity(g, *o); }; });
}

}  // namespace sonicboom::experiments
