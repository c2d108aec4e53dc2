// Ritz structure variants against full mode solves of the same varied structure.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/shell_ritz.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

ShellConfig Coarse() {
  ShellConfig s;
  s.grid_spacing_m = 0.01;
  s.axial_spacing_m = 0.01;
  return s;
}

// largest relative frequency error over the modes below f_hz, matched in order
double WorstFrequencyError(const ShellModes& a, const ShellModes& b, double f_hz) {
  double worst = 0.0;
  const Eigen::Index n = std::min(a.omega_rad_s.size(), b.omega_rad_s.size());
  for (Eigen::Index k = 0; k < n; ++k) {
    if (b.omega_rad_s[k] > 2.0 * M_PI * f_hz) break;
    worst = std::max(worst, std::abs(a.omega_rad_s[k] / b.omega_rad_s[k] - 1.0));
  }
  return worst;
}

// the smallest, over the exact modes below f_hz, of the best mass-weighted MAC with a Ritz mode
double WorstShapeMatch(const ShellModes& ritz, const ShellModes& exact, const Eigen::VectorXd& mass,
                       double f_hz) {
  const Eigen::MatrixXd overlap = exact.shapes.transpose() * mass.asDiagonal() * ritz.shapes;
  double worst = 1.0;
  for (Eigen::Index k = 0; k < exact.omega_rad_s.size(); ++k) {
    if (exact.omega_rad_s[k] > 2.0 * M_PI * f_hz) break;
    // a degenerate pair may rotate within itself: the captured fraction of the exact shape
    const double captured = overlap.row(k).squaredNorm();
    worst = std::min(worst, captured);
  }
  return worst;
}

// How far a variation moved the modes below 5 kHz from the base's, and how far its Ritz
// projection lies from its full solve
struct RitzAgainstFull {
  double moved{0.0}, err{0.0};
};

// The variant projected from the base's modes (to 12 kHz) against its full solve to 8 kHz, with
// what every projection must hold: shapes mass-normalized for the variant, the exact shapes below
// 5 kHz captured, and the frequencies bounded above (Rayleigh-Ritz never undershoots)
RitzAgainstFull CheckAgainstFullSolve(const ShellModel& base, const ShellModel& varied,
                                      const char* label) {
  const ShellModes base_modes = SolveShellModes(base, 12000.0, 0, true);
  const ShellModes exact = SolveShellModes(varied, 8000.0, 0, true);
  const ShellModes ritz = RitzShellModes(base, base_modes, varied, 8000.0);
  if (ritz.shapes.rows() != varied.dofs()) {
    ADD_FAILURE() << "Ritz shapes of " << ritz.shapes.rows() << " rows, the variant has "
                  << varied.dofs() << " DOFs";
    return {};
  }
  const Eigen::MatrixXd gram =
      ritz.shapes.transpose() * varied.mass_kg().asDiagonal() * ritz.shapes;
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(gram.rows(), gram.cols())).cwiseAbs().maxCoeff(),
            1e-8);
  EXPECT_GT(WorstShapeMatch(ritz, exact, varied.mass_kg(), 5000.0), 0.97);
  for (Eigen::Index k = 0; k < std::min<Eigen::Index>(20, exact.omega_rad_s.size()); ++k) {
    EXPECT_GE(ritz.omega_rad_s[k], exact.omega_rad_s[k] * (1.0 - 1e-9)) << k;
  }
  const RitzAgainstFull out{WorstFrequencyError(base_modes, exact, 5000.0),
                            WorstFrequencyError(ritz, exact, 5000.0)};
  std::cout << "base vs " << label << ": " << out.moved << ", Ritz vs " << label << ": " << out.err
            << " (modes < 5 kHz)\n";
  return out;
}

TEST(RitzTest, BoltsMountsAndPoissonMatchAFullSolve) {
  const TubeConfig tube;
  const MaterialConfig material;
  const ShellModel base(tube, material, Coarse());
  // stiffer and moved bolts, one more bolt, a looser flange mount, a stiffer tool mount, nu up
  ShellConfig s = Coarse();
  s.bolt_z_m = {-0.11, -0.04, 0.03, 0.09};
  s.bolt_stiffness_n_m = 1.0e7;
  s.flange_mount_stiffness_n_m2 = 1.5e6;
  s.tool_mount_stiffness_n_m2 = 4.0e6;
  MaterialConfig m2 = material;
  m2.poisson_ratio = 0.41;
  // the variation moved the modes far more than the projection errs
  const RitzAgainstFull r = CheckAgainstFullSolve(base, ShellModel(tube, m2, s), "varied");
  EXPECT_GT(r.moved, 0.02);
  EXPECT_LT(r.err, 0.01);
}

