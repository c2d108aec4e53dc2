// The fidelity ladder measured: every rung of the vibration model renders the same strikes (the
// same contact forces), and is timed and compared against the finest FD reference.
#include <CLI/CLI.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/subcommands.h"
#include "sonicboom/acoustics/ladder.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/sim/scene.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
constexpr double kPi = std::numbers::pi;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// a test strike: a wooden rod crossing the tube (rigid striker) at (z, theta)
struct TestStrike {
  double z_m, theta_rad, speed_m_s, mass_kg;
};
constexpr TestStrike kStrikes[] = {{0.05, 0.3, 0.1, 0.03},  {-0.08, 2.0, 0.3, 0.03},
                                   {0.0, -1.2, 1.0, 0.03},  {0.09, 3.0, 0.05, 0.1},
                                   {-0.1, -2.8, 0.5, 0.02}, {0.03, 1.4, 0.2, 0.05}};

ContactEvent StrikeEvent(const TestStrike& s, double time_s) {
  ContactEvent c;
  c.time_s = time_s;
  c.z_m = s.z_m;
  c.theta_rad = s.theta_rad;
  c.normal_speed_m_s = s.speed_m_s;
  c.effective_mass_kg = s.mass_kg;
  c.striker_radius_m = 0.011;
  c.striker_youngs_modulus_pa = 1e9;
  c.striker_poisson_ratio = 0.35;
  return c;
}

// relative L2 error over all channels
double RelativeError(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref) {
  return (y - ref).norm() / ref.norm();
}

// arrival of each channel: first crossing of 20 % of its peak |y|, linear between samples
Eigen::VectorXd Arrivals(const Eigen::MatrixXd& y) {
  Eigen::VectorXd t(y.rows());
  for (Eigen::Index i = 0; i < y.rows(); ++i) {
    const double thr = 0.2 * y.row(i).cwiseAbs().maxCoeff();
    t[i] = 0;
    for (Eigen::Index k = 1; k < y.cols(); ++k) {
      const double a = std::abs(y(i, k - 1)), b = std::abs(y(i, k));
      if (b >= thr) {
        t[i] = (k - 1) + (b > a ? (thr - a) / (b - a) : 1.0);
        break;
      }
    }
  }
  return t;
}

// mean over the channel pairs of the inter-channel delay error, microseconds
double DelayErrorUs(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref, double fs) {
  const Eigen::VectorXd a = Arrivals(y), b = Arrivals(ref);
  double sum = 0;
  int pairs = 0;
  for (Eigen::Index i = 0; i < y.rows(); ++i) {
    for (Eigen::Index j = i + 1; j < y.rows(); ++j) {
      sum += std::abs((a[j] - a[i]) - (b[j] - b[i]));
      ++pairs;
    }
  }
  return sum / pairs / fs * 1e6;
}

// octave-band energies (centres 250 Hz .. 16 kHz) summed over channels, by a direct DFT
Eigen::VectorXd OctaveEnergies(const Eigen::MatrixXd& y, double fs) {
  const std::vector<double> centres{250, 500, 1000, 2000, 4000, 8000, 16000};
  Eigen::VectorXd e = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(centres.size()));
  const Eigen::Index n = y.cols();
  for (Eigen::Index bin = 1; bin < n / 2; ++bin) {
    const double f = bin * fs / n;
    int band = -1;
    for (size_t b = 0; b < centres.size(); ++b) {
      if (f >= centres[b] / std::sqrt(2.0) && f < centres[b] * std::sqrt(2.0))
        band = static_cast<int>(b);
    }
    if (band < 0) continue;
    // one bin of every channel: rotate a unit phasor through the record
    const std::complex<double> step = std::polar(1.0, -2 * kPi * bin / n);
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      std::complex<double> acc = 0, w = 1;
      for (Eigen::Index k = 0; k < n; ++k) {
        acc += y(i, k) * w;
        w *= step;
      }
      e[band] += std::norm(acc);
    }
  }
  return e;
}

