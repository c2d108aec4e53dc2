// `reference`: the independent solid reference model of the tube (solid/) at successively finer
// meshes: its modes and the first arrivals of a force pulse at the six discs, with a Richardson
// error estimate of the finest mesh (docs/reference_model.md).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/solid/convergence.h"
#include "sonicboom/solid/solid_tube.h"
#include "sonicboom/solid/theory.h"

#include "internal/reference.h"
#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;

// the study's own options, beyond the meshes of ReferenceLevelOptions
struct ReferenceOptions : ReferenceLevelOptions {
  std::string out;             // markdown report; "" = print only
  std::string cache_dir;       // solved levels kept here; "" = the mode cache directory
  bool compare_shell = false;  // the shell model's arrivals against the finest mesh's
};

// the probes' disc arrivals of the same pulse through the shell model's modes (acoustics/shell.h)
// on a grid of axial spacing axial_m: (probe) x (disc), s
std::vector<std::vector<double>> ShellArrivals(const SonicBoomConfig& config, TubeEnds ends,
                                               bool ideal, double axial_m, double max_frequency_hz,
                                               int64_t* modes_out) {
  acoustics::ShellConfig shell = config.shell;
  shell.ends = ends;
  shell.ideal = shell.ideal || ideal;
  shell.axial_spacing_m = axial_m;
  const acoustics::ShellModel model(config.tube, config.material, shell);
  const acoustics::ShellModes modes = acoustics::CachedShellModes(model, max_frequency_hz, 0, true,
                                                                  config.acoustics.ModeCacheDir());
  *modes_out = modes.omega_rad_s.size();
  const std::vector<solid::ConvergenceProbe> probes = solid::DefaultConvergenceProbes();
  Eigen::MatrixXd drive(probes.size(), model.dofs());  // (probes x dofs)
  for (size_t p = 0; p < probes.size(); ++p) {
    drive.row(p) = model.RadialForceWeights(probes[p].z_m, probes[p].theta_deg * kDeg).transpose();
  }
  return solid::ProbeArrivals(modes.omega_rad_s, model.SensorRows(config.mics) * modes.shapes,
                              drive * modes.shapes, config.material.loss_factor);
}

// the q-quantile (0 to 1) of v, by rank
double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}
// the median by rank (Quantile 0.5; not internal/statistics.h's Median, which a unity batch may
// hold too)
double RankMedian(const std::vector<double>& v) {
  return Quantile(v, 0.5);
}

// a mode's three finest frequencies (coarse to fine, Hz) and their Richardson extrapolation
struct ModeSeries {
  std::vector<double> f_hz;
  solid::Extrapolation e;
};

// Richardson error estimates of the finest mesh per frequency band of its modes: markdown table
// rows and their JSON
std::string BandRows(const std::vector<ModeSeries>& modes, json* bands_json) {
  const std::vector<double> edges{0.0, 5000.0, 10000.0, 20000.0, 40000.0};
  struct Band {
    std::vector<double> error, order;
    int non_monotone{0};
  };
  std::vector<Band> bands(edges.size() - 1);
  for (const ModeSeries& m : modes) {
    const size_t b =
        std::upper_bound(edges.begin(), edges.end(), m.f_hz.back()) - edges.begin() - 1;
    bands[b].error.push_back(m.e.error / m.e.limit);
    bands[b].order.push_back(m.e.order);
    if (m.e.order == 0.0) ++bands[b].non_monotone;
  }
  std::string md;
  *bands_json = json::array();
  for (size_t b = 0; b < bands.size(); ++b) {
    if (bands[b].error.empty()) continue;
    const double max_err = *std::max_element(bands[b].error.begin(), bands[b].error.end());
    const auto over = std::count_if(bands[b].error.begin(), bands[b].error.end(),
                                    [](double e) { return e > 0.003; });
    md += fmt::format("| {:.0f}-{:.0f} Hz | {} | {:.4f} | {:.4f} | {:.4f} | {} | {:.1f} | {} |\n",
                      edges[b], edges[b + 1], bands[b].error.size(),
                      100.0 * RankMedian(bands[b].error), 100.0 * Quantile(bands[b].error, 0.9),
                      100.0 * max_err, over, RankMedian(bands[b].order), bands[b].non_monotone);
    bands_json->push_back({{"lo_hz", edges[b]},
                           {"hi_hz", edges[b + 1]},
                           {"modes", bands[b].error.size()},
                           {"median_relative_error", RankMedian(bands[b].error)},
                           {"p90_relative_error", Quantile(bands[b].error, 0.9)},
                           {"max_relative_error", max_err},
                           {"over_0_3_percent", over},
                           {"median_order", RankMedian(bands[b].order)},
                           {"non_monotone", bands[b].non_monotone}});
  }
  return md;
}

