// The exact simply supported tube (solid/ss_exact.h) against its Bessel closed forms, its own
// convergence and thin-shell theory in the thin-wall limit; the mode labeller and matcher
// (solid/exact_match.h) on fields and lists of known answer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <vector>

#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/exact_match.h"
#include "sonicboom/solid/ss_exact.h"

namespace sonicboom::solid {
namespace {

// the nearest root of `spectrum` to omega, relative to omega
double NearestRelative(const Eigen::VectorXd& spectrum, double omega) {
  return (spectrum.array() - omega).abs().minCoeff() / omega;
}

TEST(ExactTubeTest, TorsionIsShearWaveSpeedTimesKAndBesselRootsAbove) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const double cs = std::sqrt(pvc.youngs_modulus_pa / (2 * (1 + pvc.poisson_ratio)) /
                              pvc.density_kg_m3);
  const double k = 5 * kPi / tube.length_m;
  const std::vector<double> torsion = TorsionOmegas(tube, pvc, k, 2);
  EXPECT_DOUBLE_EQ(torsion[0], cs * k);
  // the first Bessel torsion root is a thickness-shear resonance, about c_s pi / h
  EXPECT_NEAR(torsion[1] / std::hypot(cs * k, cs * kPi / tube.wall_thickness_m), 1.0, 0.01);
  const Eigen::VectorXd spectrum = WallSpectrum(tube, pvc, k, 0, 12, WallFields::kAll);
  for (double omega : torsion) EXPECT_LT(NearestRelative(spectrum, omega), 1e-9) << omega;
}

TEST(ExactTubeTest, AxiallyUniformShearModesAreTheAntiPlaneBesselRoots) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  for (int64_t n : {0, 1, 2, 5}) {
    const std::vector<double> closed = AntiPlaneOmegas(tube, pvc, n, 2);
    const Eigen::VectorXd spectrum = WallSpectrum(tube, pvc, 0.0, n, 12, WallFields::kAxialOnly);
    ASSERT_EQ(spectrum.size(), 13);
    if (n == 0) {
      EXPECT_LT(spectrum(0), 1e-3 * closed[1]);  // the rigid slide
    } else {
      EXPECT_LT(std::abs(spectrum(0) / closed[0] - 1), 1e-10) << "n " << n;
    }
    EXPECT_LT(std::abs(spectrum(1) / closed[1] - 1), 1e-9) << "n " << n;
  }
  // the thin-wall limit of the n = 1 root: c_s / R at the mid-surface, within (h / R)^2
  const double cs = std::sqrt(pvc.youngs_modulus_pa / (2 * (1 + pvc.poisson_ratio)) /
                              pvc.density_kg_m3);
  EXPECT_NEAR(AntiPlaneOmegas(tube, pvc, 1, 1)[0] * tube.mid_radius_m() / cs, 1.0, 0.005);
}

TEST(ExactTubeTest, BreathingRingInPlaneStrainIsItsBesselRoot) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const Eigen::VectorXd spectrum = WallSpectrum(tube, pvc, 0.0, 0, 12, WallFields::kAll);
  for (double omega : BreathingOmegas(tube, pvc, 2))
    EXPECT_LT(NearestRelative(spectrum, omega), 1e-9) << omega;
}

TEST(ExactTubeTest, ConvergedInTheRadialDegreeTo1e6Below20kHz) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  ExactModeRequest coarse, fine;
  coarse.radial_degree = 8;
  fine.radial_degree = kMaxRadialDegree;
  const ExactModeList a = ExactSimplySupportedModes(tube, pvc, coarse);
  const ExactModeList b = ExactSimplySupportedModes(tube, pvc, fine);
  ASSERT_EQ(a.modes.size(), b.modes.size());
  EXPECT_EQ(a.rigid_body_modes, 1);
  double worst = 0.0;
  for (size_t i = 0; i < a.modes.size(); ++i) {
    EXPECT_EQ(a.modes[i].m, b.modes[i].m);
    EXPECT_EQ(a.modes[i].n, b.modes[i].n);
    worst = std::max(worst, std::abs(a.modes[i].frequency_hz / b.modes[i].frequency_hz - 1));
  }
  EXPECT_LT(worst, 1e-6);
  // every family the list holds below 10 kHz, counted: the k = 0 shear modes among them
  const auto has = [&b](int64_t m, int64_t n) {
    return std::any_of(b.modes.begin(), b.modes.end(), [=](const ExactMode& e) {
      return e.m == m && e.n == n && e.frequency_hz < 10000.0;
    });
  };
  EXPECT_TRUE(has(0, 1));
  EXPECT_TRUE(has(0, 2));
  EXPECT_TRUE(has(1, 0));
  EXPECT_GT(b.CountBelow(10000.0), 200);
}

