// Closed-form shell modes against published and computed values (docs/physics.md, "Shell modes").
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// lowest root of (m = 1, n) from a mode list
double Lowest(const std::vector<ShellMode>& modes, int m, int n) {
  double f = std::numeric_limits<double>::infinity();
  for (const auto& mode : modes) {
    if (mode.m == m && mode.n == n) f = std::min(f, mode.frequency_hz);
  }
  return f;
}

TEST(CylinderModesTest, FluggeMatchesLoyLamBenchmark) {
  // nu = 0.3, L/R = 20, h/R = 0.01, m = 1: nondimensional Omega = omega R sqrt(rho (1 - nu^2) / E)
  TubeConfig tube;
  const double R = 1.0, h = 0.01;
  tube.wall_thickness_m = h;
  tube.outer_radius_m = R + h / 2;
  tube.length_m = 20.0;
  MaterialConfig mat;
  mat.poisson_ratio = 0.3;
  mat.youngs_modulus_pa = 1e9;
  mat.density_kg_m3 = 1000.0;
  const double to_omega =
      2 * std::numbers::pi * R * std::sqrt(mat.density_kg_m3 * (1 - 0.09) / mat.youngs_modulus_pa);
  const auto modes = SimplySupportedModes(tube, mat, 200.0);
  const double table[10] = {0.016101, 0.009382, 0.022105, 0.042095, 0.068008,
                            0.099730, 0.137239, 0.180527, 0.229594, 0.284435};
  for (int n = 1; n <= 10; ++n) {
    EXPECT_NEAR(Lowest(modes, 1, n) * to_omega, table[n - 1], 1e-4 * table[n - 1] + 5e-6)
        << "n = " << n;
  }
}

TEST(CylinderModesTest, PvcSimplySupportedTable) {
  // docs/physics.md, "Simply supported ends": Flügge, default SDR35 pipe (Hz)
  const auto modes = SimplySupportedModes(TubeConfig{}, MaterialConfig{}, 5000.0);
  EXPECT_NEAR(Lowest(modes, 1, 2), 356, 1.5);
  EXPECT_NEAR(Lowest(modes, 1, 3), 655, 1.5);
  EXPECT_NEAR(Lowest(modes, 1, 1), 682, 1.5);
  EXPECT_NEAR(Lowest(modes, 2, 3), 850, 1.5);
  EXPECT_NEAR(Lowest(modes, 3, 4), 1513, 2.0);
  EXPECT_NEAR(Lowest(modes, 1, 0), 1446, 2.0);  // torsion = c_S / 2L
}

// m = 0: u = cos(n th) along the whole tube, an in-plane shear of the wall at c_s n / R (with
// Flügge's h^2 / 12 R^2 term), no radial part
TEST(CylinderModesTest, AxiallyUniformShearFamilyIsShearSpeedTimesNOverRadius) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const double cs = std::sqrt(pvc.youngs_modulus_pa / (2 * (1 + pvc.poisson_ratio)) /
                              pvc.density_kg_m3);
  const double r = tube.mid_radius_m(), h = tube.wall_thickness_m;
  const double f1 = cs / (2 * kPi * r) * std::sqrt(1 + h * h / (12 * r * r));
  const auto modes = SimplySupportedModes(tube, pvc, 6000.0);
  EXPECT_NEAR(Lowest(modes, 0, 1) / f1, 1.0, 1e-12);
  EXPECT_NEAR(Lowest(modes, 0, 2) / f1, 2.0, 1e-12);
  int uniform = 0;
  for (const ShellMode& m : modes) {
    if (m.m != 0) continue;
    ++uniform;
    EXPECT_EQ(m.w, 0.0);
    EXPECT_GE(m.n, 1);
  }
  EXPECT_EQ(uniform, 2);  // n = 1, 2 below 6 kHz (n = 3 at 8.1 kHz)
}

TEST(CylinderModesTest, RayleighFreeFreeValues) {
  // docs/physics.md, "Free-free ends", Hz: f_20 220, f_30 622, f_40 1192, f_50 1928, f_60 2829
  const double expected[5] = {220, 622, 1192, 1928, 2829};
  for (int n = 2; n <= 6; ++n) {
    EXPECT_NEAR(RayleighFrequency(TubeConfig{}, MaterialConfig{}, n), expected[n - 2],
                0.005 * expected[n - 2]);
  }
  // the free list is ascending, each frequency twice (degenerate pairs), starting at f_20
  const auto f = ClosedFormFrequencies(TubeConfig{}, MaterialConfig{}, TubeEnds::kFree, 8);
  ASSERT_EQ(f.size(), 8u);
  EXPECT_NEAR(f[0], 220, 1.5);
  EXPECT_EQ(f[0], f[1]);
  EXPECT_NEAR(f[2], 229, 1.5);  // f_21
  for (size_t i = 1; i < f.size(); ++i) EXPECT_LE(f[i - 1], f[i]);
}

TEST(CylinderModesTest, SimplySupportedListCountsPairsTwice) {
  const auto f =
      ClosedFormFrequencies(TubeConfig{}, MaterialConfig{}, TubeEnds::kSimplySupported, 10);
  ASSERT_EQ(f.size(), 10u);
  EXPECT_NEAR(f[0], 356, 1.5);
  EXPECT_EQ(f[0], f[1]);
  for (size_t i = 1; i < f.size(); ++i) EXPECT_LE(f[i - 1], f[i]);
  EXPECT_THROW(ClosedFormFrequencies(TubeConfig{}, MaterialConfig{}, TubeEnds::kFree, 0),
               ConfigError);
}

}  // namespace
}  // namespace sonicboom::acoustics