// the finest mesh's modes followed to the two coarser meshes by shape: those whose two links
// both hold a modal assurance criterion of at least kFollowedMac, below 0.97 f_max
constexpr double kFollowedMac = 0.8;
std::vector<ModeSeries> FollowedByShape(const std::vector<solid::ConvergenceLevel>& levels,
                                        double max_frequency_hz) {
  const size_t n = levels.size();
  const solid::ConvergenceLevel &a = levels[n - 3], &b = levels[n - 2], &c = levels[n - 1];
  const auto bc = solid::MatchModesByShape(b.f_hz, b.signature, c.f_hz, c.signature, 0.05);
  const auto ab = solid::MatchModesByShape(a.f_hz, a.signature, b.f_hz, b.signature, 0.05);
  std::vector<double> h;
  for (const solid::ConvergenceLevel& l : levels) h.push_back(l.h_m);
  std::vector<ModeSeries> out;
  for (size_t k = 0; k < c.f_hz.size() && c.f_hz[k] < 0.97 * max_frequency_hz; ++k) {
    if (bc[k].from < 0 || bc[k].mac < kFollowedMac) continue;
    const solid::ModeMatch& up = ab[bc[k].from];
    if (up.from < 0 || up.mac < kFollowedMac) continue;
    std::vector<double> f(n, 0.0);  // Richardson reads the last three
    f[n - 3] = a.f_hz[up.from];
    f[n - 2] = b.f_hz[bc[k].from];
    f[n - 1] = c.f_hz[k];
    out.push_back({{f[n - 3], f[n - 2], f[n - 1]}, solid::Richardson(h, f)});
  }
  return out;
}

}  // namespace

solid::ReferenceTubeConfig ReferenceTubeOf(const SonicBoomConfig& config,
                                           const solid::SolidMeshConfig& mesh, double band_hz,
                                           bool ideal, const std::string& cache_dir) {
  solid::ReferenceTubeConfig rc;
  rc.tube = config.tube;
  rc.material = config.material;
  rc.structure = ReferenceStructure(config.shell, config.shell.ends, ideal);
  rc.mesh = mesh;
  rc.mics = config.mics;
  rc.max_frequency_hz = band_hz;
  rc.cache_dir = cache_dir;
  return rc;
}

