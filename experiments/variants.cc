// `sonicboom variants`: the structure pool's cheap path measured. Each variant's modes come from a
// Ritz projection onto the base modes (acoustics/shell_ritz.h); here the first few are also solved
// in full, and the two are compared in frequency, shape and rendered signal, with the time of each.
#include <CLI/CLI.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/subcommands.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/shell_ritz.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"

#include "internal/report.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// median and largest |f_ritz / f_exact - 1| over the exact modes below f_hz, matched in order
std::pair<double, double> FrequencyError(const acoustics::ShellModes& ritz,
                                         const acoustics::ShellModes& exact, double f_hz) {
  std::vector<double> err;
  const Eigen::Index n = std::min(ritz.omega_rad_s.size(), exact.omega_rad_s.size());
  for (Eigen::Index k = 0; k < n && exact.omega_rad_s[k] <= 2 * kPi * f_hz; ++k) {
    err.push_back(std::abs(ritz.omega_rad_s[k] / exact.omega_rad_s[k] - 1.0));
  }
  if (err.empty()) return {0.0, 0.0};
  std::sort(err.begin(), err.end());
  return {err[err.size() / 2], err.back()};
}

// smallest fraction of an exact mode below f_hz (mass-weighted) that the Ritz modes capture
double WorstCapture(const acoustics::ShellModes& ritz, const acoustics::ShellModes& exact,
                    const Eigen::VectorXd& mass, double f_hz) {
  Eigen::Index n = 0;
  while (n < exact.omega_rad_s.size() && exact.omega_rad_s[n] <= 2 * kPi * f_hz) ++n;
  const Eigen::MatrixXd overlap =
      exact.shapes.leftCols(n).transpose() * mass.asDiagonal() * ritz.shapes;  // (n x ritz)
  return n == 0 ? 1.0 : overlap.rowwise().squaredNorm().minCoeff();
}

// a Hertz-like pulse of duration t_c (s) from sample 20, N per audio sample
std::vector<double> Pulse(double fs, double t_c) {
  std::vector<double> f(static_cast<size_t>(std::ceil(t_c * fs)) + 22, 0.0);
  for (size_t s = 0; s < f.size(); ++s) {
    const double t = (static_cast<double>(s) - 20.0) / fs;
    if (t > 0.0 && t < t_c) f[s] = 50.0 * std::pow(std::sin(kPi * t / t_c), 1.5);
  }
  return f;
}

}  // namespace