// mean |dB| difference over the bands that hold energy in the reference
double BandEnergyErrorDb(const Eigen::VectorXd& e, const Eigen::VectorXd& ref) {
  const double floor = 1e-6 * ref.maxCoeff();
  double sum = 0;
  int bands = 0;
  for (Eigen::Index b = 0; b < ref.size(); ++b) {
    if (ref[b] <= floor) continue;
    sum += std::abs(10 * std::log10(std::max(e[b], 1e-300) / ref[b]));
    ++bands;
  }
  return bands > 0 ? sum / bands : 0.0;
}

// one grid of the shell and what was built on it
struct Grid {
  std::string name;
  double arc_m, axial_m;
};

struct Rung {
  std::string name;
  acoustics::VibrationModel kind;  // modal or fd
  Grid grid;
  double band_hz{0};      // modal: fixed band; 0 = derived from the contact
  int64_t mode_count{0};  // modal: fixed count
  bool residual{true};
  int64_t oversampling_factor{1};  // fd: multiple of the smallest stable oversampling
};

struct RungResult {
  double ms_per_strike{0}, rel_error{0}, delay_error_us{0}, band_error_db{0};
  double modes{0}, dofs{0}, oversampling{0};
};

// the strikes every rung renders: their contact forces (solved once against the configured
// grid's modal wall) and derived bands
struct LadderStrikes {
  std::vector<std::vector<acoustics::ForceInput>> forces;  // [strike][contact]
  std::vector<double> derived_band_hz;                     // [strike]
  int64_t window{0};      // samples compared after the start of the record
  int64_t one_second{0};  // samples
};

// The reference's strain of each strike (the first rung's) and its octave-band energies.
struct Reference {
  std::vector<Eigen::MatrixXd> signal;  // [strike] 6 x window
  std::vector<Eigen::VectorXd> bands;   // [strike] octave energies
};

// Times one rung on every strike and measures its error against the reference (which this rung
// becomes when `reference` is still empty).
RungResult MeasureRung(const Rung& rung, const acoustics::VibrationRung& built,
                       const LadderStrikes& strikes, double fs, Reference* reference) {
  RungResult r;
  r.dofs = static_cast<double>(built.dofs());
  r.oversampling = static_cast<double>(built.oversampling());
  const size_t n = strikes.forces.size();
  const bool is_reference = reference->signal.empty();
  for (size_t s = 0; s < n; ++s) {
    const auto& f = strikes.forces[s];
    const double band = strikes.derived_band_hz[s];
    const auto start = Clock::now();
    const Eigen::MatrixXd y = built.Render(f, strikes.window, band);
    double seconds = 0;
    if (built.fd()) {
      // FD cost is the same for every sample: time the window, scale to one second
      seconds = Seconds(start) * static_cast<double>(strikes.one_second) /
                static_cast<double>(strikes.window);
    } else {
      r.modes += static_cast<double>(built.ModesPlayed(band)) / n;
      // a whole second, best of three
      seconds = 1e30;
      for (int rep = 0; rep < 3; ++rep) {
        const auto t0 = Clock::now();
        const Eigen::MatrixXd full = built.Render(f, strikes.one_second, band);
        seconds = std::min(seconds, Seconds(t0));
        if (full.hasNaN()) throw NumericalError("fidelity: NaN in a modal render");
      }
    }
    if (!y.allFinite())
      throw NumericalError(fmt::format("fidelity: {} produced a non-finite signal", rung.name));
    r.ms_per_strike += 1e3 * seconds / n;
    if (is_reference) {
      reference->signal.push_back(y);
      reference->bands.push_back(OctaveEnergies(y, fs));
    }
    r.rel_error += RelativeError(y, reference->signal[s]) / n;
    r.delay_error_us += DelayErrorUs(y, reference->signal[s], fs) / n;
    r.band_error_db += BandEnergyErrorDb(OctaveEnergies(y, fs), reference->bands[s]) / n;
  }
  return r;
}

