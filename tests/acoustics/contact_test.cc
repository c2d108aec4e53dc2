// Striker-tube contact: the rod's beam modes (FE vs Euler-Bernoulli roots, tip modal mass) and
// the substepped Hertz / Hunt-Crossley solve (rigid-target closed form, losses, compliant wall,
// beam striker, error paths).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/test_util.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using testing::ThrownMessage;

using ::testing::HasSubstr;

using sonicboom::kPi;
constexpr double kFs = 44100.0;
// wood tip on PVC: K = 4/3 E* sqrt(R_e), E* 2.79 GPa, R_e 6 mm (docs/physics.md, "Hertz impact")
const double kWoodOnPvc = 4.0 / 3.0 * 2.79e9 * std::sqrt(0.006);

// rigid-target Hertz closed form (docs/physics.md, "Hertz impact")
struct Hertz {
  double delta_max_m, peak_n, duration_s;
};
Hertz ClosedForm(double m_kg, double k_n_m15, double v_m_s) {
  const double delta = std::pow(5.0 * m_kg * v_m_s * v_m_s / (4.0 * k_n_m15), 0.4);
  return {delta, k_n_m15 * std::pow(delta, 1.5), 2.9432 * delta / v_m_s};
}

DrivingPoint RigidMass(double m_kg) {
  DrivingPoint p;
  p.rigid_mass_kg = m_kg;
  return p;
}
const DrivingPoint kHeld;  // infinite mass, no modes

// Ø12.7 mm wooden dowel, E 12 GPa, rho 700 kg/m^3 (docs/physics.md, "Beam modes", example)
BeamSpec Dowel(double length_m) {
  const double r = 0.0127 / 2.0, area = kPi * r * r, second_moment = kPi * std::pow(r, 4) / 4.0;
  BeamSpec b;
  b.length_m = length_m;
  b.flexural_rigidity_n_m2 = 12e9 * second_moment;
  b.linear_density_kg_m = 700.0 * area;
  b.contact_from_clamp_m = length_m;
  return b;
}

// ---- beam modes ----

TEST(BeamModesTest, CantileverAndClampedClampedMatchEulerBernoulliRoots) {
  BeamSpec beam = Dowel(0.5);
  beam.contact_from_clamp_m = 0.37;  // the mesh splits here: unequal elements either side
  const double scale_rad_s =
      std::sqrt(beam.flexural_rigidity_n_m2 / (beam.linear_density_kg_m * std::pow(0.5, 4)));
  auto check = [&](const std::vector<double>& roots, const Eigen::VectorXd& f_hz) {
    ASSERT_GE(f_hz.size(), static_cast<Eigen::Index>(roots.size()));
    for (size_t n = 0; n < roots.size(); ++n) {
      const double exact_hz = roots[n] * roots[n] * scale_rad_s / (2.0 * kPi);
      const double err = f_hz[static_cast<Eigen::Index>(n)] / exact_hz - 1.0;
      std::cout << "  mode " << n + 1 << ": " << f_hz[static_cast<Eigen::Index>(n)] << " Hz, "
                << "error " << err * 100.0 << " %\n";
      EXPECT_LT(std::abs(err), 1e-3) << "mode " << n + 1;
    }
  };
  std::cout << "cantilever, 48 elements:\n";
  check({1.875104, 4.694091, 7.854757, 10.995541, 14.137168}, BeamFrequenciesHz(beam, 48, 0.0));
  beam.clamped_both_ends = true;
  std::cout << "clamped-clamped, 48 elements:\n";
  check({4.730041, 7.853205, 10.995608}, BeamFrequenciesHz(beam, 48, 0.0));
}

