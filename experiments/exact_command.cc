// `exact`: the ladder's models of the ideal simply supported tube against exact 3-D elasticity
// (solid/ss_exact.h): the reference solid, the shell's grids (thin and thick-plate; the FD rung
// integrates the thin grid's K) and Flügge's closed form, each mode matched by (m, n, branch)
// and by rank (docs/reference_model.md, "Against exact 3-D elasticity").
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/fidelity_strikes.h"
#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/acoustics/dispersion.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/solid/exact_match.h"
#include "sonicboom/solid/solid_modes.h"
#include "sonicboom/solid/solid_tube.h"
#include "sonicboom/solid/ss_exact.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct ExactOptions {
  double max_frequency_hz{20000.0};
  int radial_degree{12};
  std::vector<double> solid_element_m{0.0135, 0.018};
  bool shell{true};
  std::string out;  // Markdown table ("" = none)
};

// the models' modes are solved this far past the band, so that a family's modes that the model
// puts above the band are still there to match
constexpr double kSolveMargin = 1.15;

double SecondsSince(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// one model of the table and its modes, each labelled (m, n)
struct ExactRow {
  std::string rung, grid;
  double band_hz{0.0};  // what the rung is compared up to
  int64_t dofs{0};
  double seconds{0.0};
  std::vector<solid::LabelledMode> labelled;
  std::vector<double> FrequenciesHz() const {
    std::vector<double> f;
    for (const solid::LabelledMode& m : labelled) f.push_back(m.frequency_hz);
    return f;
  }
};

// a (rows x columns) grid component, zero where a DOF is absent or held
solid::SurfaceComponent GridComponent(std::vector<double> z, std::vector<double> theta) {
  solid::SurfaceComponent c;
  c.values = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(z.size()),
                                   static_cast<Eigen::Index>(theta.size()));
  c.z_m = std::move(z);
  c.theta_rad = std::move(theta);
  return c;
}

// the shell's modes on the ideal simply supported tube: as solved (thin) and thick-plate
// corrected, each labelled from its w, u and v on their staggered grids
std::array<ExactRow, 2> ShellRows(const SonicBoomConfig& config, double arc_m, double axial_m,
                                  double band_hz) {
  acoustics::ShellConfig shell = config.shell;
  shell.ends = TubeEnds::kSimplySupported;
  shell.ideal = true;
  shell.grid_spacing_m = arc_m;
  shell.axial_spacing_m = axial_m;
  const auto t0 = Clock::now();
  const acoustics::ShellModel model(config.tube, config.material, shell);
  acoustics::ShellModes modes = acoustics::CachedShellModes(
      model, kSolveMargin * band_hz, 0, true, config.acoustics.ModeCacheDir());
  const double seconds = SecondsSince(t0);
  const int rows = model.axial_points(), cols = model.circumferential_points();
  const double dz = model.dz_m(), dth = model.dtheta_rad();
  std::vector<double> zw, zu, thw, thv;
  for (int i = 0; i < rows; ++i) zw.push_back(model.NodeZ(i));
  for (int i = 0; i + 1 < rows; ++i) zu.push_back(model.NodeZ(i) + 0.5 * dz);
  for (int j = 0; j < cols; ++j) thw.push_back(j * dth);
  for (int j = 0; j < cols; ++j) thv.push_back((j + 0.5) * dth);
  const int64_t max_m = std::min(40, rows - 2), max_n = std::min(30, (cols - 1) / 2);
  std::vector<int64_t> all(static_cast<size_t>(model.dofs()));
  for (size_t d = 0; d < all.size(); ++d) all[d] = static_cast<int64_t>(d);
  // every DOF's row: the shapes move in whole (ModeRows::Of would copy them)
  const acoustics::ModeRows rows_of_all{modes.omega_rad_s, modes.rigid_body_modes, std::move(all),
                                        std::move(modes.shapes)};
  const Eigen::MatrixXd& shapes = rows_of_all.shapes;  // (dofs x modes)
  const Eigen::VectorXd factors = acoustics::ThickPlateFrequencyFactors(model, rows_of_all);
  std::array<ExactRow, 2> out;
  const std::string grid = fmt::format("shell, {:.1f} x {:.1f} mm", 1e3 * arc_m, 1e3 * axial_m);
  out[0] = {"thin (as solved; FD integrates this K)", grid, band_hz, model.dofs(), seconds, {}};
  out[1] = {"thick-plate", grid, band_hz, model.dofs(), seconds, {}};
  for (Eigen::Index k = 0; k < modes.omega_rad_s.size(); ++k) {
    std::array<solid::SurfaceComponent, 3> c{GridComponent(zw, thw), GridComponent(zw, thv),
                                             GridComponent(zu, thw)};
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) {
        const int64_t w = model.WIndex(i, j), v = model.VIndex(i, j), u = model.UIndex(i, j);
        if (w >= 0) c[0].values(i, j) = shapes(w, k);
        if (v >= 0) c[1].values(i, j) = shapes(v, k);
        if (u >= 0) c[2].values(i, j) = shapes(u, k);
      }
    }
    const solid::ModeLabel label = solid::LabelSimplySupportedMode(config.tube, c, max_m, max_n);
    const double f = modes.omega_rad_s(k) / (2 * kPi);
    out[0].labelled.push_back({f, label});
    out[1].labelled.push_back({f * factors(k), label});
  }
  return out;
}