// The whole default strike (contact solve, modes, DAQ) through the production renderer, 40
// times: {ms per strike, ms of it in the vibration model}.
std::pair<double, double> WholeStrikeMs(const SonicBoomConfig& config, const Grid& configured,
                                        bool quick, int64_t strikes) {
  acoustics::AcousticModelConfig whole = AcousticModel(config);
  if (quick) {
    whole.shell.grid_spacing_m = configured.arc_m;
    whole.shell.axial_spacing_m = configured.axial_m;
  }
  const acoustics::StrikeSynthesizer synth(whole);
  const int64_t reps = 40;
  const auto t0 = Clock::now();
  double vibration_s = 0;
  for (int64_t i = 0; i < reps; ++i) {
    const TestStrike& ts = kStrikes[i % strikes];
    ContactEvent ev = StrikeEvent(ts, config.audio.onset_time_s);
    sim::ObjectConfig rod;  // the default struck rod: its bending modes take part
    sim::DescribeStruckBeam(rod, rod.length_m - 0.05, &ev);
    const acoustics::RenderedStrike rs = synth.Render(ev, {}, 0.0, static_cast<uint64_t>(i));
    vibration_s += rs.vibration_s;
  }
  return {1e3 * Seconds(t0) / reps, 1e3 * vibration_s / reps};
}

// The table's rows (markdown and JSON).
void LadderRows(const std::vector<Rung>& rungs, const std::vector<RungResult>& results,
                std::string* md, json* rows_json) {
  for (size_t i = 0; i < rungs.size(); ++i) {
    const Rung& rung = rungs[i];
    const RungResult& r = results[i];
    const std::string size = rung.kind == acoustics::VibrationModel::kFd
                                 ? fmt::format("{:.0f}x", r.oversampling)
                                 : fmt::format("{:.0f}", r.modes);
    *md += fmt::format("| {} | {:.1f} x {:.1f} | {:.0f} | {} | {:.3g} | {:.3g} | {} | {} | {} |\n",
                       rung.name, rung.grid.arc_m * 1e3, rung.grid.axial_m * 1e3, r.dofs, size,
                       r.ms_per_strike, 1e3 / r.ms_per_strike,
                       i == 0 ? "—" : fmt::format("{:.3f}", r.rel_error),
                       i == 0 ? "—" : fmt::format("{:.1f}", r.delay_error_us),
                       i == 0 ? "—" : fmt::format("{:.2f}", r.band_error_db));
    rows_json->push_back({{"rung", rung.name},
                          {"kind", NameOf(rung.kind)},
                          {"grid_arc_m", rung.grid.arc_m},
                          {"grid_axial_m", rung.grid.axial_m},
                          {"dofs", r.dofs},
                          {"modes", r.modes},
                          {"oversampling", r.oversampling},
                          {"ms_per_strike", r.ms_per_strike},
                          {"relative_error", r.rel_error},
                          {"delay_error_us", r.delay_error_us},
                          {"band_energy_error_db", r.band_error_db}});
  }
}

// The FD rung's damping against the loss law (shell.damping = law): the Rayleigh curve meets the
// law at shell.loss_low_hz and loss_high_hz and departs from it elsewhere. Appends the section
// to `md`; returns its rows (empty for Rayleigh damping).
json DampingSection(const SonicBoomConfig& config, std::string* md) {
  json damping_json = json::array();
  if (config.shell.damping != acoustics::DampingModel::kLaw) return damping_json;
  const acoustics::ShellModel law(config.tube, config.material, config.shell);
  *md +=
      "\nDamping: the modal rung gives every mode the loss law's eta(f); the FD rung's Rayleigh "
      "curve (C = alpha M + beta K) meets it at shell.loss_low_hz and shell.loss_high_hz:\n\n"
      "| f (Hz) | law eta | FD (Rayleigh) eta | ratio |\n|---|---|---|---|\n";
  for (double f : {100.0, 220.0, 500.0, 1000.0, 2000.0, 5000.0, 10000.0, 20000.0}) {
    const double w = 2.0 * std::numbers::pi * f;
    const double eta_law = 2.0 * law.DampingRatio(w), eta_fd = 2.0 * law.RayleighDampingRatio(w);
    *md += fmt::format("| {:.0f} | {:.4f} | {:.4f} | {:.2f} |\n", f, eta_law, eta_fd,
                       eta_fd / eta_law);
    damping_json.push_back({{"frequency_hz", f}, {"law_eta", eta_law}, {"fd_eta", eta_fd}});
  }
  return damping_json;
}