TEST(BeamModesTest, DowelExampleAndBandLimit) {
  const Eigen::VectorXd f_hz = BeamFrequenciesHz(Dowel(0.5), 48, 600.0);
  ASSERT_EQ(f_hz.size(), 3);  // 29.4, 184.4, 516.3 Hz; the fourth (1012 Hz) is above the band
  EXPECT_NEAR(f_hz[0], 29.4, 0.05);
  EXPECT_NEAR(f_hz[1], 184.4, 0.05);
  EXPECT_NEAR(f_hz[2], 516.3, 0.05);
  // unlimited: only the resolved part of a 96-DOF spectrum
  const Eigen::VectorXd all = BeamFrequenciesHz(Dowel(0.5), 48, 0.0);
  EXPECT_GT(all.size(), 10);
  EXPECT_LE(all.size(), 2 * 48 * 2 / 3);
  EXPECT_TRUE(std::is_sorted(all.data(), all.data() + all.size()));
}

TEST(BeamModesTest, CantileverTipModalMassIsQuarterRodMass) {
  const BeamSpec beam = Dowel(0.5);
  const double rod_kg = beam.linear_density_kg_m * beam.length_m;  // 44.3 g
  const DrivingPoint tip = BeamDrivingPoint(beam, 20000.0);
  ASSERT_GE(tip.phi.size(), 3);
  EXPECT_TRUE(std::isinf(tip.rigid_mass_kg));
  for (int n = 0; n < 3; ++n) {
    const double modal_kg = 1.0 / (tip.phi[n] * tip.phi[n]);
    std::cout << "  mode " << n + 1 << " tip modal mass " << modal_kg * 1e3
              << " g (m_rod/4 = " << rod_kg / 4.0 * 1e3 << " g)\n";
    EXPECT_NEAR(modal_kg / (rod_kg / 4.0), 1.0, 0.01) << "mode " << n + 1;
    EXPECT_NEAR(tip.zeta[n], 0.5 * beam.loss_factor, 1e-15);
  }
  EXPECT_LE(tip.omega_rad_s.maxCoeff(), 2.0 * kPi * 20000.0);
}

TEST(BeamModesTest, InvalidRodIsConfigErrorNamingTheField) {
  BeamSpec b = Dowel(0.5);
  b.length_m = 0.0;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamFrequenciesHz(b, 48, 0.0); }),
              HasSubstr("length_m"));
  b = Dowel(0.5);
  b.flexural_rigidity_n_m2 = -1.0;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamDrivingPoint(b, 1000.0); }),
              HasSubstr("flexural_rigidity_n_m2"));
  b = Dowel(0.5);
  b.linear_density_kg_m = 0.0;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamDrivingPoint(b, 1000.0); }),
              HasSubstr("linear_density_kg_m"));
  b = Dowel(0.5);
  b.contact_from_clamp_m = 0.6;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamDrivingPoint(b, 1000.0); }),
              HasSubstr("contact_from_clamp_m"));
  b.contact_from_clamp_m = 0.0;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamDrivingPoint(b, 1000.0); }),
              HasSubstr("contact_from_clamp_m"));
  // clamped at both ends, the far end is a clamp: nothing to hit there
  b = Dowel(0.5);
  b.clamped_both_ends = true;
  EXPECT_THAT(ThrownMessage<ConfigError>([&] { BeamDrivingPoint(b, 1000.0); }),
              HasSubstr("contact_from_clamp_m"));
}

// ---- contact solve ----

