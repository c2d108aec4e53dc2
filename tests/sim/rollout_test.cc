// Dynamic strike rollouts in MuJoCo: placement, contact records, press, determinism, failures.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "rollout_expect.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {
namespace {

using sonicboom::kPi;
constexpr int kSeeds = 30;

// one default rollout model and its 30 seeded rollouts, shared by the tests of this file
const StrikeRollout& DefaultRollout() {
  static const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{},
                                     RolloutConfig{});
  return rollout;
}
const std::vector<RolloutResult>& DefaultResults() {
  static const std::vector<RolloutResult> results = [] {
    std::vector<RolloutResult> out;
    for (uint64_t i = 0; i < kSeeds; ++i) out.push_back(DefaultRollout().Run(i, SampleSeed(21, i)));
    return out;
  }();
  return results;
}

double AngleDistance(double a_rad, double b_rad) {
  return std::abs(WrapAngle(a_rad - b_rad));
}

TEST(RolloutTest, ContactsLieOnTheTubeWhereTheRodWasPlaced) {
  const TubeConfig tube;
  const StrikeConfig strike;
  int valid = 0;
  std::map<std::string, int> reasons;
  for (const RolloutResult& r : DefaultResults()) {
    if (!r.valid) {
      ++reasons[r.invalid_reason.substr(0, r.invalid_reason.find(" ("))];
      continue;
    }
    ++valid;
    ASSERT_FALSE(r.contacts.empty());
    const ContactRecord& first = r.contacts.front();
    EXPECT_EQ(first.kind, ContactEpisode::Kind::kImpact);
    EXPECT_GE(first.z_m, tube.contact_z_min_m);
    EXPECT_LE(first.z_m, tube.contact_z_max_m);
    // the placement: the first touch is where the rod was put
    EXPECT_LT(std::abs(first.z_m - r.target_z_m), 0.01);
    EXPECT_LT(AngleDistance(first.theta_rad, r.target_theta_rad), 10.0 * kPi / 180.0);
    // and near the intended onset
    EXPECT_LT(std::abs(first.time_s - r.target_time_s), 0.05);
    for (const ContactRecord& c : r.contacts) {
      const double radius_m = std::hypot(c.point_m.x(), c.point_m.y());
      EXPECT_LT(std::abs(radius_m - tube.outer_radius_m), 1e-3);
      EXPECT_GT(c.theta_rad, -kPi);
      EXPECT_LE(c.theta_rad, kPi);
      EXPECT_NEAR(c.normal.norm(), 1.0, 1e-9);
      // the outward normal points along the surface normal at theta
      EXPECT_GT(c.normal.dot(SurfaceNormal(c.theta_rad)), 0.95);
      EXPECT_GT(c.impulse_Ns, 0.0);
      EXPECT_GT(c.peak_force_N, 0.0);
      EXPECT_GT(c.effective_mass_kg, 0.0);
      // in series with the rod's modal mass 5 cm from its tip: never above it
      const ObjectConfig rod;
      const double rod_kg = rod.LinearDensityKgM() * rod.length_m;
      EXPECT_LT(c.effective_mass_kg,
                BeamModalMassKg(rod_kg, rod.length_m, rod.length_m - 0.05, false));
      EXPECT_EQ(c.object, "rod T22L42");
      EXPECT_EQ(c.material, "wood");
    }
    EXPECT_GT(first.normal_speed_m_s, 0.01);
    EXPECT_LT(first.normal_speed_m_s, 0.5);
    // proprioception: finite, unit quaternions
    ASSERT_EQ(r.proprio.rows(), strike.proprio_rows);
    ASSERT_EQ(r.proprio.cols(), kProprioFeatures);
    EXPECT_TRUE(r.proprio.allFinite());
    for (int k = 0; k < r.proprio.rows(); ++k) {
      EXPECT_NEAR(r.proprio.row(k).segment<4>(3).norm(), 1.0, 1e-5) << "row " << k;
    }
    EXPECT_EQ(r.joint_speed_rad_s.size(), 200u);
  }
  std::cout << "valid " << valid << " / " << kSeeds << "\n";
  for (const auto& [reason, count] : reasons) std::cout << "  " << count << " x " << reason << "\n";
  EXPECT_GE(valid, static_cast<int>(0.8 * kSeeds));
}