TEST(RitzTest, AttachedMassesMatchAFullSolve) {
  const TubeConfig tube;
  const MaterialConfig material;
  const ShellModel base(tube, material, Coarse());
  // a 30 g connector near the flange, a 10 g cable clamp mid-tube, 2 g on each of two discs,
  // and a tighter bolt row (stiffness and mass change together)
  ShellConfig s = Coarse();
  s.attached_mass_kg = {0.03, 0.01, 0.002, 0.002};
  s.attached_mass_z_m = {-0.12, 0.02, -0.13, 0.13};
  s.attached_mass_theta_deg = {60.0, -150.0, 0.0, 120.0};
  s.bolt_stiffness_n_m = 6.0e6;
  const ShellModel varied(tube, material, s);
  // the masses are all there: 44 g more in each of the three directions
  EXPECT_NEAR(varied.mass_kg().sum() - base.mass_kg().sum(), 3.0 * 0.044, 1e-12);
  const RitzAgainstFull r = CheckAgainstFullSolve(base, varied, "massed");
  EXPECT_GT(r.moved, 0.01);
  EXPECT_LT(r.err, 0.2 * r.moved);
  EXPECT_LT(r.err, 0.01);
}

TEST(RitzTest, RefusesAnotherGrid) {
  const TubeConfig tube;
  const MaterialConfig material;
  const ShellModel base(tube, material, Coarse());
  const ShellModes base_modes = SolveShellModes(base, 3000.0, 0, true);
  ShellConfig s = Coarse();
  s.hole_z_m = {0.0};
  s.hole_theta_deg = {45.0};
  s.hole_diameter_m = 0.02;
  const ShellModel drilled(tube, material, s);
  try {
    RitzShellModes(base, base_modes, drilled, 3000.0);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("full mode solve"), std::string::npos) << e.what();
  }
  // the same grid with a thicker wall: the projections were made for the base's wall
  TubeConfig thick = tube;
  thick.wall_thickness_m *= 1.1;
  const ShellModel walled(thick, material, Coarse());
  ASSERT_EQ(walled.dofs(), base.dofs());
  const std::string refusal = testing::ThrownMessage<ConfigError>(
      [&] { RitzShellModes(base, base_modes, walled, 3000.0); });
  EXPECT_NE(refusal.find("wall thickness"), std::string::npos) << refusal;
}

TEST(RitzTest, CacheReadsBackWhatItWrote) {
  const TubeConfig tube;
  const MaterialConfig material;
  const ShellModel base(tube, material, Coarse());
  const ShellModes base_modes = SolveShellModes(base, 3000.0, 0, true);
  const ShellRitzProjector projector(base, base_modes);
  ShellConfig s = Coarse();
  s.bolt_stiffness_n_m *= 3.0;
  const ShellModel varied(tube, material, s);
  const std::vector<int64_t> rows = {0, 7, 100, 2001};
  const testing::TempDir dir;
  const auto get = [&projector]() -> const ShellRitzProjector& { return projector; };
  bool hit = true;
  const ModeRows first =
      CachedRitzModes(get, base, varied, 3000.0, rows, dir.path().string(), &hit);
  EXPECT_FALSE(hit);
  const ModeRows second =
      CachedRitzModes(get, base, varied, 3000.0, rows, dir.path().string(), &hit);
  EXPECT_TRUE(hit);
  // frequencies exact, shapes stored in single precision
  EXPECT_TRUE(first.omega_rad_s == second.omega_rad_s);
  EXPECT_TRUE(second.dofs == rows);
  EXPECT_TRUE(first.shapes.cast<float>().cast<double>() == second.shapes);
  // other rows are another entry
  CachedRitzModes(get, base, varied, 3000.0, {0, 7}, dir.path().string(), &hit);
  EXPECT_FALSE(hit);
  // a damaged file is recomputed
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    std::filesystem::resize_file(entry.path(), 100);
  }
  const ModeRows third =
      CachedRitzModes(get, base, varied, 3000.0, rows, dir.path().string(), &hit);
  EXPECT_FALSE(hit);
  EXPECT_TRUE(third.omega_rad_s == first.omega_rad_s);
}

}  // namespace
}  // namespace sonicboom::acoustics