// the reference solid, simply supported, no structure, on elements of element_m
ExactRow SolidRow(const SonicBoomConfig& config, double element_m, double band_hz) {
  solid::SolidMeshConfig mesh;
  mesh.element_arc_m = mesh.element_axial_m = element_m;
  mesh.Validate(config.tube);
  solid::SolidStructure structure;
  structure.ends = TubeEnds::kSimplySupported;
  const auto t0 = Clock::now();
  const solid::SolidTubeModel model(config.tube, config.material, structure, mesh);
  const solid::SolidLabelGrid grid = solid::MakeSolidLabelGrid(model);
  solid::SolidModeRequest request;
  request.max_frequency_hz = kSolveMargin * band_hz;
  request.with_shapes = false;
  request.projection_rows = grid.rows;
  const solid::SolidModes modes = solid::SolveSolidModes(model, request);
  ExactRow row{"reference solid",
               fmt::format("solid, h {:.1f} mm, p {}/{}", 1e3 * element_m, mesh.degree_wall,
                           mesh.degree_thickness),
               band_hz, model.dofs(), SecondsSince(t0), solid::LabelSolidModes(model, grid, modes)};
  return row;
}

// Flügge's thin shell: its (m, n, root) are labels by construction
ExactRow FluggeRow(const SonicBoomConfig& config, double band_hz) {
  ExactRow row{"closed form (Flügge)", "ideal simply supported tube", band_hz, 0, 0.0, {}};
  for (const acoustics::ShellMode& m :
       acoustics::SimplySupportedModes(config.tube, config.material, kSolveMargin * band_hz)) {
    for (int copy = 0; copy < (m.n == 0 ? 1 : 2); ++copy) {
      row.labelled.push_back({m.frequency_hz, {m.m, m.n, 1.0}});
    }
  }
  return row;
}

std::string ComparisonCell(const solid::ExactComparison& c) {
  if (c.matched == 0) return "–";
  return fmt::format("{:.2f} / {:.2f} / {:+.2f} ({})", 100 * c.median_abs, 100 * c.max_abs,
                     100 * c.signed_median, c.matched);
}

json ComparisonJson(const solid::ExactComparison& c) {
  json unmatched = json::array();
  for (const solid::ExactMode& e : c.unmatched)
    unmatched.push_back({{"m", e.m}, {"n", e.n}, {"branch", e.branch}, {"hz", e.frequency_hz}});
  return {{"unmatched", unmatched}, {"exact_count", c.exact_count}, {"model_count", c.model_count},
          {"matched", c.matched},         {"median_abs", c.median_abs},
          {"max_abs", c.max_abs},         {"signed_median", c.signed_median}};
}