TEST(RolloutTest, TargetsMatchTheKinematicGenerator) {
  // the same draws: a seed names the same intended contact in both generators
  const StrikeModel kinematic(StrikeConfig{}, SceneConfig{}, TubeConfig{}, AudioConfig{});
  for (uint64_t i = 0; i < 5; ++i) {
    const StrikeEvents ev = kinematic.Generate(SampleSeed(21, i));
    const RolloutResult& r = DefaultResults()[i];
    EXPECT_EQ(r.target_z_m, ev.label.z_m);
    EXPECT_EQ(r.target_time_s, ev.label.time_s);
    EXPECT_LT(AngleDistance(r.target_theta_rad, ev.label.theta_rad), 1e-3);
  }
}

TEST(RolloutTest, TubeStaysPressedAgainstTheRod) {
  // the goal lies beyond the rod: after the impact the tube stays on it
  int pressed = 0, valid = 0;
  std::map<ContactEpisode::Kind, int> kinds;
  double min_duration_s = 1e9, max_duration_s = 0.0;
  for (const RolloutResult& r : DefaultResults()) {
    if (!r.valid) continue;
    ++valid;
    bool long_contact = false;
    for (const ContactRecord& c : r.contacts) {
      ++kinds[c.kind];
      if (c.kind == ContactEpisode::Kind::kPress ||
          (c.kind == ContactEpisode::Kind::kImpact && c.duration_s > 0.02)) {
        long_contact = true;
      }
    }
    const double first_s = r.contacts.front().duration_s;
    min_duration_s = std::min(min_duration_s, first_s);
    max_duration_s = std::max(max_duration_s, first_s);
    pressed += long_contact ? 1 : 0;
  }
  std::cout << "pressed " << pressed << " / " << valid << "; first episode " << min_duration_s
            << " .. " << max_duration_s << " s; kinds:";
  for (const auto& [kind, count] : kinds)
    std::cout << " " << static_cast<int>(kind) << " " << count;
  std::cout << "\n";
  EXPECT_EQ(pressed, valid);
}

TEST(RolloutTest, SameSeedSameRolloutOnAnyThread) {
  const StrikeRollout& rollout = DefaultRollout();
  ExpectSameRecords(rollout.Run(3, SampleSeed(21, 3)), DefaultResults()[3]);
  // 8 seeds on one thread, then split over two threads
  constexpr int kCount = 8;
  std::vector<RolloutResult> serial(kCount), parallel(kCount);
  for (int i = 0; i < kCount; ++i) serial[i] = rollout.Run(i, SampleSeed(77, i));
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      for (int i = t; i < kCount; i += 2) parallel[i] = rollout.Run(i, SampleSeed(77, i));
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (int i = 0; i < kCount; ++i) ExpectSameRecords(serial[i], parallel[i]);
  // and different seeds give different strikes
  EXPECT_NE(serial[0].target_z_m, serial[1].target_z_m);
}