TEST(ContactTest, RigidTargetMatchesHertzClosedForm) {
  ContactConfig coarse;
  coarse.substeps_per_duration = 50;  // the floor the config allows must already be within 1 %
  double worst_default = 0.0, worst_coarse = 0.0;
  for (const double m_kg : {0.002, 0.01, 0.1, 1.0}) {
    for (const double v_m_s : {0.01, 0.1, 0.5, 10.0}) {
      const Hertz exact = ClosedForm(m_kg, kWoodOnPvc, v_m_s);
      for (const ContactConfig& config : {ContactConfig{}, coarse}) {
        const double time_s = 0.0123456;  // not on the sample or substep grid
        const ContactForce c =
            SolveContact(RigidMass(m_kg), kHeld, kWoodOnPvc, v_m_s, time_s, kFs, config);
        const double e_duration = c.duration_s / exact.duration_s - 1.0;
        const double e_peak = c.peak_force_n / exact.peak_n - 1.0;
        const double e_impulse = c.impulse_ns / (2.0 * m_kg * v_m_s) - 1.0;
        const double e_rebound = c.rebound_speed_m_s / v_m_s - 1.0;
        const double worst = std::max(
            {std::abs(e_duration), std::abs(e_peak), std::abs(e_impulse), std::abs(e_rebound)});
        double& tally = config.substeps_per_duration == 50 ? worst_coarse : worst_default;
        tally = std::max(tally, worst);
        SCOPED_TRACE(::testing::Message() << "m " << m_kg << " kg, v " << v_m_s << " m/s, "
                                          << config.substeps_per_duration << " substeps/t_c");
        EXPECT_LT(std::abs(e_duration), 0.01);
        EXPECT_LT(std::abs(e_peak), 0.01);
        EXPECT_LT(std::abs(e_impulse), 0.01);
        EXPECT_LT(std::abs(e_rebound), 0.01);
        EXPECT_EQ(c.touches, 1);
        EXPECT_EQ(c.first_closure_s, c.duration_s);
        // the sample-averaged force carries the impulse, from the sample holding time_s
        EXPECT_EQ(c.first_sample, static_cast<int64_t>(std::floor(time_s * kFs)));
        const double carried = std::accumulate(c.force_n.begin(), c.force_n.end(), 0.0) / kFs;
        EXPECT_NEAR(carried / c.impulse_ns, 1.0, 1e-12);
        EXPECT_GE(c.force_n.front(), 0.0);
        // trimmed at the release (or one sample before, when the release substep held no force)
        EXPECT_GT(c.force_n.back(), 0.0);
        const int64_t release_sample =
            static_cast<int64_t>(std::floor((time_s + c.duration_s) * kFs));
        EXPECT_LE(c.first_sample + static_cast<int64_t>(c.force_n.size()) - 1, release_sample);
        EXPECT_GE(c.first_sample + static_cast<int64_t>(c.force_n.size()) - 1, release_sample - 1);
      }
    }
  }
  std::cout << "rigid target, worst relative error (duration, peak, impulse, rebound): "
            << worst_default << " at 200 substeps/t_c, " << worst_coarse << " at 50\n";
  EXPECT_LT(worst_default, 1e-3);
}

TEST(ContactTest, TwoFreeMassesActAsTheirSeriesMass) {
  // a 30 g tube side into a free 20 g striker: m* = 12 g; the striker's rebound is inside the
  // relative coordinate, so the closed form holds with m*
  const Hertz exact = ClosedForm(0.012, kWoodOnPvc, 0.8);
  const ContactForce c =
      SolveContact(RigidMass(0.03), RigidMass(0.02), kWoodOnPvc, 0.8, 0.0, kFs, ContactConfig{});
  EXPECT_NEAR(c.duration_s / exact.duration_s, 1.0, 1e-3);
  EXPECT_NEAR(c.peak_force_n / exact.peak_n, 1.0, 1e-3);
  EXPECT_NEAR(c.impulse_ns / (2.0 * 0.012 * 0.8), 1.0, 1e-3);
  // which side is held does not matter: a held tube hit by a free striker is the same impact
  const ContactForce swapped =
      SolveContact(kHeld, RigidMass(0.012), kWoodOnPvc, 0.8, 0.0, kFs, ContactConfig{});
  EXPECT_NEAR(swapped.impulse_ns / c.impulse_ns, 1.0, 1e-3);
}