CommandResult RunExact(const GlobalOptions& g, const ExactOptions& o) {
  const SonicBoomConfig config = Resolve(g);
  if (!o.out.empty()) RequireParentDir(o.out);
  const auto t0 = Clock::now();
  solid::ExactModeRequest request;
  request.max_frequency_hz = kSolveMargin * o.max_frequency_hz;
  request.radial_degree = o.radial_degree;
  const solid::ExactModeList exact =
      solid::ExactSimplySupportedModes(config.tube, config.material, request);
  const double exact_s = SecondsSince(t0);
  spdlog::info("exact: {} roots to {:.0f} Hz in {:.2f} s", exact.modes.size(),
               request.max_frequency_hz, exact_s);
  std::vector<ExactRow> rows;
  for (double h : o.solid_element_m) {
    spdlog::info("exact: reference solid on {:.1f} mm elements", 1e3 * h);
    rows.push_back(SolidRow(config, h, o.max_frequency_hz));
  }
  rows.push_back(FluggeRow(config, o.max_frequency_hz));
  if (o.shell) {
    const double arc = config.shell.grid_spacing_m, axial = config.shell.AxialSpacing();
    const std::vector<std::array<double, 2>> grids{
        {arc, axial}, {arc, 2 * axial}, {2 * arc, 2 * axial}, {0.01, 0.02}};
    for (const auto& [a, z] : grids) {
      spdlog::info("exact: shell on {:.1f} x {:.1f} mm", 1e3 * a, 1e3 * z);
      for (ExactRow& r : ShellRows(config, a, z, o.max_frequency_hz)) rows.push_back(r);
    }
    for (double band : kDerivedGridBandsHz) {
      const double spacing = SceneOfBand(config, band).config.shell.grid_spacing_m;
      ExactRow r = ShellRows(config, spacing, spacing, band)[1];
      r.rung = fmt::format("thick-plate, derived grid of {:.0f} kHz", band / 1000);
      rows.push_back(r);
    }
  }
  const double lo = std::min(10000.0, o.max_frequency_hz), hi = o.max_frequency_hz;
  std::string md = fmt::format(
      "Ideal simply supported tube (no seam, holes, bolts or mounts), exact 3-D elasticity "
      "(radial degree {}): {} modes below {:.0f} Hz, {} below {:.0f} Hz (pairs counted twice; "
      "{} rigid slide not counted), in {:.2f} s.\n\n"
      "| rung | grid | band (kHz) | modes < {:.0f} / < {:.0f} kHz | by (m, n, branch) to {:.0f} "
      "kHz: median / max / signed median % (matched) | to {:.0f} kHz | by rank to {:.0f} kHz | "
      "to {:.0f} kHz | s |\n|---|---|---|---|---|---|---|---|---|\n",
      o.radial_degree, exact.CountBelow(lo), lo, exact.CountBelow(hi), hi, exact.rigid_body_modes,
      exact_s, lo / 1000, hi / 1000, lo / 1000, hi / 1000, lo / 1000, hi / 1000);
  json jrows = json::array();
  std::string notes;  // the exact modes each rung leaves unmatched by family
  for (const ExactRow& r : rows) {
    const double b_lo = std::min(lo, r.band_hz), b_hi = std::min(hi, r.band_hz);
    const auto rank_lo = solid::CompareByRank(exact, r.FrequenciesHz(), b_lo);
    const auto rank_hi = solid::CompareByRank(exact, r.FrequenciesHz(), b_hi);
    const auto fam_lo = solid::CompareByFamily(exact, r.labelled, b_lo);
    const auto fam_hi = solid::CompareByFamily(exact, r.labelled, b_hi);
    const bool has_hi = r.band_hz >= hi;
    double purity = 1.0;  // the least clear label below the band
    for (const solid::LabelledMode& m : r.labelled)
      if (m.frequency_hz < b_hi) purity = std::min(purity, m.label.purity);
    md += fmt::format("| {} | {} | {:.0f} | {} / {} | {} | {} | {} | {} | {:.0f} |\n", r.rung,
                      r.grid, r.band_hz / 1000, rank_lo.model_count,
                      has_hi ? std::to_string(rank_hi.model_count) : "–", ComparisonCell(fam_lo),
                      has_hi ? ComparisonCell(fam_hi) : "–", ComparisonCell(rank_lo), has_hi ? ComparisonCell(rank_hi) : "–",
                      r.seconds);
    if (!fam_lo.worst.empty()) {
      std::string list;
      for (const auto& [e, err] : fam_lo.worst)
        list += fmt::format("{}({}, {}, {}) {:.1f} Hz {:+.2f} %", list.empty() ? "" : ", ", e.m,
                            e.n, e.branch, e.frequency_hz, 100 * err);
      notes += fmt::format("- {} ({}), worst below {:.0f} Hz by family: {}\n", r.rung, r.grid,
                           b_lo, list);
    }
    if (!fam_hi.unmatched.empty()) {
      std::string list;
      for (size_t i = 0; i < fam_hi.unmatched.size() && i < 12; ++i) {
        const solid::ExactMode& e = fam_hi.unmatched[i];
        list += fmt::format("{}({}, {}, {}) {:.1f} Hz", i ? ", " : "", e.m, e.n, e.branch,
                            e.frequency_hz);
      }
      notes += fmt::format("- {} ({}): {} exact modes below {:.0f} Hz without a mode of their "
                           "family: {}{}\n",
                           r.rung, r.grid, fam_hi.unmatched.size(), b_hi, list,
                           fam_hi.unmatched.size() > 12 ? ", ..." : "");
    }
    jrows.push_back({{"rung", r.rung},
                     {"grid", r.grid},
                     {"band_hz", r.band_hz},
                     {"dofs", r.dofs},
                     {"seconds", r.seconds},
                     {"lowest_purity", purity},
                     {"by_family_low", ComparisonJson(fam_lo)},
                     {"by_family_high", ComparisonJson(fam_hi)},
                     {"by_rank_low", ComparisonJson(rank_lo)},
                     {"by_rank_high", ComparisonJson(rank_hi)}});
  }
  if (!notes.empty()) md += "\n" + notes;
  json jexact = json::array();
  for (const solid::ExactMode& e : exact.modes)
    jexact.push_back({e.m, e.n, e.branch, e.frequency_hz, e.multiplicity});
  if (!o.out.empty()) WriteTextAtomic(o.out, md);
  json j = {{"exact_modes_m_n_branch_hz_multiplicity", jexact},
            {"exact_count_low", exact.CountBelow(lo)},
            {"exact_count_high", exact.CountBelow(hi)},
            {"rows", jrows}};
  return {j.dump(), md};
}

}  // namespace

void RegisterExact(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<ExactOptions>();
  auto* cmd = app.add_subcommand(
      "exact", "the ladder's models of the ideal simply supported tube against exact 3-D elasticity");
  cmd->add_option("--max-frequency", o->max_frequency_hz, "compare every mode up to here, Hz")
      ->check(NumberIn(1000.0, 22000.0));
  cmd->add_option("--radial-degree", o->radial_degree, "degree through the wall of the exact solver")
      ->check(NumberIn(solid::kMinRadialDegree, solid::kMaxRadialDegree, false, true));
  cmd->add_option("--solid-element", o->solid_element_m,
                  "element lengths of the reference solid meshes, m (none: no solid)");
  cmd->add_flag("!--no-shell", o->shell, "leave out the shell's grids");
  cmd->add_option("--out", o->out, "write the Markdown table here");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunExact(g, *o); }; });
}

}  // namespace sonicboom::experiments