// --strikes, --window-s and --out's directory, before any work.
void CheckFidelityOptions(const std::string& out_md, int64_t strikes, double window_s) {
  if (strikes < 1 || strikes > static_cast<int64_t>(std::size(kStrikes))) {
    throw ConfigError(
        fmt::format("--strikes must be in [1, {}], got {}", std::size(kStrikes), strikes));
  }
  if (!(window_s >= 0.005 && window_s <= 1.0)) {
    throw ConfigError(fmt::format("--window-s must be in [0.005, 1], got {}", window_s));
  }
  if (!out_md.empty()) {
    const std::filesystem::path parent = std::filesystem::path(out_md).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent)) {
      throw IoError(fmt::format("--out {}: directory {} does not exist", out_md, parent.string()));
    }
  }
}

}  // namespace

CommandResult RunFidelity(const GlobalOptions& g, const std::string& out_md, int64_t strikes,
                          double window_s, bool quick) {
  const SonicBoomConfig config = ResolveConfig(g.sources);
  CheckFidelityOptions(out_md, strikes, window_s);
  const double fs = config.audio.sample_rate_hz;
  const double onset_s = 0.001;
  LadderStrikes ladder;
  ladder.one_second = static_cast<int64_t>(std::llround(fs));
  ladder.window = static_cast<int64_t>(std::llround((onset_s + window_s) * fs));
  const std::string cache = config.acoustics.mode_cache_dir.empty()
                                ? acoustics::DefaultModeCacheDir()
                                : config.acoustics.mode_cache_dir;

  // grids: the configured one (the production rung's), coarser ones, and the reference
  const double arc = config.shell.grid_spacing_m, axial = config.shell.AxialSpacing();
  const double finest = quick ? 0.005 : std::min(arc, axial);
  const Grid reference{"reference", finest, finest};
  const Grid configured{"configured", quick ? 0.005 : arc, quick ? 0.01 : axial};
  const Grid coarse{"coarse", 2 * configured.arc_m, 2 * configured.axial_m};
  const Grid coarser{"coarser", 0.01, 0.02};
  // every rung, modal and FD, damps by the FD rung's Rayleigh curve, so that the table measures
  // discretization and truncation alone; the law's own fit error is the section below the table
  MaterialConfig rayleigh_material = config.material;
  acoustics::ShellConfig rayleigh_shell = config.shell;
  acoustics::UseFdDamping(config.tube, &rayleigh_material, &rayleigh_shell);
  // the modes every modal rung draws from: the production default (20 kHz below Nyquist)
  const double full_band = config.acoustics.mode_band_hz > 0 ? config.acoustics.mode_band_hz
                                                             : std::min(20000.0, 0.95 * 0.5 * fs);
  auto build = [&](const Rung& rung) {
    acoustics::RungSpec spec;
    spec.model = rung.kind;
    spec.arc_m = rung.grid.arc_m;
    spec.axial_m = rung.grid.axial_m;
    spec.band_hz = rung.band_hz;
    spec.mode_count = rung.mode_count;
    spec.residual = rung.residual;
    spec.oversampling_factor = rung.oversampling_factor;
    return std::make_unique<acoustics::VibrationRung>(
        config.tube, rayleigh_material, rayleigh_shell, config.mics, fs, spec, full_band,
        config.acoustics.decay_floor_db, cache);
  };

  // the contact forces, solved once against the configured grid's modal wall
  spdlog::info("fidelity: modes of the configured grid ({} x {} mm)", configured.arc_m * 1e3,
               configured.axial_m * 1e3);
  const auto wall = build({"wall", acoustics::VibrationModel::kModal, configured, 0, 0, true, 1});
  for (int64_t s = 0; s < strikes; ++s) {
    acoustics::SolvedForce solved =
        acoustics::SolveRigidStrikeForce(StrikeEvent(kStrikes[s], onset_s), *wall, config.tube,
                                         config.material, config.acoustics, fs, full_band);
    ladder.derived_band_hz.push_back(solved.derived_band_hz);
    ladder.forces.push_back({std::move(solved.force)});
  }

  // the rungs, the reference first
  const auto fd = acoustics::VibrationModel::kFd, modal = acoustics::VibrationModel::kModal;
  const std::vector<Rung> rungs{
      {"FD reference (2x stable oversampling)", fd, reference, 0, 0, true, 2},
      {"FD", fd, configured, 0, 0, true, 1},
      {"FD", fd, coarse, 0, 0, true, 1},
      {"FD", fd, coarser, 0, 0, true, 1},
      {"modal, derived band (default)", modal, configured, 0, 0, true, 1},
      {"modal, all modes", modal, configured, full_band, 0, true, 1},
      {"modal, all modes, no residual", modal, configured, full_band, 0, false, 1},
      {"modal, 10 kHz", modal, configured, 10000, 0, true, 1},
      {"modal, 5 kHz", modal, configured, 5000, 0, true, 1},
      {"modal, 2 kHz", modal, configured, 2000, 0, true, 1},
      {"modal, 100 modes", modal, configured, 0, 100, true, 1},
      {"modal, derived band", modal, coarse, 0, 0, true, 1},
      {"modal, derived band", modal, coarser, 0, 0, true, 1}};
  Reference ref;
  std::vector<RungResult> results;
  for (const Rung& rung : rungs) {
    spdlog::info("fidelity: {} on the {} grid", rung.name, rung.grid.name);
    results.push_back(MeasureRung(rung, *build(rung), ladder, fs, &ref));
  }
  const auto [whole_ms, whole_vibration_ms] = WholeStrikeMs(config, configured, quick, strikes);

  // the table
  std::string md = fmt::format(
      "# Fidelity ladder: speed against accuracy\n\n"
      "Made by `sonicboom fidelity --out docs/fidelity.md{}` (experiments/fidelity.cc); do not "
      "edit "
      "by hand. One core, {}.\n\n"
      "Every rung renders the same {} strikes (wooden rod, 0.05–1 m/s, contact forces solved once "
      "against the configured grid's modal wall). Time: the vibration model for 1 s of 6 channels "
      "(FD: timed on the {:.0f} ms window and scaled; its cost per sample is constant). Errors: "
      "sensor strain over the first {:.0f} ms after the onset against the reference, averaged "
      "over the strikes: relative L2 error over all channels; inter-channel delay error (20 % "
      "threshold arrival, mean over the 15 pairs); octave-band energy error (250 Hz–16 kHz, mean "
      "|dB|).\n\n"
      "| rung | grid (arc x axial mm) | DOFs | modes / oversampling | ms per strike | strikes/s | "
      "relative error | delay error (µs) | band-energy error (dB) |\n"
      "|---|---|---|---|---|---|---|---|---|\n",
      quick ? " --quick" : "", fmt::format("{} Hz", fs), strikes, window_s * 1e3, window_s * 1e3);
  json rows_json = json::array();
  LadderRows(rungs, results, &md, &rows_json);
  md += fmt::format(
      "\nWhole default strike through `StrikeSynthesizer` (acoustics.model = {}, contact solve "
      "with "
      "the rod's bending modes, modal bank, DAQ and noise, 1 s record): {:.2f} ms per strike = "
      "{:.0f} strikes/s on one core, of which the vibration model {:.2f} ms.\n",
      NameOf(config.acoustics.model), whole_ms, 1e3 / whole_ms, whole_vibration_ms);
  const json damping_json = DampingSection(config, &md);
  json j = {{"rungs", rows_json},
            {"strikes", strikes},
            {"window_s", window_s},
            {"damping", damping_json},
            {"whole_strike_ms", whole_ms},
            {"whole_strike_vibration_ms", whole_vibration_ms},
            {"quick", quick}};
  if (!out_md.empty()) WriteTextAtomic(out_md, md);
  return {j.dump(), md};
}

void RegisterFidelity(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string out = "docs/fidelity.md";
    int64_t strikes = 4;
    double window_s = 0.03;
    bool quick = false;
  };
  auto o = std::make_shared<Options>();
  auto* fidelity = app.add_subcommand("fidelity",
                                      "time and error of every vibration-model rung "
                                      "against the finest FD reference");
  fidelity->add_option("--out", o->out, "markdown table (\"\" = print only)");
  fidelity->add_option("--strikes", o->strikes, "test strikes (1-6)");
  fidelity->add_option("--window-s", o->window_s, "compared signal after the onset, s");
  fidelity->add_flag("--quick", o->quick, "coarse grids only (a smoke run)");
  fidelity->callback([&g, run, o] {
    *run = [&g, o] { return RunFidelity(g, o->out, o->strikes, o->window_s, o->quick); };
  });
}

}  // namespace sonicboom::experiments