CommandResult RunReference(const GlobalOptions& g, const ReferenceOptions& o) {
  const SonicBoomConfig config = Resolve(g);
  if (!o.out.empty()) {
    RefuseWritingOverInputs(g, {o.out}, {});
    const std::filesystem::path parent = std::filesystem::absolute(o.out).parent_path();
    if (!std::filesystem::is_directory(parent))
      throw IoError(fmt::format("--out {}: directory {} does not exist", o.out, parent.string()));
  }
  // each level solved (or read back from the cache, where an earlier run or apps/reference_levels
  // left it), coarse to fine
  const std::vector<solid::ConvergenceRequest> requests =
      ReferenceLevelRequests(o, config.tube, config.material, config.mics, config.shell,
                             o.cache_dir.empty() ? config.acoustics.ModeCacheDir() : o.cache_dir);
  std::vector<solid::ConvergenceLevel> levels;
  for (const solid::ConvergenceRequest& request : requests) {
    levels.push_back(solid::SolveConvergenceLevel(request));
    const solid::ConvergenceLevel& level = levels.back();
    spdlog::info("reference: h = {:.2f} mm, {} DOFs, {} modes to {} Hz; {} in {:.1f} s",
                 1e3 * level.h_m, level.dofs, level.f_hz.size(), o.max_frequency_hz,
                 level.from_cache ? "read from the cache, solved" : "solved",
                 level.build_s + level.solve_s);
  }
  const size_t probes = requests.front().probes.size();
  std::vector<double> h;
  for (const solid::ConvergenceLevel& l : levels) h.push_back(l.h_m);

  // frequencies: modes matched by order, up to the fewest any level found below 0.97 f_max
  size_t common = levels.front().f_hz.size();
  for (const solid::ConvergenceLevel& l : levels) {
    common = std::min<size_t>(
        common,
        std::lower_bound(l.f_hz.begin(), l.f_hz.end(), 0.97 * o.max_frequency_hz) - l.f_hz.begin());
  }
  std::vector<ModeSeries> by_rank;
  json modes_json = json::array();
  for (size_t i = 0; i < common; ++i) {
    std::vector<double> f;
    for (const solid::ConvergenceLevel& l : levels) f.push_back(l.f_hz[i]);
    const solid::Extrapolation e = solid::Richardson(h, f);
    by_rank.push_back({f, e});
    modes_json.push_back({{"f_hz", f},
                          {"limit_hz", e.limit},
                          {"order", e.order},
                          {"relative_error", e.error / e.limit}});
  }
  const std::vector<ModeSeries> by_shape = FollowedByShape(levels, o.max_frequency_hz);
  // arrivals and inter-disc delays per probe
  std::vector<double> arrival_err, delay_err;
  const int discs = config.mics.count();
  for (size_t p = 0; p < probes; ++p) {
    for (int a = 0; a < discs; ++a) {
      std::vector<double> t;
      for (const solid::ConvergenceLevel& l : levels) t.push_back(l.t_s[p][a]);
      arrival_err.push_back(solid::Richardson(h, t).error);
      for (int b = a + 1; b < discs; ++b) {
        std::vector<double> d;
        for (const solid::ConvergenceLevel& l : levels) d.push_back(l.t_s[p][a] - l.t_s[p][b]);
        delay_err.push_back(solid::Richardson(h, d).error);
      }
    }
  }

  // report
  std::string md = fmt::format(
      "Made by `sonicboom reference --boundary {} --max-frequency {} --element-m {} "
      "--degree-wall {} --degree-thickness {} {}{}{}` "
      "(experiments/reference_command.cc).\n\n",
      NameOf(o.ends), o.max_frequency_hz, o.element_m, o.degree_wall, o.degree_thickness,
      o.subdivisions.empty() ? fmt::format("--levels {} --ratio {}", o.levels, o.ratio)
                             : fmt::format("--subdivisions {} --fixed-interval-m {}",
                                           fmt::join(o.subdivisions, ","), o.fixed_interval_m),
      o.ideal ? " --ideal" : "", o.compare_shell ? " --compare-shell" : "");
  md +=
      "| mesh h (mm) | DOFs | modes to f_max | build (s) | modes and projections (s) | solved |\n";
  md += "|---|---|---|---|---|---|\n";
  json levels_json = json::array();
  for (const solid::ConvergenceLevel& l : levels) {
    md += fmt::format("| {:.2f} | {} | {} | {:.1f} | {:.1f} | {} |\n", 1e3 * l.h_m, l.dofs,
                      l.f_hz.size(), l.build_s, l.solve_s,
                      l.from_cache ? "earlier (read from --cache-dir)" : "now");
    levels_json.push_back({{"h_m", l.h_m},
                           {"dofs", l.dofs},
                           {"build_s", l.build_s},
                           {"solve_s", l.solve_s},
                           {"frequencies_hz", l.f_hz},
                           {"arrivals_s", l.t_s},
                           {"from_cache", l.from_cache}});
  }
  const std::string table_head =
      "| band | modes | median error (%) | 90th percentile (%) | max error (%) "
      "| modes over 0.3 % | median order | non-monotone |\n"
      "|---|---|---|---|---|---|---|---|\n";
  json bands_json, shape_bands_json;
  md +=
      fmt::format("\nRichardson error estimate of the finest mesh, {} modes matched by order:\n\n",
                  common) +
      table_head + BandRows(by_rank, &bands_json);
  const size_t finest_modes = std::lower_bound(levels.back().f_hz.begin(), levels.back().f_hz.end(),
                                               0.97 * o.max_frequency_hz) -
                              levels.back().f_hz.begin();
  md += fmt::format(
            "\nThe same, each mode of the finest mesh followed to the two coarser ones by its "
            "shape (the displacement at {} surface points; modal assurance criterion >= {} on "
            "both links, pairs within 5 % in frequency): {} of {} modes followed.\n\n",
            requests.front().signature_points, kFollowedMac, by_shape.size(), finest_modes) +
        table_head + BandRows(by_shape, &shape_bands_json);
  const double arrival_max = *std::max_element(arrival_err.begin(), arrival_err.end());
  const double delay_max = *std::max_element(delay_err.begin(), delay_err.end());
  // a 20 % threshold can jump to another wave packet between meshes: such jumps (over 50 us)
  // are counted apart from the converging arrivals
  auto jumps = [](const std::vector<double>& e) {
    return std::count_if(e.begin(), e.end(), [](double x) { return x > 50e-6; });
  };
  md += fmt::format(
      "\nFirst arrivals (20 % of each disc's peak strain; a 0.25 ms half-sine pulse at {} probe "
      "points, loss factor {}) at the {} discs, Richardson error of the finest mesh: arrivals "
      "median {:.2f} us, 90th percentile {:.2f} us, max {:.2f} us ({} of {} jump by over 50 us "
      "between meshes); inter-disc delays median {:.2f} us, 90th percentile {:.2f} us, max {:.2f} "
      "us ({} of {} jump).\n",
      probes, config.material.loss_factor, discs, 1e6 * RankMedian(arrival_err),
      1e6 * Quantile(arrival_err, 0.9), 1e6 * arrival_max, jumps(arrival_err), arrival_err.size(),
      1e6 * RankMedian(delay_err), 1e6 * Quantile(delay_err, 0.9), 1e6 * delay_max,
      jumps(delay_err), delay_err.size());
  // rungs against the finest mesh: arrival and inter-disc delay errors over the probes
  auto errors = [&](const std::vector<std::vector<double>>& t, std::vector<double>* arrival,
                    std::vector<double>* delay) {
    const auto& ref = levels.back().t_s;
    for (size_t p = 0; p < ref.size(); ++p) {
      for (int a = 0; a < discs; ++a) {
        arrival->push_back(std::abs(t[p][a] - ref[p][a]));
        for (int b = a + 1; b < discs; ++b) {
          delay->push_back(std::abs((t[p][a] - t[p][b]) - (ref[p][a] - ref[p][b])));
        }
      }
    }
  };
  md +=
      "\n| rung, against the finest mesh | modes | arrival error median / 90 % / max (us) | "
      "delay error median / 90 % / max (us) |\n|---|---|---|---|\n";
  json rungs_json = json::array();
  auto add_rung = [&](const std::string& name, int64_t modes,
                      const std::vector<std::vector<double>>& t) {
    std::vector<double> arrival, delay;
    errors(t, &arrival, &delay);
    md += fmt::format("| {} | {} | {:.1f} / {:.1f} / {:.1f} | {:.1f} / {:.1f} / {:.1f} |\n", name,
                      modes, 1e6 * RankMedian(arrival), 1e6 * Quantile(arrival, 0.9),
                      1e6 * Quantile(arrival, 1.0), 1e6 * RankMedian(delay),
                      1e6 * Quantile(delay, 0.9), 1e6 * Quantile(delay, 1.0));
    rungs_json.push_back({{"rung", name},
                          {"modes", modes},
                          {"arrival_error_s", {RankMedian(arrival), Quantile(arrival, 0.9)}},
                          {"delay_error_s", {RankMedian(delay), Quantile(delay, 0.9)}}});
  };
  for (size_t l = 0; l + 1 < levels.size(); ++l) {
    add_rung(fmt::format("reference, h = {:.1f} mm", 1e3 * levels[l].h_m),
             static_cast<int64_t>(levels[l].f_hz.size()), levels[l].t_s);
  }
  if (o.compare_shell) {
    // the default axial spacing and the arc spacing along the axis too (one rung when equal)
    std::vector<double> axials{config.shell.AxialSpacing()};
    if (config.shell.grid_spacing_m != axials[0]) axials.push_back(config.shell.grid_spacing_m);
    for (const double axial : axials) {
      int64_t modes = 0;
      const auto t = ShellArrivals(config, o.ends, o.ideal, axial, o.max_frequency_hz, &modes);
      add_rung(fmt::format("shell modal, {:.1f} x {:.1f} mm grid",
                           1e3 * config.shell.grid_spacing_m, 1e3 * axial),
               modes, t);
    }
  }
  if (!o.out.empty()) WriteTextAtomic(o.out, md);
  json j = {{"levels", levels_json},
            {"bands", bands_json},
            {"bands_by_shape", shape_bands_json},
            {"followed_by_shape", by_shape.size()},
            {"finest_modes", finest_modes},
            {"modes", modes_json},
            {"rungs", rungs_json},
            {"arrival_error_s", {{"median", RankMedian(arrival_err)}, {"max", arrival_max}}},
            {"delay_error_s", {{"median", RankMedian(delay_err)}, {"max", delay_max}}}};
  return {j.dump(), md};
}

void RegisterReference(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<ReferenceOptions>();
  auto* cmd = app.add_subcommand(
      "reference",
      "the independent 3-D solid model of the tube: convergence of modes and arrivals");
  AddEnumOption(cmd, "--boundary", &o->ends, "free | simply-supported");
  AddReferenceLevelOptions(cmd, o.get());
  cmd->add_option("--out", o->out, "markdown report (\"\" = print only)");
  cmd->add_option("--cache-dir", o->cache_dir,
                  "solved levels kept and reused here (default: the mode cache directory)");
  cmd->add_flag("--compare-shell", o->compare_shell,
                "also the shell model's arrivals (its grid, and the arc spacing along the axis "
                "where that differs) against the finest mesh");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunReference(g, *o); }; });
}

}  // namespace sonicboom::experiments