CommandResult RunVariants(const GlobalOptions& g, int64_t check, const std::string& out_md) {
  if (!out_md.empty()) RefuseWritingOverInputs(g, {out_md}, {});
  const SonicBoomConfig config = ResolveConfig(g.sources);
  const acoustics::RandomizeConfig& r = config.randomize;
  if (!r.structure()) {
    throw ConfigError(
        "sonicboom variants measures the structure pool: set "
        "randomize.structure_variants > 0 (configs/randomized.yaml does)");
  }
  if (check < 0 || check > r.structure_variants) {
    throw ConfigError(
        fmt::format("--check must be in [0, randomize.structure_variants = {}], got {}",
                    r.structure_variants, check));
  }
  const double fs = config.audio.sample_rate_hz;
  const double band = config.acoustics.ModeBandHz(fs);
  const std::string cache = config.acoustics.ModeCacheDir();
  const acoustics::ShellModel base(config.tube, config.material, config.shell);
  const acoustics::ShellModes base_modes = acoustics::CachedShellModes(base, band, 0, true, cache);
  auto t = Clock::now();
  const acoustics::ShellRitzProjector projector(base, base_modes);
  const double projector_s = Seconds(t);

  // the test forces: a sharp and a dull strike at two points, 30 ms of signal
  const int64_t samples = static_cast<int64_t>(0.03 * fs);
  std::vector<acoustics::ForceInput> forces;
  for (const auto& [z, theta, t_c] :
       {std::tuple{0.04, 0.3, 0.2e-3}, std::tuple{-0.07, 2.4, 1.0e-3}}) {
    forces.push_back({z, theta, 0, Pulse(fs, t_c)});
  }
  auto render = [&](const acoustics::ShellModel& model, const acoustics::ShellModes& modes) {
    const acoustics::ShellModalBank bank(
        model, modes, config.mics, fs, config.acoustics.decay_floor_db, config.acoustics.residual);
    std::vector<Eigen::MatrixXd> out;
    for (const auto& f : forces) out.push_back(bank.Render({&f, 1}, bank.modes(), samples));
    return out;
  };

  std::string md = fmt::format(
      "Structure pool: {} variants, modes to {:.0f} Hz, {} base modes, grid {} x {} mm; Ritz "
      "projector built in {:.2f} s.\n\n"
      "| variant | bolts | bolt scale | flange | tool | nu | Ritz (s) | full (s) | f err < 5 kHz "
      "(median / max) | f err < 20 kHz (median / max) | worst capture < 10 kHz | signal error |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n",
      r.structure_variants, band, base_modes.omega_rad_s.size(), config.shell.grid_spacing_m * 1e3,
      config.shell.AxialSpacing() * 1e3, projector_s);
  json rows = json::array();
  double ritz_total_s = 0.0;
  for (int64_t v = 0; v < r.structure_variants; ++v) {
    const acoustics::StructureVariant draw = acoustics::DrawStructure(
        r, {config.tube, config.shell, config.mics, config.material.poisson_ratio}, config.seed, v);
    MaterialConfig material = config.material;
    material.poisson_ratio = draw.poisson_ratio;
    const acoustics::ShellModel varied(config.tube, material, draw.shell);
    t = Clock::now();
    const acoustics::ShellModes ritz = projector.Project(varied, band);
    const double ritz_s = Seconds(t);
    ritz_total_s += ritz_s;
    if (v >= check) continue;
    spdlog::info("variants: full solve of variant {}", v);
    t = Clock::now();
    const acoustics::ShellModes exact = acoustics::SolveShellModes(varied, band, 0, true);
    const double full_s = Seconds(t);
    const auto [f5_med, f5_max] = FrequencyError(ritz, exact, 5000.0);
    const auto [f20_med, f20_max] = FrequencyError(ritz, exact, band);
    const double capture = WorstCapture(ritz, exact, varied.mass_kg(), 10000.0);
    const std::vector<Eigen::MatrixXd> a = render(varied, ritz), b = render(varied, exact);
    double signal = 0.0;
    for (size_t k = 0; k < a.size(); ++k)
      signal = std::max(signal, (a[k] - b[k]).norm() / b[k].norm());
    double log_scale = 0.0;
    for (double s : draw.shell.bolt_stiffness_scale) log_scale += std::log(s);
    const double bolt_scale =
        draw.shell.bolt_z_m.empty()
            ? 1.0
            : std::exp(log_scale / static_cast<double>(draw.shell.bolt_z_m.size()));
    const double flange =
        draw.shell.flange_mount_stiffness_n_m2 / config.shell.flange_mount_stiffness_n_m2;
    const double tool =
        draw.shell.tool_mount_stiffness_n_m2 / config.shell.tool_mount_stiffness_n_m2;
    md += fmt::format(
        "| {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.3f} | {:.2f} | {:.1f} | {:.2e} / {:.2e} | "
        "{:.2e} / {:.2e} | {:.4f} | {:.4f} |\n",
        v, draw.shell.bolt_z_m.size(), bolt_scale, flange, tool, draw.poisson_ratio, ritz_s, full_s,
        f5_med, f5_max, f20_med, f20_max, capture, signal);
    rows.push_back({{"variant", v},
                    {"bolts", draw.shell.bolt_z_m.size()},
                    {"bolt_stiffness_scale", bolt_scale},
                    {"flange_mount_scale", flange},
                    {"tool_mount_scale", tool},
                    {"poisson_ratio", draw.poisson_ratio},
                    {"ritz_s", ritz_s},
                    {"full_s", full_s},
                    {"freq_err_5k_median", f5_med},
                    {"freq_err_5k_max", f5_max},
                    {"freq_err_band_median", f20_med},
                    {"freq_err_band_max", f20_max},
                    {"worst_capture_10k", capture},
                    {"signal_error", signal}});
  }
  md += fmt::format(
      "\nRitz projection: {:.2f} s per variant on average ({} variants, one thread each); the "
      "signal error is the larger relative error of the six channels over 30 ms for a 0.2 ms and "
      "a 1 ms pulse.\n",
      ritz_total_s / static_cast<double>(r.structure_variants), r.structure_variants);
  json j = {{"variants", r.structure_variants},
            {"band_hz", band},
            {"base_modes", base_modes.omega_rad_s.size()},
            {"projector_s", projector_s},
            {"ritz_s_mean", ritz_total_s / static_cast<double>(r.structure_variants)},
            {"checked", rows}};
  if (!out_md.empty()) WriteTextAtomic(out_md, md);
  return {j.dump(), md};
}

void RegisterVariants(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    int64_t check = 3;
    std::string out;
  };
  auto o = std::make_shared<Options>();
  auto* variants = app.add_subcommand("variants",
                                      "the structure pool's Ritz modes against full "
                                      "solves: error and time");
  variants->add_option("--check", o->check, "variants also solved in full (default 3)");
  variants->add_option("--out", o->out, "markdown table (default: print only)");
  variants->callback([&g, run, o] { *run = [&g, o] { return RunVariants(g, o->check, o->out); }; });
}

}  // namespace sonicboom::experiments