// a wall 0.3 mm thick is a thin shell: Flügge's frequencies of each (m, n, root) within 0.5 %
TEST(ExactTubeTest, ThinWallMeetsFluggesShell) {
  TubeConfig tube;
  tube.wall_thickness_m = 0.0003;
  const MaterialConfig pvc;
  ExactModeRequest request;
  request.max_frequency_hz = 3000.0;
  const ExactModeList exact = ExactSimplySupportedModes(tube, pvc, request);
  std::map<std::tuple<int64_t, int64_t, int64_t>, double> by_family;
  for (const ExactMode& e : exact.modes) by_family[{e.m, e.n, e.branch}] = e.frequency_hz;
  int compared = 0;
  for (const acoustics::ShellMode& f : acoustics::SimplySupportedModes(tube, pvc, 2500.0)) {
    if (f.root != 0 || f.n < 2) continue;
    const auto it = by_family.find({f.m, f.n, 0});
    ASSERT_NE(it, by_family.end()) << f.m << " " << f.n;
    EXPECT_NEAR(it->second / f.frequency_hz, 1.0, 0.005) << f.m << " " << f.n;
    ++compared;
  }
  EXPECT_GE(compared, 10);
}

TEST(ExactTubeTest, RefusesDegreesOutsideItsRange) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  EXPECT_THROW(WallSpectrum(tube, pvc, 1.0, 1, kMaxRadialDegree + 1, WallFields::kAll),
               ConfigError);
  EXPECT_THROW(WallSpectrum(tube, pvc, -1.0, 1, 8, WallFields::kAll), ConfigError);
}

// a field of one (m, n) sampled on a grid: u_r, u_th, u_z of the separable form, scaled, turned
// by turn_rad; swapped: the other orientation (u_r ~ sin, u_th ~ cos: torsion when n = 0)
std::array<SurfaceComponent, 3> Field(const TubeConfig& tube, int64_t m, int64_t n, double ur,
                                      double ut, double uz, double turn_rad, bool swapped) {
  std::array<SurfaceComponent, 3> c;
  for (auto& comp : c) {
    for (int i = 0; i < 40; ++i) comp.z_m.push_back(tube.length_m * ((i + 0.5) / 40 - 0.5));
    for (int j = 0; j < 48; ++j) comp.theta_rad.push_back(2 * kPi * j / 48);
    comp.values.resize(40, 48);
  }
  for (int i = 0; i < 40; ++i) {
    const double x = kPi * m * (c[0].z_m[i] / tube.length_m + 0.5);
    for (int j = 0; j < 48; ++j) {
      const double t = n * (c[0].theta_rad[j] + turn_rad);
      const double even = swapped ? std::sin(t) : std::cos(t);
      const double odd = swapped ? std::cos(t) : std::sin(t);
      c[0].values(i, j) = ur * std::sin(x) * even;
      c[1].values(i, j) = ut * std::sin(x) * odd;
      c[2].values(i, j) = uz * std::cos(x) * even;
    }
  }
  return c;
}

TEST(ExactMatchTest, LabelsSeparableFieldsOfEveryKindAndTurn) {
  const TubeConfig tube;
  struct Case {
    int64_t m, n;
    double ur, ut, uz, turn;
    bool swapped;
  };
  for (const Case& k :
       {Case{3, 4, 1.0, 0.2, 0.05, 0.0, false}, Case{7, 2, 0.1, 1.0, 0.0, 0.3, true},
        Case{1, 0, 0.0, 1.0, 0.0, 0.0, true}, Case{2, 0, 1.0, 0.0, 0.4, 0.0, false},
        Case{0, 2, 0.0, 0.0, 1.0, 0.1, false}, Case{12, 9, 1.0, 0.0, 0.0, 1.1, false}}) {
    const ModeLabel label = LabelSimplySupportedMode(
        tube, Field(tube, k.m, k.n, k.ur, k.ut, k.uz, k.turn, k.swapped), 30, 20);
    EXPECT_EQ(label.m, k.m);
    EXPECT_EQ(label.n, k.n);
    EXPECT_GT(label.purity, 0.99) << k.m << " " << k.n;
  }
}

TEST(ExactMatchTest, FamiliesMatchEachPairInTurnAndRankMixesSwappedModes) {
  ExactModeList exact;
  exact.modes = {{1, 2, 0, 100.0, 2}, {1, 3, 0, 101.0, 2}, {2, 0, 0, 300.0, 1}};
  // the model has the (1, 3) pair below the (1, 2) pair, and one mode of (2, 0) past the band
  const auto mode = [](double f, int64_t m, int64_t n) { return LabelledMode{f, {m, n, 1.0}}; };
  const std::vector<LabelledMode> model{mode(99.0, 1, 3), mode(99.5, 1, 3), mode(102.0, 1, 2),
                                        mode(102.0, 1, 2), mode(350.0, 2, 0)};
  const ExactComparison family = CompareByFamily(exact, model, 200.0);
  EXPECT_EQ(family.exact_count, 4);
  EXPECT_EQ(family.model_count, 4);
  ASSERT_EQ(family.matched, 4);
  EXPECT_NEAR(family.max_abs, 0.02, 1e-12);  // 102 against 100
  std::vector<double> hz;
  for (const LabelledMode& m : model) hz.push_back(m.frequency_hz);
  const ExactComparison rank = CompareByRank(exact, hz, 400.0);
  EXPECT_EQ(rank.exact_count, 5);
  EXPECT_EQ(rank.matched, 5);
  EXPECT_NEAR(rank.relative_error[0], -0.01, 1e-12);  // 99 against 100
  EXPECT_NEAR(rank.relative_error[4], 350.0 / 300.0 - 1, 1e-12);
}

}  // namespace
}  // namespace sonicboom::solid