TEST(ContactTest, HuntCrossleyLosesEnergyAndNeverPulls) {
  const double m_kg = 0.01;
  for (const double v_m_s : {0.2, 1.0, 5.0}) {
    for (const double lambda_s_m : {0.05, 0.5, 5.0}) {
      ContactConfig config;
      config.hunt_crossley_s_m = lambda_s_m;
      const ContactForce c =
          SolveContact(RigidMass(m_kg), kHeld, kWoodOnPvc, v_m_s, 0.001, kFs, config);
      SCOPED_TRACE(::testing::Message() << "v " << v_m_s << " m/s, lambda " << lambda_s_m);
      EXPECT_LT(c.rebound_speed_m_s, v_m_s);
      EXPECT_GT(c.rebound_speed_m_s, 0.0);
      EXPECT_GT(c.impulse_ns, m_kg * v_m_s);
      EXPECT_LT(c.impulse_ns, 2.0 * m_kg * v_m_s);
      // the rigid mass leaves at the rebound speed: impulse = m (v + v_out)
      EXPECT_NEAR(c.impulse_ns / (m_kg * (v_m_s + c.rebound_speed_m_s)), 1.0, 1e-3);
      EXPECT_EQ(c.touches, 1);
      for (const double f : c.force_n) EXPECT_GE(f, 0.0);
      // weak damping: restitution e ~ 1 - 2/3 lambda v (Hunt & Crossley 1975)
      if (lambda_s_m * v_m_s <= 0.05) {
        EXPECT_NEAR(c.rebound_speed_m_s / v_m_s, 1.0 - 2.0 / 3.0 * lambda_s_m * v_m_s, 0.005);
      }
    }
  }
}

// tube side: a 10 g rigid part with a wall of three light modes above the contact band
DrivingPoint CompliantTube(double zeta) {
  DrivingPoint p = RigidMass(0.01);
  p.omega_rad_s = 2.0 * kPi * Eigen::Vector3d(3000.0, 5200.0, 8100.0);
  p.zeta = Eigen::Vector3d::Constant(zeta);
  p.phi = Eigen::Vector3d(1.0 / std::sqrt(0.004), 1.0 / std::sqrt(0.006), 1.0 / std::sqrt(0.01));
  return p;
}

TEST(ContactTest, CompliantWallLengthensAndSoftensTheContact) {
  const double v_m_s = 0.5;
  const Hertz rigid = ClosedForm(0.01, kWoodOnPvc, v_m_s);
  const ContactForce c =
      SolveContact(CompliantTube(0.0), kHeld, kWoodOnPvc, v_m_s, 0.0, kFs, ContactConfig{});
  std::cout << "compliant wall: duration " << c.duration_s * 1e6 << " us (rigid "
            << rigid.duration_s * 1e6 << "), peak " << c.peak_force_n << " N (rigid "
            << rigid.peak_n << "), impulse " << c.impulse_ns / (2 * 0.01 * v_m_s)
            << " x 2 m v, touches " << c.touches << ", substeps " << c.substeps << "\n";
  EXPECT_GT(c.duration_s, 1.05 * rigid.duration_s);
  EXPECT_LT(c.peak_force_n, 0.95 * rigid.peak_n);
  // the rigid part cannot leave faster than it came: impulse = m (v + v_out) <= 2 m v
  EXPECT_GT(c.impulse_ns, 0.0);
  EXPECT_LE(c.impulse_ns, 2.0 * 0.01 * v_m_s * (1.0 + 1e-6));
  for (const double f : c.force_n) EXPECT_GE(f, 0.0);
  // converged: four times finer substeps change nothing beyond 0.1 %
  ContactConfig fine;
  fine.substeps_per_duration = 800;
  const ContactForce f = SolveContact(CompliantTube(0.0), kHeld, kWoodOnPvc, v_m_s, 0.0, kFs, fine);
  EXPECT_NEAR(f.duration_s / c.duration_s, 1.0, 1e-3);
  EXPECT_NEAR(f.peak_force_n / c.peak_force_n, 1.0, 1e-3);
  EXPECT_NEAR(f.impulse_ns / c.impulse_ns, 1.0, 1e-3);
}