TEST(RolloutTest, SteadyPressStepsKeepContactsAndImpulses) {
  // every step at timestep_s against the default (a steady press steps 2 timesteps)
  RolloutConfig config;
  config.press_step_multiple = 1;
  ASSERT_EQ(RolloutConfig{}.ResolvedPressStepMultiple(), 2);
  const StrikeRollout fine(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
  int64_t fine_steps = 0, default_steps = 0;
  for (uint64_t i = 0; i < 10; ++i) {
    const RolloutResult a = fine.Run(i, SampleSeed(21, i));
    const RolloutResult& b = DefaultResults()[i];
    fine_steps += a.steps;
    default_steps += b.steps;
    ASSERT_EQ(a.valid, b.valid) << i;
    ASSERT_EQ(a.contacts.size(), b.contacts.size()) << i;
    for (size_t k = 0; k < a.contacts.size(); ++k) {
      const ContactRecord &x = a.contacts[k], &y = b.contacts[k];
      EXPECT_EQ(x.time_s, y.time_s);
      EXPECT_EQ(x.z_m, y.z_m);
      EXPECT_EQ(x.theta_rad, y.theta_rad);
      EXPECT_EQ(x.normal_speed_m_s, y.normal_speed_m_s);
      EXPECT_EQ(x.kind, y.kind);
      EXPECT_NEAR(x.duration_s, y.duration_s, 1e-9);
      EXPECT_NEAR(y.impulse_Ns, x.impulse_Ns, 0.005 * x.impulse_Ns) << i << " " << k;
    }
    EXPECT_TRUE((a.proprio - b.proprio).cwiseAbs().maxCoeff() < 1e-3) << i;
  }
  // the press is most of the stepping: the default takes well under 80 % of the steps
  EXPECT_LT(default_steps, 0.8 * fine_steps) << default_steps << " vs " << fine_steps;
  // a multiple the contact cannot take is refused, naming the limit
  config.press_step_multiple = 3;
  try {
    StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("rollout.press_step_multiple = 3"), std::string::npos) << message;
    EXPECT_NE(message.find("0.003 s"), std::string::npos) << message;  // 2 x 3 x 0.0005 s
  }
}

// The step scheduler's shortcuts against plain stepping (the full model, collision detection at
// every step of one timestep) on the default scene's first 30 seeds: the exact shortcuts
// (collision skipping, the tube-only model) change nothing, bit for bit; the multi-steps (free
// flight at k timesteps, a steady press at 2) keep the first contact's kind and segment and move
// its labels and impulse by less than the bounds below (later episodes of a press may differ:
// the friction flicker re-contacts under the 2-step press).
TEST(RolloutTest, StepSchedulersAgreeWithPlainStepping) {
  RolloutConfig plain_config, exact_config;
  plain_config.stepping = StepScheduler::kPlain;
  exact_config.stepping = StepScheduler::kExact;
  const StrikeRollout plain(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{},
                            plain_config);
  const StrikeRollout exact(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{},
                            exact_config);
  const double dt = RolloutConfig{}.ResolvedTimestep();
  double worst_time = 0, worst_z = 0, worst_theta = 0, worst_speed = 0, worst_impulse = 0;
  int64_t fast_steps = 0, plain_steps = 0, contacts = 0, more_episodes = 0;
  for (uint64_t i = 0; i < kSeeds; ++i) {
    const RolloutResult p = plain.Run(i, SampleSeed(21, i));
    ExpectSameRecords(exact.Run(i, SampleSeed(21, i)), p);
    const RolloutResult& f = DefaultResults()[i];
    fast_steps += f.steps;
    plain_steps += p.steps;
    ASSERT_EQ(f.valid, p.valid) << i;
    ASSERT_EQ(f.contacts.empty(), p.contacts.empty()) << i;
    // the press's friction flicker may re-contact under the 2-step press: later episodes differ
    more_episodes += f.contacts.size() != p.contacts.size() ? 1 : 0;
    for (size_t k = 0; k < std::min<size_t>(1, p.contacts.size()); ++k) {
      const ContactRecord &x = f.contacts[k], &y = p.contacts[k];
      EXPECT_EQ(x.kind, y.kind) << i << " " << k;
      EXPECT_EQ(x.segment, y.segment) << i << " " << k;
      worst_time = std::max(worst_time, std::abs(x.time_s - y.time_s));
      worst_z = std::max(worst_z, std::abs(x.z_m - y.z_m));
      worst_theta = std::max(worst_theta, AngleDistance(x.theta_rad, y.theta_rad));
      worst_speed = std::max(worst_speed, std::abs(x.normal_speed_m_s - y.normal_speed_m_s) /
                                              std::max(1e-9, std::abs(y.normal_speed_m_s)));
      // a press split in two by a re-contact carries its impulse in two episodes
      if (f.contacts.size() == p.contacts.size()) {
        worst_impulse = std::max(worst_impulse, std::abs(x.impulse_Ns - y.impulse_Ns) /
                                                    std::max(1e-9, std::abs(y.impulse_Ns)));
      }
      ++contacts;
    }
  }
  std::printf(
      "fast vs plain over %d seeds, %lld first contacts: time %.3g s (%.2f steps), z %.3g m, "
      "theta %.3g rad, speed %.3g, impulse %.3g (relative); %lld seeds with another episode "
      "count; steps %lld vs %lld\n",
      kSeeds, static_cast<long long>(contacts), worst_time, worst_time / dt, worst_z, worst_theta,
      worst_speed, worst_impulse, static_cast<long long>(more_episodes),
      static_cast<long long>(fast_steps), static_cast<long long>(plain_steps));
  EXPECT_GT(contacts, kSeeds / 2);
  // the bounds: the same first step, z within 1 um, theta within 1e-4 rad, approach speed within
  // 0.5 %, impulse within 1 % (same episode count), at most 3 seeds of 30 with another count
  EXPECT_EQ(worst_time, 0.0);
  EXPECT_LT(worst_z, 1e-6);
  EXPECT_LT(worst_theta, 1e-4);
  EXPECT_LT(worst_speed, 0.005);
  EXPECT_LT(worst_impulse, 0.01);
  EXPECT_LE(more_episodes, 3);
  // what the shortcuts buy: under half the steps
  EXPECT_LT(fast_steps, plain_steps / 2);
}

