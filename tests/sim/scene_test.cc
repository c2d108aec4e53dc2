// Scenes: beam modal mass, object geometry, object draws, validation, and rollouts of every mode.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "rollout_expect.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/sim/stationary.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::sim {
namespace {

using sonicboom::kPi;

ObjectConfig Rod(double diameter_m, double length_m) {
  ObjectConfig o;
  o.kind = ObjectKind::kRod;
  o.diameter_m = diameter_m;
  o.length_m = length_m;
  return o;
}

// the three strikers of configs/materials.yaml
std::vector<ObjectConfig> MaterialStrikers() {
  auto striker = [](ObjectMaterial material, double diameter_m, double wall_m, double e_pa,
                    double contact_e_pa, double poisson, double density, double loss) {
    ObjectConfig o;
    o.kind = ObjectKind::kStriker;
    o.material = material;
    o.diameter_m = diameter_m;
    o.length_m = 0.40;
    o.wall_thickness_m = wall_m;
    o.elastic.youngs_modulus_pa = e_pa;
    o.contact_youngs_modulus_pa = contact_e_pa;
    o.elastic.poisson_ratio = poisson;
    o.elastic.density_kg_m3 = density;
    o.elastic.loss_factor = loss;
    return o;
  };
  return {striker(ObjectMaterial::kWood, 0.022, 0.0, 1.2e10, 1.0e9, 0.35, 650, 0.01),
          striker(ObjectMaterial::kAluminium, 0.025, 0.0015, 6.9e10, 6.9e10, 0.33, 2700, 0.001),
          striker(ObjectMaterial::kPvc, 0.0213, 0.0028, 3.0e9, 3.0e9, 0.38, 1400, 0.02)};
}

// configs/ts3.yaml's scene: one branch structure with foliage, guided sampling around it
SceneConfig Ts3Scene() {
  SceneConfig scene;
  scene.mode = SceneMode::kGuided;
  ObjectConfig branch;
  branch.kind = ObjectKind::kBranch;
  branch.diameter_m = 0.025;
  branch.length_m = 0.30;
  branch.branch.levels = 2;
  branch.branch.forks = 2;
  branch.branch.fork_angle_deg = 35;
  branch.branch.length_ratio = 0.8;
  branch.branch.variants = 1;
  branch.branch.shape_seed = 3;
  branch.branch.min_target_diameter_m = 0.006;
  branch.branch.leaf_cluster_radius_m = 0.06;
  branch.branch.leaf_clusters_per_tip = 3;
  scene.objects = {branch};
  GuidedConfig& g = scene.guided;
  g.object_position_m = {-0.40, 0.40, 0.31};
  g.object_yaw_deg = 0;
  g.plane_z_m = 0.315;
  g.x_range_m = {-0.22, 0.22};
  g.y_range_m = {0.20, 0.55};
  g.grid_points = 484;
  g.clearance_m = 0.0715;
  g.layer_m = 0.10;
  g.tap_deg = 15;
  g.amplitude_threshold = 0.02;
  return scene;
}

// distance between the infinite lines through two segments (not parallel)
double AxisDistance(const ObjectSegment& a, const ObjectSegment& b) {
  const Eigen::Vector3d n = (a.p1 - a.p0).cross(b.p1 - b.p0);
  return std::abs((b.p0 - a.p0).dot(n)) / n.norm();
}

// throws ConfigError whose message contains every one of `keys`
template <typename F>
void ExpectConfigError(F&& f, const std::vector<std::string>& keys) {
  try {
    f();
    ADD_FAILURE() << "no ConfigError; expected one naming " << keys.front();
  } catch (const ConfigError& e) {
    const std::string message = e.what();
    for (const std::string& key : keys) {
      EXPECT_NE(message.find(key), std::string::npos) << "'" << key << "' not in: " << message;
    }
  }
}

// the first hard (non-brush) contact, or null
const ContactRecord* FirstHard(const RolloutResult& r) {
  for (const ContactRecord& c : r.contacts) {
    if (c.kind != ContactEpisode::Kind::kBrush) return &c;
  }
  return nullptr;
}

void PrintReasons(const std::string& what, const std::vector<RolloutResult>& results) {
  std::map<std::string, int> reasons;
  int valid = 0;
  for (const RolloutResult& r : results) {
    if (r.valid) {
      ++valid;
    } else {
      ++reasons[r.invalid_reason.substr(0, r.invalid_reason.find(" ("))];
    }
  }
  std::cout << what << ": valid " << valid << " / " << results.size() << "\n";
  for (const auto& [reason, count] : reasons) std::cout << "  " << count << " x " << reason << "\n";
}

// ---------------------------------------------------------------------------------------------
// Beam modal mass (docs/physics.md, "Beam modes")

TEST(SceneTest, BeamModalMassOfCantileverAndClampedBeam) {
  const double m = 0.17, length = 0.42;
  // every cantilever mode has tip modal mass m / 4
  EXPECT_NEAR(BeamModalMassKg(m, length, length, false) / (0.25 * m), 1.0, 1e-6);
  // clamped-clamped at mid-span: m / phi(1/2)^2 = m / 2.522 = 0.3965 m
  EXPECT_NEAR(BeamModalMassKg(m, length, 0.5 * length, true) / m, 0.396, 0.01 * 0.396);
  // a clamp does not move: infinite (or huge) modal mass there
  for (const bool both : {false, true}) {
    const double at_clamp = BeamModalMassKg(m, length, 0.0, both);
    EXPECT_TRUE(std::isinf(at_clamp) || at_clamp > 1e6 * m) << at_clamp;
    EXPECT_GT(at_clamp, 0.0);
  }
  const double far_clamp = BeamModalMassKg(m, length, length, true);
  EXPECT_TRUE(std::isinf(far_clamp) || far_clamp > 1e6 * m) << far_clamp;
  // a cantilever moves more towards its tip: the modal mass falls monotonically
  double previous = std::numeric_limits<double>::infinity();
  for (int k = 1; k <= 200; ++k) {
    const double mass = BeamModalMassKg(m, length, length * k / 200.0, false);
    EXPECT_LT(mass, previous) << "x = " << length * k / 200.0;
    previous = mass;
  }
  // the clamped-clamped mode is symmetric about mid-span, with its smallest mass there
  for (const double f : {0.1, 0.25, 0.4}) {
    const double left = BeamModalMassKg(m, length, f * length, true);
    const double right = BeamModalMassKg(m, length, (1.0 - f) * length, true);
    EXPECT_NEAR(left / right, 1.0, 1e-9) << f;
    EXPECT_GT(left, BeamModalMassKg(m, length, 0.5 * length, true));
  }
  // proportional to the mass, and a function of x / L only
  EXPECT_NEAR(BeamModalMassKg(2 * m, length, 0.3 * length, false),
              2 * BeamModalMassKg(m, length, 0.3 * length, false), 1e-12);
  EXPECT_NEAR(BeamModalMassKg(m, 2 * length, 0.6 * length, false),
              BeamModalMassKg(m, length, 0.3 * length, false), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Object geometry

TEST(SceneTest, RodIsOneSegmentOfItsLengthAndRadius) {
  const ObjectConfig rod = Rod(0.032, 0.42);
  const ObjectGeometry g = BuildObjectGeometry(rod, 0);
  ASSERT_EQ(g.segments.size(), 1u);
  EXPECT_EQ(g.segments[0].p0, Eigen::Vector3d::Zero());
  EXPECT_NEAR((g.segments[0].p1 - Eigen::Vector3d(0.42, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(g.segments[0].radius_m, 0.016);
  EXPECT_TRUE(g.segments[0].free_tip);
  EXPECT_EQ(g.targets, std::vector<int>{0});
  EXPECT_TRUE(g.leaves.empty());
  EXPECT_EQ(ObjectVariants(rod), 1);
  EXPECT_EQ(rod.DisplayName(), "rod T32L42");
}

TEST(SceneTest, CrossSecondRodTouchesTheFirstAtItsMiddleAtRightAngles) {
  ObjectConfig cross = Rod(0.022, 0.42);
  cross.kind = ObjectKind::kCross;
  cross.cross.diameter_m = 0.012;
  cross.cross.length_m = 0.50;
  const ObjectGeometry g = BuildObjectGeometry(cross, 0);
  ASSERT_EQ(g.segments.size(), 2u);
  const ObjectSegment &a = g.segments[0], &b = g.segments[1];
  EXPECT_NEAR((a.p1 - a.p0).norm(), 0.42, 1e-15);
  EXPECT_NEAR((b.p1 - b.p0).norm(), 0.50, 1e-15);
  EXPECT_DOUBLE_EQ(a.radius_m, 0.011);
  EXPECT_DOUBLE_EQ(b.radius_m, 0.006);
  // perpendicular, touching: the axes lie r1 + r2 apart
  EXPECT_NEAR((a.p1 - a.p0).normalized().dot((b.p1 - b.p0).normalized()), 0.0, 1e-12);
  EXPECT_NEAR(AxisDistance(a, b), a.radius_m + b.radius_m, 1e-12);
  // at the first rod's middle, and the second rod's middle on the common normal
  const Eigen::Vector3d mid_b = 0.5 * (b.p0 + b.p1);
  const Eigen::Vector3d dir_a = (a.p1 - a.p0).normalized();
  EXPECT_NEAR((mid_b - a.p0).dot(dir_a), 0.21, 1e-12);
  EXPECT_NEAR((mid_b - a.p0 - (mid_b - a.p0).dot(dir_a) * dir_a).norm(), 0.017, 1e-12);
  // behind the first rod (+y) as the header says
  EXPECT_GT(mid_b.y(), 0.0);
  EXPECT_EQ(g.targets, std::vector<int>{0});
  EXPECT_EQ(cross.DisplayName(), "cross T22L42+T12L50");
}

TEST(SceneTest, BranchForksByLeonardoFromParentEnds) {
  ObjectConfig tree = Rod(0.025, 0.30);
  tree.kind = ObjectKind::kBranch;
  BranchConfig& b = tree.branch;
  for (const auto& [levels, forks] :
       {std::pair{2, 2}, std::pair{3, 3}, std::pair{0, 2}, std::pair{1, 4}}) {
    b.levels = levels;
    b.forks = forks;
    b.fork_angle_deg = 35;
    b.length_ratio = 0.8;
    b.min_target_diameter_m = 0.0;
    const ObjectGeometry g = BuildObjectGeometry(tree, 1);
    SCOPED_TRACE(testing::Message() << "levels " << levels << " forks " << forks);
    // sum_{k=0..L} F^k segments, generation by generation
    size_t expected = 0, generation = 1;
    std::vector<size_t> starts;
    for (int k = 0; k <= levels; ++k) {
      starts.push_back(expected);
      expected += generation;
      generation *= static_cast<size_t>(forks);
    }
    starts.push_back(expected);
    ASSERT_EQ(g.segments.size(), expected);
    EXPECT_EQ(g.segments[0].p0, Eigen::Vector3d::Zero());
    EXPECT_NEAR((g.segments[0].p1 - Eigen::Vector3d(0.30, 0, 0)).norm(), 0.0, 1e-15);
    EXPECT_DOUBLE_EQ(g.segments[0].radius_m, 0.0125);
    for (int k = 1; k <= levels; ++k) {
      for (size_t i = starts[k]; i < starts[k + 1]; ++i) {
        const ObjectSegment& child = g.segments[i];
        const ObjectSegment& parent =
            g.segments[starts[k - 1] + (i - starts[k]) / static_cast<size_t>(forks)];
        // children start at their parent's end
        EXPECT_EQ(child.p0, parent.p1) << "segment " << i;
        // Leonardo: r_child = r_parent / sqrt(F), so F r_child^2 = r_parent^2
        EXPECT_NEAR(child.radius_m, parent.radius_m / std::sqrt(static_cast<double>(forks)), 1e-15);
        // fork angle and length ratio within their +-20 % jitter
        const Eigen::Vector3d pa = parent.p1 - parent.p0, ca = child.p1 - child.p0;
        const double angle = std::acos(std::clamp(pa.normalized().dot(ca.normalized()), -1.0, 1.0));
        EXPECT_GE(angle, 0.8 * 35 * kDeg - 1e-9);
        EXPECT_LE(angle, 1.2 * 35 * kDeg + 1e-9);
        EXPECT_GE(ca.norm() / pa.norm(), 0.8 * 0.8 - 1e-12);
        EXPECT_LE(ca.norm() / pa.norm(), 1.2 * 0.8 + 1e-12);
      }
    }
    // free tips: exactly the last generation
    for (size_t i = 0; i < g.segments.size(); ++i) {
      EXPECT_EQ(g.segments[i].free_tip, i >= starts[levels]) << "segment " << i;
    }
    EXPECT_EQ(g.targets.size(), g.segments.size());  // no minimum diameter
    EXPECT_TRUE(g.leaves.empty());                   // no leaf radius
  }
}

TEST(SceneTest, BranchShapeFollowsSeedAndVariant) {
  ObjectConfig tree = Rod(0.025, 0.30);
  tree.kind = ObjectKind::kBranch;
  tree.branch.levels = 3;
  tree.branch.forks = 2;
  tree.branch.variants = 4;
  tree.branch.shape_seed = 7;
  tree.branch.min_target_diameter_m = 0.01;
  EXPECT_EQ(ObjectVariants(tree), 4);
  auto same = [](const ObjectGeometry& a, const ObjectGeometry& b) {
    if (a.segments.size() != b.segments.size() || a.leaves.size() != b.leaves.size()) return false;
    for (size_t i = 0; i < a.segments.size(); ++i) {
      if (a.segments[i].p0 != b.segments[i].p0 || a.segments[i].p1 != b.segments[i].p1 ||
          a.segments[i].radius_m != b.segments[i].radius_m) {
        return false;
      }
    }
    for (size_t i = 0; i < a.leaves.size(); ++i) {
      if (a.leaves[i] != b.leaves[i]) return false;
    }
    return a.targets == b.targets;
  };
  tree.branch.leaf_cluster_radius_m = 0.05;
  const ObjectGeometry g2 = BuildObjectGeometry(tree, 2);
  EXPECT_TRUE(same(g2, BuildObjectGeometry(tree, 2)));
  EXPECT_FALSE(same(g2, BuildObjectGeometry(tree, 3)));
  ObjectConfig other = tree;
  other.branch.shape_seed = 8;
  EXPECT_FALSE(same(g2, BuildObjectGeometry(other, 2)));
  // targets: segments at least min_target_diameter_m thick (r 12.5, 8.8, 6.25, 4.4 mm)
  std::vector<int> thick;
  for (size_t i = 0; i < g2.segments.size(); ++i) {
    if (2 * g2.segments[i].radius_m >= 0.01) thick.push_back(static_cast<int>(i));
  }
  EXPECT_EQ(g2.targets, thick);
  EXPECT_EQ(g2.targets.size(), 7u);  // trunk, 2 children, 4 grandchildren
}

TEST(SceneTest, LeafClustersSitAlongEveryTip) {
  ObjectConfig tree = Rod(0.025, 0.30);
  tree.kind = ObjectKind::kBranch;
  tree.branch.levels = 2;
  tree.branch.forks = 3;
  for (const int64_t per_tip : {1, 3}) {
    tree.branch.leaf_clusters_per_tip = per_tip;
    tree.branch.leaf_cluster_radius_m = 0.04;
    const ObjectGeometry g = BuildObjectGeometry(tree, 0);
    std::vector<const ObjectSegment*> tips;
    for (const ObjectSegment& s : g.segments) {
      if (s.free_tip) tips.push_back(&s);
    }
    ASSERT_EQ(tips.size(), 9u);
    ASSERT_EQ(g.leaves.size(), tips.size() * static_cast<size_t>(per_tip));
    for (size_t t = 0; t < tips.size(); ++t) {
      for (int64_t k = 0; k < per_tip; ++k) {
        const Eigen::Vector4d& leaf = g.leaves[t * per_tip + k];
        EXPECT_EQ(leaf[3], 0.04);
        // spread along the tip segment, the last at its tip, within one radius of its spot
        const double f = static_cast<double>(k + 1) / static_cast<double>(per_tip);
        const Eigen::Vector3d spot = tips[t]->p0 + f * (tips[t]->p1 - tips[t]->p0);
        EXPECT_LE((leaf.head<3>() - spot).norm(), 0.04 + 1e-12);
      }
    }
    // no radius, no leaves (and the same branches)
    tree.branch.leaf_cluster_radius_m = 0.0;
    const ObjectGeometry bare = BuildObjectGeometry(tree, 0);
    EXPECT_TRUE(bare.leaves.empty());
    ASSERT_EQ(bare.segments.size(), g.segments.size());
    for (size_t i = 0; i < g.segments.size(); ++i) EXPECT_EQ(bare.segments[i].p1, g.segments[i].p1);
  }
}

// ---------------------------------------------------------------------------------------------
// Object draws and validation

TEST(SceneTest, DrawObjectIndexFollowsTheWeights) {
  std::vector<ObjectConfig> objects(3);
  objects[0].weight = 1;
  objects[1].weight = 0;
  objects[2].weight = 3;
  std::array<int, 3> counts{};
  constexpr int kDraws = 40000;
  Rng rng(12345);
  for (int i = 0; i < kDraws; ++i) {
    // a regular grid of u and random u
    ++counts[DrawObjectIndex(objects, (i + 0.5) / kDraws)];
    ++counts[DrawObjectIndex(objects, rng.Uniform())];
  }
  EXPECT_NEAR(counts[0] / (2.0 * kDraws), 0.25, 0.01);
  EXPECT_EQ(counts[1], 0);
  EXPECT_NEAR(counts[2] / (2.0 * kDraws), 0.75, 0.01);
  // the ends of [0, 1): a zero-weight object is never drawn, not even last or first
  const double below_one = std::nextafter(1.0, 0.0);
  EXPECT_EQ(DrawObjectIndex(objects, 0.0), 0);
  EXPECT_EQ(DrawObjectIndex(objects, below_one), 2);
  objects = std::vector<ObjectConfig>(4);
  const std::vector<double> weights = {0.0, 0.1, 0.7, 0.0};
  for (size_t i = 0; i < weights.size(); ++i) objects[i].weight = weights[i];
  for (const double u : {0.0, 1e-300, 0.125, 0.1249999999, 0.5, 0.99, below_one}) {
    const int index = DrawObjectIndex(objects, u);
    EXPECT_GT(objects[static_cast<size_t>(index)].weight, 0.0) << "u = " << u;
  }
  EXPECT_EQ(DrawObjectIndex(objects, 0.0), 1);
  EXPECT_EQ(DrawObjectIndex(objects, below_one), 2);
}

TEST(SceneTest, ValidateNamesTheOffendingKey) {
  SceneConfig scene;
  EXPECT_NO_THROW(scene.Validate());
  // no objects
  scene.objects.clear();
  ExpectConfigError([&] { scene.Validate(); }, {"scene.objects"});
  // a striker in mode strike (and guided)
  scene.objects = {Rod(0.022, 0.42), Rod(0.022, 0.42)};
  scene.objects[1].kind = ObjectKind::kStriker;
  for (const SceneMode mode : {SceneMode::kStrike, SceneMode::kGuided}) {
    scene.mode = mode;
    ExpectConfigError([&] { scene.Validate(); }, {"scene.objects.1", "striker"});
  }
  // a rod in mode stationary
  scene.mode = SceneMode::kStationary;
  scene.objects = MaterialStrikers();
  EXPECT_NO_THROW(scene.Validate());
  scene.objects[1].kind = ObjectKind::kRod;
  ExpectConfigError([&] { scene.Validate(); }, {"scene.objects.1", "stationary"});
  // a wall as thick as the radius (and thicker)
  scene = SceneConfig{};
  scene.objects = {Rod(0.022, 0.42), Rod(0.022, 0.42)};
  for (const double wall_m : {0.011, 0.02}) {
    scene.objects[1].wall_thickness_m = wall_m;
    ExpectConfigError([&] { scene.Validate(); }, {"scene.objects.1.wall_thickness_m"});
  }
  scene.objects[1].wall_thickness_m = 0.0109;
  EXPECT_NO_THROW(scene.Validate());
  // weights: negative, or all zero
  scene.objects[1].weight = -1;
  ExpectConfigError([&] { scene.Validate(); }, {"scene.objects.1.weight"});
  scene.objects[0].weight = scene.objects[1].weight = 0;
  ExpectConfigError([&] { scene.Validate(); }, {"scene.objects", "weights"});
  // a branch with no segment thick enough to aim at
  scene = SceneConfig{};
  scene.objects[0].kind = ObjectKind::kBranch;
  scene.objects[0].branch.min_target_diameter_m = 0.03;
  ExpectConfigError([&] { scene.Validate(); }, {"scene.objects.0.branch.min_target_diameter_m"});
  // the rollouts refuse the mode they do not simulate
  scene = SceneConfig{};
  scene.mode = SceneMode::kStationary;
  scene.objects = MaterialStrikers();
  ExpectConfigError(
      [&] { StrikeRollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{}); },
      {"stationary"});
  ExpectConfigError(
      [&] {
        HandStrikeRollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, SceneConfig{},
                          RolloutConfig{});
      },
      {"stationary"});
}

// ---------------------------------------------------------------------------------------------
// Rollouts, mode strike

TEST(SceneRolloutTest, TwoRodsAreBothDrawnAndNamedInTheirContacts) {
  const TubeConfig tube;
  SceneConfig scene;
  scene.objects = {Rod(0.012, 0.42), Rod(0.032, 0.42)};
  const std::vector<std::string> names = {"rod T12L42", "rod T32L42"};
  const StrikeRollout rollout(tube, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{});
  constexpr int kCount = 12;
  std::vector<RolloutResult> serial(kCount);
  for (int i = 0; i < kCount; ++i) serial[i] = rollout.Run(i, SampleSeed(31, i));
  PrintReasons("two rods", serial);
  std::set<int> drawn, struck;
  int valid = 0;
  for (const RolloutResult& r : serial) {
    ASSERT_GE(r.object, 0);
    ASSERT_LT(r.object, 2);
    drawn.insert(r.object);
    const ObjectConfig& rod = scene.objects[static_cast<size_t>(r.object)];
    for (const ContactRecord& c : r.contacts) {
      EXPECT_EQ(c.object, names[static_cast<size_t>(r.object)]);
      EXPECT_EQ(c.material, "wood");
      EXPECT_EQ(c.segment, 0);
      EXPECT_DOUBLE_EQ(c.segment_radius_m, 0.5 * rod.diameter_m);
    }
    if (!r.valid) continue;
    ++valid;
    struck.insert(r.object);
    ASSERT_FALSE(r.contacts.empty());
    const ContactRecord& first = r.contacts.front();
    EXPECT_EQ(first.kind, ContactEpisode::Kind::kImpact);
    EXPECT_LT(std::abs(std::hypot(first.point_m.x(), first.point_m.y()) - tube.outer_radius_m),
              1e-3);
    EXPECT_GE(first.z_m, tube.contact_z_min_m);
    EXPECT_LE(first.z_m, tube.contact_z_max_m);
    EXPECT_LT(std::abs(first.z_m - r.target_z_m), 0.01);
    // in the rod's frame: on its surface, 5 cm from its free tip
    const Eigen::Vector3d p = r.object_pose.inverse() * first.point_world_m;
    EXPECT_NEAR(p.x(), rod.length_m - 0.05, 0.01);
    EXPECT_NEAR(std::hypot(p.y(), p.z()), 0.5 * rod.diameter_m, 1e-3);
    // the arm in series with the rod's modal mass there: lighter than either
    const double rod_kg = rod.LinearDensityKgM() * rod.length_m;
    EXPECT_GT(first.effective_mass_kg, 0.0);
    EXPECT_LT(first.effective_mass_kg, BeamModalMassKg(rod_kg, rod.length_m, p.x(), false));
  }
  EXPECT_EQ(drawn, (std::set<int>{0, 1}));
  EXPECT_EQ(struck, (std::set<int>{0, 1}));
  EXPECT_GE(valid, static_cast<int>(0.75 * kCount));
  // the same records from two threads
  constexpr int kThreaded = 6;
  std::vector<RolloutResult> parallel(kThreaded);
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      for (int i = t; i < kThreaded; i += 2) parallel[i] = rollout.Run(i, SampleSeed(31, i));
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (int i = 0; i < kThreaded; ++i) {
    SCOPED_TRACE(testing::Message() << "sample " << i);
    ExpectSameRecords(serial[i], parallel[i]);
  }
}

TEST(SceneRolloutTest, LateralStrikesSweepJointSix) {
  StrikeConfig strike;
  strike.motions = {"lateral"};
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, strike, SceneConfig{}, RolloutConfig{});
  constexpr int kCount = 8;
  std::vector<RolloutResult> results;
  int impacts = 0;
  for (int i = 0; i < kCount; ++i) {
    results.push_back(rollout.Run(i, SampleSeed(41, i)));
    const RolloutResult& r = results.back();
    EXPECT_EQ(r.motion, "lateral");
    if (r.valid && !r.contacts.empty() &&
        r.contacts.front().kind == ContactEpisode::Kind::kImpact &&
        r.contacts.front().normal_speed_m_s > 1e-3) {
      ++impacts;
    }
  }
  PrintReasons("lateral", results);
  EXPECT_GE(impacts, 6) << "of " << kCount;
}

TEST(SceneRolloutTest, CrossIsStruckOnItsFirstRod) {
  SceneConfig scene;
  ObjectConfig cross = Rod(0.022, 0.42);
  cross.kind = ObjectKind::kCross;
  cross.cross.diameter_m = 0.012;
  cross.cross.length_m = 0.42;
  scene.objects = {cross};
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{});
  constexpr int kCount = 6;
  std::vector<RolloutResult> results;
  int valid = 0;
  for (int i = 0; i < kCount; ++i) {
    results.push_back(rollout.Run(i, SampleSeed(51, i)));
    const RolloutResult& r = results.back();
    if (!r.valid) continue;
    ++valid;
    const ContactRecord& first = r.contacts.front();
    EXPECT_EQ(first.object.rfind("cross", 0), 0u) << first.object;
    EXPECT_EQ(first.object, "cross T22L42+T12L42");
    EXPECT_EQ(first.segment, 0);  // the struck rod, not the one behind it
    EXPECT_DOUBLE_EQ(first.segment_radius_m, 0.011);
    // struck in the middle 60 % of the first rod, on its surface
    const Eigen::Vector3d p = r.object_pose.inverse() * first.point_world_m;
    EXPECT_GE(p.x(), 0.2 * 0.42 - 0.01);
    EXPECT_LE(p.x(), 0.8 * 0.42 + 0.01);
    EXPECT_NEAR(std::hypot(p.y(), p.z()), 0.011, 1e-3);
    // the second rod lies behind the first (+y): the tube touches the front (-y) face
    EXPECT_NEAR(p.y(), -0.011, 1e-3);
  }
  PrintReasons("cross", results);
  EXPECT_GE(valid, kCount / 2);
}

// ---------------------------------------------------------------------------------------------
// Rollouts, mode stationary

TEST(SceneRolloutTest, HandStrikesHitTheCommandedGridPoints) {
  const TubeConfig tube;
  SceneConfig scene;
  scene.mode = SceneMode::kStationary;
  scene.objects = MaterialStrikers();
  const StationaryConfig& sc = scene.stationary;
  const StrikeConfig strike;
  const HandStrikeRollout rollout(tube, AudioConfig{}, strike, scene, RolloutConfig{});
  constexpr int kCount = 12;
  std::vector<RolloutResult> results;
  std::set<std::string> materials;
  int valid = 0;
  double speed_lo = 1e9, speed_hi = 0.0;
  for (int i = 0; i < kCount; ++i) {
    results.push_back(rollout.Run(i, SampleSeed(61, i)));
    const RolloutResult& r = results.back();
    const ObjectConfig& striker = scene.objects[static_cast<size_t>(r.object)];
    EXPECT_EQ(r.motion, "hand strike");
    // the commanded point on the 2 cm grid
    EXPECT_NEAR(r.target_z_m / sc.z_grid_m, std::round(r.target_z_m / sc.z_grid_m), 1e-9)
        << r.target_z_m;
    EXPECT_GE(r.target_z_m, tube.contact_z_min_m);
    EXPECT_LE(r.target_z_m, tube.contact_z_max_m);
    // held pose at rest: every row the same, zero velocity
    ASSERT_EQ(r.proprio.rows(), strike.proprio_rows);
    for (int k = 0; k < r.proprio.rows(); ++k) {
      EXPECT_TRUE((r.proprio.row(k).array() == r.proprio.row(0).array()).all()) << "row " << k;
    }
    EXPECT_TRUE((r.proprio.rightCols<3>().array() == 0.0f).all());
    EXPECT_NEAR(r.proprio.row(0).segment<4>(3).norm(), 1.0, 1e-6);
    for (const double s : r.joint_speed_rad_s) EXPECT_EQ(s, 0.0);
    if (!r.valid) continue;
    ++valid;
    const ContactRecord& first = r.contacts.front();
    EXPECT_EQ(first.kind, ContactEpisode::Kind::kImpact);
    EXPECT_LT(std::abs(first.z_m - r.target_z_m), 0.01);
    EXPECT_LT(std::abs(std::hypot(first.point_m.x(), first.point_m.y()) - tube.outer_radius_m),
              1e-3);
    EXPECT_LT(std::abs(WrapAngle(first.theta_rad - r.target_theta_rad)), 5 * kDeg);
    EXPECT_GE(first.normal_speed_m_s,
              sc.speed_min_m_s * std::cos(sc.approach_spread_deg * kDeg) / 1.2);
    EXPECT_LE(first.normal_speed_m_s, sc.speed_max_m_s * 1.2);
    speed_lo = std::min(speed_lo, first.normal_speed_m_s);
    speed_hi = std::max(speed_hi, first.normal_speed_m_s);
    // the held arm in series: lighter than the rigid striker alone
    const double striker_kg = striker.LinearDensityKgM() * striker.length_m;
    EXPECT_GT(first.effective_mass_kg, 0.0);
    EXPECT_LT(first.effective_mass_kg, striker_kg);
    EXPECT_GT(first.impulse_Ns, 0.0);
    for (const ContactRecord& c : r.contacts) {
      EXPECT_EQ(c.material, NameOf(striker.material));
      EXPECT_EQ(c.object, striker.DisplayName());
      EXPECT_EQ(c.object.rfind("striker " + std::string(NameOf(striker.material)), 0), 0u)
          << c.object;
      EXPECT_DOUBLE_EQ(c.segment_radius_m, 0.5 * striker.diameter_m);
    }
    materials.insert(std::string(NameOf(striker.material)));
  }
  PrintReasons("hand strikes", results);
  std::cout << "approach speed " << speed_lo << " .. " << speed_hi << " m/s\n";
  EXPECT_GE(valid, static_cast<int>(0.8 * kCount));
  EXPECT_GE(materials.size(), 2u);
  // deterministic in the seed
  ExpectSameRecords(rollout.Run(3, SampleSeed(61, 3)), results[3]);
}

// ---------------------------------------------------------------------------------------------
// Rollouts, mode guided

TEST(SceneRolloutTest, GuidedTapsAroundTheCanopyBrushLeavesAndHitBranches) {
  const SceneConfig scene = Ts3Scene();
  StrikeConfig strike;
  strike.sweep_duration_s = 1.0;
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, strike, scene, RolloutConfig{});
  const std::vector<Eigen::Vector3d> points = rollout.GuidedPoints();
  ASSERT_FALSE(points.empty());
  std::cout << points.size() << " guided points\n";
  for (const Eigen::Vector3d& p : points) {
    EXPECT_EQ(p.z(), scene.guided.plane_z_m);
    EXPECT_GE(p.x(), scene.guided.x_range_m[0] - 1e-12);
    EXPECT_LE(p.x(), scene.guided.x_range_m[1] + 1e-12);
    EXPECT_GE(p.y(), scene.guided.y_range_m[0] - 1e-12);
    EXPECT_LE(p.y(), scene.guided.y_range_m[1] + 1e-12);
  }
  const uint64_t n = points.size();
  const uint64_t first = n >= 5 ? 4 * (n - 5) : 0;
  std::vector<RolloutResult> results;
  int brushes = 0, hard = 0;
  for (uint64_t i = first; i < 4 * n && i < first + 20; ++i) {
    results.push_back(rollout.Run(i, SampleSeed(71, i)));
    const RolloutResult& r = results.back();
    // sample i: point i / 4, tap i % 4 (j1+, j1-, j6+, j6-)
    const char* taps[] = {"tap j1+", "tap j1-", "tap j6+", "tap j6-"};
    EXPECT_EQ(r.motion, taps[i % 4]);
    EXPECT_EQ(r.object, 0);
    // the object stands where scene.guided puts it
    EXPECT_NEAR((r.object_pose.translation() - Eigen::Vector3d(-0.40, 0.40, 0.31)).norm(), 0.0,
                1e-12);
    EXPECT_TRUE(r.object_pose.linear().isIdentity(1e-12));
    bool brushed = false;
    for (const ContactRecord& c : r.contacts) {
      if (c.kind != ContactEpisode::Kind::kBrush) continue;
      brushed = true;
      EXPECT_EQ(c.object, "leaves");
      EXPECT_EQ(c.segment, -1);
      EXPECT_EQ(c.impulse_Ns, 0.0);
      EXPECT_EQ(c.peak_force_N, 0.0);
      EXPECT_EQ(c.effective_mass_kg, 0.0);
      EXPECT_EQ(c.material, "foliage");
      // the tube point nearest the cluster: on the surface, within the tube
      EXPECT_NEAR(std::hypot(c.point_m.x(), c.point_m.y()), TubeConfig{}.outer_radius_m, 1e-12);
      EXPECT_LE(std::abs(c.z_m), 0.5 * TubeConfig{}.length_m + 1e-12);
      EXPECT_GE(c.duration_s, 0.0);
    }
    brushes += brushed ? 1 : 0;
    const ContactRecord* c = FirstHard(r);
    if (r.valid && c != nullptr) {
      ++hard;
      EXPECT_EQ(c->object.rfind("branch", 0), 0u) << c->object;
      EXPECT_GT(c->impulse_Ns, 0.0);
    }
  }
  PrintReasons("guided", results);
  std::cout << "brushed " << brushes << ", hard " << hard << "\n";
  EXPECT_GE(brushes, 1);
  EXPECT_GE(hard, 1);
  // a sample index names its point and tap: the same rollout twice
  ExpectSameRecords(rollout.Run(first + 1, SampleSeed(71, first + 1)), results[1]);
}

// ---------------------------------------------------------------------------------------------
// Failures

TEST(SceneRolloutTest, ObjectOverlappingTheArmAtTheStartIsInvalid) {
  // guided: a long rod through the robot's base, far below the tube's plane
  SceneConfig scene;
  scene.mode = SceneMode::kGuided;
  scene.objects = {Rod(0.02, 2.0)};
  scene.guided.object_position_m = {-1.0, 0.0, 0.03};
  scene.guided.layer_m = 1.0;
  const StrikeRollout rollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{});
  const RolloutResult r = rollout.Run(0, SampleSeed(81, 0));
  EXPECT_FALSE(r.valid);
  EXPECT_NE(r.invalid_reason.find("overlaps"), std::string::npos) << r.invalid_reason;
  EXPECT_NE(r.invalid_reason.find("panda_link0"), std::string::npos) << r.invalid_reason;
  EXPECT_TRUE(r.proprio.allFinite());
  // guided without clearance: the tube starts inside the object
  scene = Ts3Scene();
  scene.objects[0].branch.leaf_cluster_radius_m = 0.0;
  scene.guided.clearance_m = 0.0;
  scene.guided.layer_m = 0.02;
  const StrikeRollout inside(TubeConfig{}, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{});
  const RolloutResult t = inside.Run(2, SampleSeed(81, 2));
  EXPECT_FALSE(t.valid);
  EXPECT_NE(t.invalid_reason.find("overlaps tube at the start"), std::string::npos)
      << t.invalid_reason;
}

TEST(SceneRolloutTest, GuidedWithoutFeasiblePointIsAConfigError) {
  SceneConfig scene = Ts3Scene();
  scene.guided.clearance_m = 10.0;
  ExpectConfigError(
      [&] { StrikeRollout(TubeConfig{}, AudioConfig{}, StrikeConfig{}, scene, RolloutConfig{}); },
      {"scene.guided", "clearance_m"});
  // an object position without three entries
  scene = Ts3Scene();
  scene.guided.object_position_m = {0.0, 0.4};
  ExpectConfigError([&] { scene.Validate(); }, {"scene.guided.object_position_m"});
}

}  // namespace
}  // namespace sonicboom::sim