TEST(ContactTest, LightWallModeUnderAHeavyTubeIsResolvedAndConverges) {
  // a 0.5 kg tube side whose wall carries a 1 g mode at 800 Hz: the first closure is a quick
  // bounce of that mode, far shorter than the rigid-mass estimate the substep starts from
  DrivingPoint tube = RigidMass(0.5);
  tube.omega_rad_s = 2.0 * kPi * Eigen::Vector2d(800.0, 6000.0);
  tube.zeta = Eigen::Vector2d(0.01, 0.01);
  tube.phi = Eigen::Vector2d(1.0 / std::sqrt(0.001), 1.0 / std::sqrt(0.005));
  const DrivingPoint striker = RigidMass(0.01);
  const double v_m_s = 0.5, m_star = 1.0 / (1.0 / 0.5 + 1.0 / 0.01);
  ContactForce runs[2];
  for (int i = 0; i < 2; ++i) {
    ContactConfig config;
    config.substeps_per_duration = i == 0 ? 200 : 800;
    runs[i] = SolveContact(tube, striker, kWoodOnPvc, v_m_s, 0.0, kFs, config);
  }
  const ContactForce& c = runs[0];
  std::cout << "light wall mode: duration " << c.duration_s * 1e6 << " us (rigid "
            << ClosedForm(m_star, kWoodOnPvc, v_m_s).duration_s * 1e6 << "), peak "
            << c.peak_force_n << " N, impulse " << c.impulse_ns / (m_star * v_m_s)
            << " x m* v, touches " << c.touches << ", substeps " << c.substeps << " / "
            << runs[1].substeps << "; 4x finer: impulse " << runs[1].impulse_ns / c.impulse_ns - 1
            << ", peak " << runs[1].peak_force_n / c.peak_force_n - 1 << "\n";
  // the rigid parts end up separating, no faster than they met: m* v <= impulse <= 2 m* v
  EXPECT_GE(c.impulse_ns, m_star * v_m_s);
  EXPECT_LE(c.impulse_ns, 2.0 * m_star * v_m_s * (1.0 + 1e-6));
  EXPECT_NEAR(runs[1].impulse_ns / c.impulse_ns, 1.0, 2e-3);
  EXPECT_NEAR(runs[1].peak_force_n / c.peak_force_n, 1.0, 2e-3);
  EXPECT_EQ(runs[1].touches, c.touches);
  // chatter: the first closure is the wall mode's quick bounce, well inside the whole contact
  ASSERT_GT(c.touches, 1);
  EXPECT_LT(c.first_closure_s, 0.5 * c.duration_s);
  EXPECT_LT(c.first_closure_s, ClosedForm(m_star, kWoodOnPvc, v_m_s).duration_s);
}

TEST(ContactTest, DowelStrikerModalMassSetsTheScale) {
  // a 20 g tube side into the tip of a clamped dowel (tip modal mass m_rod/4 = 11.1 g per mode)
  const BeamSpec dowel = Dowel(0.5);
  const DrivingPoint rod = BeamDrivingPoint(dowel, ContactConfig{}.beam_max_frequency_hz);
  const double m_tube = 0.02, v_m_s = 0.5;
  const double m_mode = dowel.linear_density_kg_m * dowel.length_m / 4.0;
  const double m_eff = 1.0 / (1.0 / m_tube + 1.0 / m_mode);
  ContactConfig config;
  config.max_duration_s = 0.2;  // the rod's 29 Hz mode takes its time to push back
  const ContactForce c = SolveContact(RigidMass(m_tube), rod, kWoodOnPvc, v_m_s, 0.0, kFs, config);
  std::cout << "dowel striker: " << rod.phi.size() << " modes, duration " << c.duration_s * 1e3
            << " ms, peak " << c.peak_force_n << " N, impulse "
            << c.impulse_ns / (2 * m_eff * v_m_s) << " x 2 m_eff v, touches " << c.touches
            << ", rebound " << c.rebound_speed_m_s << " m/s, substeps " << c.substeps << "\n";
  EXPECT_TRUE(std::isfinite(c.impulse_ns));
  EXPECT_GT(c.impulse_ns, 0.0);
  EXPECT_GT(c.impulse_ns, 0.5 * 2.0 * m_eff * v_m_s);
  EXPECT_LT(c.impulse_ns, 2.0 * 2.0 * m_eff * v_m_s);
  // the tube ends up leaving the held rod, no faster than it came: m v <= impulse <= 2 m v
  EXPECT_GE(c.impulse_ns, m_tube * v_m_s);
  EXPECT_LE(c.impulse_ns, 2.0 * m_tube * v_m_s * (1.0 + 1e-6));
  // far softer than a rigid target: the rod's modes take the blow
  EXPECT_LT(c.peak_force_n, 0.5 * ClosedForm(m_tube, kWoodOnPvc, v_m_s).peak_n);
  for (const double f : c.force_n) EXPECT_GE(f, 0.0);
  EXPECT_GE(c.touches, 1);
  // converged: the chatter's total impulse barely moves with 4x finer substeps
  config.substeps_per_duration = 800;
  const ContactForce fine =
      SolveContact(RigidMass(m_tube), rod, kWoodOnPvc, v_m_s, 0.0, kFs, config);
  std::cout << "  4x finer: impulse " << fine.impulse_ns / c.impulse_ns - 1 << ", duration "
            << fine.duration_s / c.duration_s - 1 << ", touches " << fine.touches << "\n";
  EXPECT_NEAR(fine.impulse_ns / c.impulse_ns, 1.0, 0.01);
}