TEST(RolloutTest, TinyPenetrationLimitInvalidatesWithoutCrashing) {
  RolloutConfig config;
  config.penetration_limit_m = 1e-9;
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
  const RolloutResult r = rollout.Run(0, SampleSeed(21, 0));
  EXPECT_FALSE(r.valid);
  EXPECT_NE(r.invalid_reason.find("rollout.penetration_limit_m"), std::string::npos)
      << r.invalid_reason;
  EXPECT_TRUE(r.proprio.allFinite());
}

TEST(RolloutTest, SoftContactSinksIntoTheRodAndIsInvalid) {
  // a 0.2 s contact time constant lets the pressing arm sink far into the rod
  RolloutConfig config;
  config.contact_timeconst_s = 0.2;
  config.timestep_s = 0.001;
  config.settle_s = 0.3;
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
  const RolloutResult r = rollout.Run(0, SampleSeed(21, 0));
  EXPECT_FALSE(r.valid);
  EXPECT_NE(r.invalid_reason.find("penetration"), std::string::npos) << r.invalid_reason;
}

TEST(RolloutTest, AbsurdStiffnessNeverCrashes) {
  // torques saturate at the motor limits; whatever happens, Run returns
  RolloutConfig config;
  config.stiffness_nm_rad.assign(7, 1e9);
  config.timestep_s = 0.005;
  config.contact_timeconst_s = 0.01;
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
  const RolloutResult r = rollout.Run(1, SampleSeed(21, 1));
  if (!r.valid) std::cout << "absurd stiffness: " << r.invalid_reason << "\n";
  EXPECT_TRUE(r.proprio.allFinite());
}

TEST(RolloutTest, ContactTimeConstantBelowTwoTimestepsIsAConfigError) {
  RolloutConfig config;
  config.timestep_s = 0.001;
  config.contact_timeconst_s = 0.0015;
  try {
    StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("rollout.contact_timeconst_s"), std::string::npos) << message;
    EXPECT_NE(message.find("0.002"), std::string::npos) << message;  // the limit, 2 x 0.001 s
  }
  // the derived timestep (timeconst / 4) always satisfies the rule
  config.timestep_s = 0.0;
  EXPECT_DOUBLE_EQ(StrikeRollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config)
                       .timestep_s(),
                   0.0015 / 4);
  config.stiffness_nm_rad.pop_back();
  EXPECT_THROW(StrikeRollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{}, config),
               ConfigError);
}

}  // namespace
}  // namespace sonicboom::sim
