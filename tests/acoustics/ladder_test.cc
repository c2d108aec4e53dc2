// The vibration ladder's public API (acoustics/ladder.h): shared damping, FD and modal rungs of
// one grid, and the contact force solved against a rung's wall.
#include "sonicboom/acoustics/ladder.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

constexpr double kFs = 44100.0;
constexpr double kBandHz = 12000.0;

const testing::TempDir& Cache() {
  static const testing::TempDir dir;
  return dir;
}

// a rung of the 10 mm grid, damped as the FD rung realizes the default loss law
std::unique_ptr<VibrationRung> Rung(VibrationModel model, double band_hz = 0.0) {
  MaterialConfig material;
  ShellConfig shell;
  // the thin shell the FD rung integrates (the thick-plate correction is dispersion_test's)
  shell.dispersion = Dispersion::kThin;
  UseFdDamping(TubeConfig{}, &material, &shell);
  AcousticModelConfig base;
  base.material = material;
  base.shell = shell;
  base.audio.sample_rate_hz = kFs;
  base.synth.decay_floor_db = -80.0;
  base.synth.mode_cache_dir = Cache().path().string();
  RungSpec spec;
  spec.model = model;
  spec.arc_m = spec.axial_m = 0.01;
  spec.band_hz = band_hz;
  return std::make_unique<VibrationRung>(base, spec, kBandHz);
}

ContactEvent Dowel() {
  ContactEvent c;
  c.time_s = 0.002;
  c.z_m = 0.04;
  c.theta_rad = 0.9;
  c.normal_speed_m_s = 0.3;
  c.effective_mass_kg = 0.03;
  c.striker_radius_m = 0.011;
  c.striker_youngs_modulus_pa = 1e9;
  c.striker_poisson_ratio = 0.35;
  return c;
}

TEST(LadderTest, FdDampingMeetsTheLossLawAtItsAnchors) {
  const TubeConfig tube;
  MaterialConfig material;
  ShellConfig shell;  // damping law, constant eta = material.loss_factor
  const ShellModel law(tube, material, shell);
  UseFdDamping(tube, &material, &shell);
  EXPECT_EQ(shell.damping, DampingModel::kRayleigh);
  const ShellModel fd(tube, material, shell);
  for (double f : {shell.loss_low_hz, shell.loss_high_hz}) {
    const double w = 2.0 * std::numbers::pi * f;
    EXPECT_NEAR(fd.DampingRatio(w), law.DampingRatio(w), 1e-9 * law.DampingRatio(w)) << f;
  }
  // between the anchors the Rayleigh curve departs from the flat law, below it
  const double w = 2.0 * std::numbers::pi * std::sqrt(shell.loss_low_hz * shell.loss_high_hz);
  EXPECT_LT(fd.DampingRatio(w), law.DampingRatio(w));
  // a Rayleigh shell is left alone
  const MaterialConfig before = material;
  UseFdDamping(tube, &material, &shell);
  EXPECT_EQ(material.loss_factor, before.loss_factor);
}

TEST(LadderTest, FdAndModalRungsOfOneGridAgree) {
  const auto modal = Rung(VibrationModel::kModal, kBandHz);
  const auto fd = Rung(VibrationModel::kFd);
  EXPECT_FALSE(modal->fd());
  EXPECT_TRUE(fd->fd());
  EXPECT_EQ(modal->dofs(), fd->dofs());
  EXPECT_GE(fd->oversampling(), 1);
  EXPECT_EQ(modal->oversampling(), 0);
  EXPECT_EQ(fd->ModesPlayed(5000.0), 0);
  // the band picks the modes: more below a wider band; the spec's band overrides the strike's
  const auto derived = Rung(VibrationModel::kModal);
  EXPECT_LT(derived->ModesPlayed(2000.0), derived->ModesPlayed(8000.0));
  EXPECT_EQ(modal->ModesPlayed(2000.0), modal->ModesPlayed(8000.0));

  // one solved contact force through both rungs: they differ by integration and truncation only
  const SolvedForce solved = SolveRigidStrikeForce(Dowel(), *modal, TubeConfig{}, MaterialConfig{},
                                                   SynthConfig{}, kFs, kBandHz);
  ASSERT_FALSE(solved.force.force_n.empty());
  EXPECT_GT(solved.derived_band_hz, 0.0);
  EXPECT_LE(solved.derived_band_hz, kBandHz);
  const std::vector<ForceInput> forces{solved.force};
  const int64_t samples = static_cast<int64_t>(0.02 * kFs);
  const Eigen::MatrixXd a = modal->Render(forces, samples, solved.derived_band_hz);
  const Eigen::MatrixXd b = fd->Render(forces, samples, solved.derived_band_hz);
  ASSERT_EQ(a.rows(), 6);
  ASSERT_EQ(a.cols(), samples);
  ASSERT_TRUE(a.allFinite() && b.allFinite());
  EXPECT_GT(b.norm(), 0.0);
  EXPECT_LT((a - b).norm() / b.norm(), 0.05);
}

TEST(LadderTest, OnlyAModalRungHasAModalWall) {
  EXPECT_THROW(Rung(VibrationModel::kFd)->WallAt(0.0, 0.0, 5000.0), Error);
  EXPECT_THROW(Rung(VibrationModel::kModalClosedForm)->WallAt(0.0, 0.0, 5000.0), Error);
}

// the closed-form rung (the ideal simply supported tube): a slow inward push right under a disc
// compresses that disc (the sign every rung shares, docs/conventions.md), it plays the modes of
// its band, and it has no grid
TEST(LadderTest, ClosedFormRungPushesInwardAndPlaysItsBand) {
  const auto rung = Rung(VibrationModel::kModalClosedForm);
  const MicArrayConfig mics;
  ForceInput push{mics.z_m[0], mics.theta_deg[0] * std::numbers::pi / 180.0, 10, {}};
  for (int k = 0; k <= 220; ++k)
    push.force_n.push_back(20.0 * std::sin(std::numbers::pi * k / 220));
  const Eigen::MatrixXd y = rung->Render(std::span<const ForceInput>(&push, 1), 600, 5000.0);
  Eigen::Index at = 0;
  y.row(0).cwiseAbs().maxCoeff(&at);
  EXPECT_LT(y(0, at), 0.0);
  EXPECT_EQ(rung->dofs(), 0);
  const Eigen::VectorXd f = rung->FrequenciesHz();
  EXPECT_EQ(rung->ModesPlayed(5000.0), (f.array() <= 5000.0).count());
  EXPECT_GT(rung->ModesPlayed(5000.0), 20);
}

}  // namespace
}  // namespace sonicboom::acoustics