// ---- errors ----

struct Root {
  struct Acoustics {
    ContactConfig contact;
    void Serialize(Archive* a) { a->Visit("contact", &contact); }
  } acoustics;
  void Serialize(Archive* a) { a->Visit("acoustics", &acoustics); }
};

std::string ReadError(const std::string& yaml) {
  return ThrownMessage<ConfigError>([&] {
    ConfigLayers layers;
    layers.AddText(yaml, "test");
    Root root;
    layers.ReadInto(&root);
  });
}

TEST(ContactConfigTest, BoundsAreEnforcedOnRead) {
  EXPECT_THAT(ReadError("acoustics: {contact: {substeps_per_duration: 49}}"),
              HasSubstr("acoustics.contact.substeps_per_duration"));
  EXPECT_THAT(ReadError("acoustics: {contact: {min_substeps: 0}}"),
              HasSubstr("acoustics.contact.min_substeps"));
  EXPECT_THAT(ReadError("acoustics: {contact: {hunt_crossley_s_m: -0.1}}"),
              HasSubstr("acoustics.contact.hunt_crossley_s_m"));
  EXPECT_THAT(ReadError("acoustics: {contact: {separation_window_s: 0}}"),
              HasSubstr("acoustics.contact.separation_window_s"));
  EXPECT_THAT(ReadError("acoustics: {contact: {max_duration_s: 11}}"),
              HasSubstr("acoustics.contact.max_duration_s"));
  EXPECT_THAT(ReadError("acoustics: {contact: {beam_max_frequency_hz: 0}}"),
              HasSubstr("acoustics.contact.beam_max_frequency_hz"));
  // in range reads back
  ConfigLayers layers;
  layers.AddText("acoustics: {contact: {substeps_per_duration: 50, separation_window_s: 1}}", "ok");
  Root root;
  layers.ReadInto(&root);
  EXPECT_EQ(root.acoustics.contact.substeps_per_duration, 50);
  EXPECT_EQ(root.acoustics.contact.separation_window_s, 1.0);
}

TEST(ContactTest, ContactThatCannotEndIsNumericalErrorNamingTheLimit) {
  // a heavy tube side pressing into a clamped rod keeps it closed past max_duration_s
  const DrivingPoint rod = BeamDrivingPoint(Dowel(0.5), 2000.0);
  const std::string message = ThrownMessage<NumericalError>(
      [&] { SolveContact(RigidMass(50.0), rod, kWoodOnPvc, 0.5, 0.0, kFs, ContactConfig{}); });
  EXPECT_THAT(message, HasSubstr("acoustics.contact.max_duration_s"));
  // both sides held: refused up front
  EXPECT_THAT(ThrownMessage<ConfigError>(
                  [&] { SolveContact(kHeld, kHeld, kWoodOnPvc, 0.5, 0.0, kFs, ContactConfig{}); }),
              HasSubstr("rigid_mass_kg"));
  EXPECT_THROW(SolveContact(RigidMass(0.01), kHeld, kWoodOnPvc, 0.0, 0.0, kFs, ContactConfig{}),
               ConfigError);
}

}  // namespace
}  // namespace sonicboom::acoustics
