#include "sonicboom/core/constants.h"
#include "sonicboom/sim/scene.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <numbers>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::sim {
namespace {

// fundamental roots (docs/physics.md, "Beam modes"): cantilever cos cosh = -1, clamped-clamped 1
constexpr double kCantileverBetaL = 1.875104068711961;
constexpr double kClampedBetaL = 4.730040744862704;

std::string PaperName(double diameter_m, double length_m) {
  return fmt::format("T{:.0f}L{:.0f}", diameter_m * 1e3, length_m * 1e2);
}

void Require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError(message);
}

// A unit vector perpendicular to `axis`.
Eigen::Vector3d AnyPerpendicular(const Eigen::Vector3d& axis) {
  const Eigen::Vector3d helper =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return axis.cross(helper).normalized();
}

// Fundamental mode shape of a clamped-free or clamped-clamped beam at xi = x / L, unnormalised.
double BeamMode(double xi, bool clamped_both_ends) {
  const double bl = clamped_both_ends ? kClampedBetaL : kCantileverBetaL;
  const double sigma = clamped_both_ends
                           ? (std::cosh(bl) - std::cos(bl)) / (std::sinh(bl) - std::sin(bl))
                           : (std::cosh(bl) + std::cos(bl)) / (std::sinh(bl) + std::sin(bl));
  const double b = bl * xi;
  return std::cosh(b) - std::cos(b) - sigma * (std::sinh(b) - std::sin(b));
}

}  // namespace

void CrossConfig::Serialize(Archive* a) {
  a->Visit("diameter_m", &diameter_m, Bounds::Open(0.0, 0.5));
  a->Visit("length_m", &length_m, Bounds::Open(0.0, 5.0));
}

void BranchConfig::Serialize(Archive* a) {
  a->Visit("levels", &levels, Bounds::Closed(0, 5));
  a->Visit("forks", &forks, Bounds::Closed(1, 4));
  a->Visit("fork_angle_deg", &fork_angle_deg, Bounds::Closed(0.0, 90.0));
  a->Visit("length_ratio", &length_ratio, Bounds::Open(0.0, 1.5));
  a->Visit("variants", &variants, Bounds::Closed(1, 64));
  a->Visit("shape_seed", &shape_seed, Bounds::NonNegative());
  a->Visit("min_target_diameter_m", &min_target_diameter_m, Bounds::NonNegative());
  a->Visit("leaf_cluster_radius_m", &leaf_cluster_radius_m, Bounds::Closed(0.0, 0.5));
  a->Visit("leaf_clusters_per_tip", &leaf_clusters_per_tip, Bounds::Closed(0, 8));
}

void ObjectConfig::Serialize(Archive* a) {
  // kind first: the kind-specific groups below exist only for their kind
  a->Visit("kind", &kind);
  a->Visit("name", &name);
  a->Visit("weight", &weight, Bounds::NonNegative());
  a->Visit("diameter_m", &diameter_m, Bounds::Open(0.0, 0.5));
  a->Visit("length_m", &length_m, Bounds::Open(0.0, 5.0));
  a->Visit("wall_thickness_m", &wall_thickness_m, Bounds::NonNegative());
  if (kind == ObjectKind::kRod || kind == ObjectKind::kCross) a->Visit("clamp", &clamp);
  a->Visit("material", &material);
  a->Visit("youngs_modulus_pa", &elastic.youngs_modulus_pa, Bounds::Open(1e6, 1e13));
  a->Visit("contact_youngs_modulus_pa", &contact_youngs_modulus_pa, Bounds::Open(1e6, 1e13));
  a->Visit("poisson_ratio", &elastic.poisson_ratio, Bounds::Open(-1.0, 0.5));
  a->Visit("density_kg_m3", &elastic.density_kg_m3, Bounds::Open(1.0, 1e5));
  a->Visit("loss_factor", &elastic.loss_factor, Bounds::Open(0.0, 1.0));
  if (kind == ObjectKind::kCross) a->Visit("cross", &cross);
  if (kind == ObjectKind::kBranch) a->Visit("branch", &branch);
}

void ObjectConfig::Validate(const std::string& key) const {
  Require(wall_thickness_m < 0.5 * diameter_m,
          fmt::format("{}.wall_thickness_m = {} must be below half of diameter_m = {} (0 = solid)",
                      key, wall_thickness_m, diameter_m));
  Require(std::isfinite(weight) && weight >= 0.0,
          fmt::format("{}.weight = {} must be non-negative", key, weight));
  if (kind == ObjectKind::kBranch) {
    Require(branch.min_target_diameter_m <= diameter_m,
            fmt::format("{}.branch.min_target_diameter_m = {} exceeds the trunk diameter_m = {}: "
                        "no segment could be aimed at",
                        key, branch.min_target_diameter_m, diameter_m));
  }
}

std::string ObjectConfig::DisplayName() const {
  if (!name.empty()) return name;
  const std::string dims = PaperName(diameter_m, length_m);
  if (kind == ObjectKind::kCross)
    return fmt::format("cross {}+{}", dims, PaperName(cross.diameter_m, cross.length_m));
  if (kind == ObjectKind::kStriker) return fmt::format("striker {} {}", NameOf(material), dims);
  return fmt::format("{} {}", NameOf(kind), dims);
}

double ObjectConfig::LinearDensityKgM() const {
  const double r_out = 0.5 * diameter_m;
  const double r_in = wall_thickness_m > 0.0 ? r_out - wall_thickness_m : 0.0;
  return elastic.density_kg_m3 * kPi * (r_out * r_out - r_in * r_in);
}

void StationaryConfig::Serialize(Archive* a) {
  a->Visit("speed_min_m_s", &speed_min_m_s, Bounds::Open(0.0, 20.0));
  a->Visit("speed_max_m_s", &speed_max_m_s, Bounds::Open(0.0, 20.0));
  a->Visit("z_grid_m", &z_grid_m, Bounds::Closed(0.0, 0.2));
  a->Visit("approach_spread_deg", &approach_spread_deg, Bounds::Closed(0.0, 60.0));
  a->Visit("hand_stiffness_n_m", &hand_stiffness_n_m, Bounds::Open(0.0, 1e7));
  a->Visit("hand_damping_ratio", &hand_damping_ratio, Bounds::Closed(0.0, 10.0));
  a->Visit("follow_through_m", &follow_through_m, Bounds::Closed(0.0, 0.05));
  a->Visit("tip_margin_m", &tip_margin_m, Bounds::Closed(0.0, 1.0));
  a->Visit("approach_s", &approach_s, Bounds::Open(0.0, 1.0));
}

void StationaryConfig::Validate() const {
  Require(speed_min_m_s <= speed_max_m_s,
          fmt::format("scene.stationary.speed_min_m_s = {} exceeds speed_max_m_s = {}",
                      speed_min_m_s, speed_max_m_s));
}

void GuidedConfig::Serialize(Archive* a) {
  a->Visit("object_position_m", &object_position_m);
  a->Visit("object_yaw_deg", &object_yaw_deg, Bounds::Closed(-360.0, 360.0));
  a->Visit("plane_z_m", &plane_z_m);
  a->Visit("x_range_m", &x_range_m);
  a->Visit("y_range_m", &y_range_m);
  a->Visit("grid_points", &grid_points, Bounds::Closed(1, 1000000));
  a->Visit("clearance_m", &clearance_m, Bounds::NonNegative());
  a->Visit("layer_m", &layer_m, Bounds::Positive());
  a->Visit("joint7_rad", &joint7_rad);
  a->Visit("tap_deg", &tap_deg, Bounds::Open(0.0, 90.0));
  a->Visit("amplitude_threshold", &amplitude_threshold, Bounds::Closed(0.0, 1.0));
}

void GuidedConfig::Validate() const {
  Require(object_position_m.size() == 3,
          fmt::format("scene.guided.object_position_m needs 3 entries, got {}",
                      object_position_m.size()));
  for (const auto& [key, range] :
       {std::pair{"x_range_m", &x_range_m}, std::pair{"y_range_m", &y_range_m}}) {
    Require(range->size() == 2 && (*range)[0] <= (*range)[1],
            fmt::format("scene.guided.{} must be [min, max] with min <= max", key));
  }
}

void SceneConfig::Serialize(Archive* a) {
  a->Visit("mode", &mode);
  a->VisitList("objects", &objects);
  a->Visit("stationary", &stationary);
  a->Visit("guided", &guided);
}

void SceneConfig::Validate() const {
  Require(!objects.empty(), "scene.objects is empty: a scene needs at least one object");
  double total_weight = 0.0;
  for (size_t i = 0; i < objects.size(); ++i) {
    const ObjectConfig& o = objects[i];
    const std::string key = fmt::format("scene.objects.{}", i);
    o.Validate(key);
    total_weight += o.weight;
    // the mode decides which kinds make sense
    const bool striker = o.kind == ObjectKind::kStriker;
    if (mode == SceneMode::kStationary) {
      Require(striker, fmt::format("{}.kind = {}: scene.mode stationary needs hand-held strikers "
                                   "(kind striker)",
                                   key, NameOf(o.kind)));
    } else {
      Require(!striker, fmt::format("{}.kind = striker needs scene.mode stationary (mode is {})",
                                    key, NameOf(mode)));
    }
  }
  Require(total_weight > 0.0, "scene.objects: the weights sum to zero");
  stationary.Validate();
  guided.Validate();
}

Eigen::Isometry3d GuidedObjectPose(const GuidedConfig& guided) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(guided.object_position_m[0], guided.object_position_m[1],
                                       guided.object_position_m[2]);
  pose.linear() =
      Eigen::AngleAxisd(guided.object_yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return pose;
}

std::vector<ObjectSegment> GuidedSegmentsInBase(const SceneConfig& scene) {
  if (scene.mode != SceneMode::kGuided || scene.objects.empty()) return {};
  const Eigen::Isometry3d pose = GuidedObjectPose(scene.guided);
  std::vector<ObjectSegment> segments = BuildObjectGeometry(scene.objects.front(), 0).segments;
  for (ObjectSegment& s : segments) {
    s.p0 = pose * s.p0;
    s.p1 = pose * s.p1;
  }
  return segments;
}

int64_t ObjectVariants(const ObjectConfig& object) {
  return object.kind == ObjectKind::kBranch ? object.branch.variants : 1;
}

int DrawObjectIndex(const std::vector<ObjectConfig>& objects, double u) {
  SONICBOOM_DEMAND(!objects.empty());
  double total = 0.0;
  for (const ObjectConfig& o : objects) total += o.weight;
  double acc = 0.0;
  for (size_t i = 0; i < objects.size(); ++i) {
    acc += objects[i].weight;
    if (u * total < acc) return static_cast<int>(i);
  }
  // u * total rounding up to total: the last object with a weight
  for (size_t i = objects.size(); i-- > 0;) {
    if (objects[i].weight > 0.0) return static_cast<int>(i);
  }
  return 0;
}

double BeamModalMassKg(double mass_kg, double length_m, double x_m, bool clamped_both_ends) {
  // normalisation (1/L) integral(phi^2) by Simpson's rule on 400 intervals
  constexpr int kIntervals = 400;
  double sum = 0.0;
  for (int k = 0; k <= kIntervals; ++k) {
    const double phi = BeamMode(static_cast<double>(k) / kIntervals, clamped_both_ends);
    const double w = (k == 0 || k == kIntervals) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
    sum += w * phi * phi;
  }
  const double mean_sq = sum / (3.0 * kIntervals);
  const double phi_x = BeamMode(std::clamp(x_m / length_m, 0.0, 1.0), clamped_both_ends);
  if (phi_x * phi_x < 1e-12 * mean_sq) return std::numeric_limits<double>::infinity();
  return mass_kg * mean_sq / (phi_x * phi_x);
}

void DescribeStruckBeam(const ObjectConfig& object, double contact_from_clamp_m,
                        ContactEvent* event) {
  if (object.kind != ObjectKind::kRod && object.kind != ObjectKind::kCross) return;
  // second moment of a solid rod or a pipe: pi (r_out^4 - r_in^4) / 4
  const double r_out = 0.5 * object.diameter_m;
  const double r_in = object.wall_thickness_m > 0.0 ? r_out - object.wall_thickness_m : 0.0;
  const double second_moment_m4 = 0.25 * kPi * (std::pow(r_out, 4) - std::pow(r_in, 4));
  event->beam_length_m = object.length_m;
  event->beam_contact_from_clamp_m =
      std::clamp(contact_from_clamp_m, 1e-3 * object.length_m, object.length_m);
  event->beam_flexural_rigidity_n_m2 = object.elastic.youngs_modulus_pa * second_moment_m4;
  event->beam_linear_density_kg_m = object.LinearDensityKgM();
  event->beam_clamped_both_ends = object.clamp == Clamp::kBothEnds;
  event->beam_loss_factor = object.elastic.loss_factor;
}

ObjectGeometry BuildObjectGeometry(const ObjectConfig& o, int64_t variant) {
  ObjectGeometry g;
  const double radius_m = 0.5 * o.diameter_m;
  const Eigen::Vector3d x_axis = Eigen::Vector3d::UnitX();
  if (o.kind == ObjectKind::kRod || o.kind == ObjectKind::kStriker) {
    g.segments.push_back({Eigen::Vector3d::Zero(), o.length_m * x_axis, radius_m, true});
    g.targets = {0};
    return g;
  }
  if (o.kind == ObjectKind::kCross) {
    // struck rod along x; the second rod behind it (+y, touching) at its middle, along z
    g.segments.push_back({Eigen::Vector3d::Zero(), o.length_m * x_axis, radius_m, true});
    const double r2_m = 0.5 * o.cross.diameter_m;
    const Eigen::Vector3d mid(0.5 * o.length_m, radius_m + r2_m, 0.0);
    const Eigen::Vector3d half(0.0, 0.0, 0.5 * o.cross.length_m);
    g.segments.push_back({mid - half, mid + half, r2_m, true});
    g.targets = {0};
    return g;
  }
  SONICBOOM_DEMAND(o.kind == ObjectKind::kBranch);
  // trunk along x from the origin; every fork turns its children off the parent axis by the fork
  // angle at evenly spaced azimuths (random start), with +-20 % jitter of angle and length
  const BranchConfig& b = o.branch;
  Rng rng(SampleSeed(static_cast<uint64_t>(b.shape_seed), static_cast<uint64_t>(variant)),
          Stream::kScene);
  g.segments.push_back({Eigen::Vector3d::Zero(), o.length_m * x_axis, radius_m, true});
  std::vector<int> generation = {0};
  for (int64_t level = 0; level < b.levels; ++level) {
    std::vector<int> next;
    for (int parent : generation) {
      g.segments[parent].free_tip = false;
      const ObjectSegment p = g.segments[parent];
      const Eigen::Vector3d axis = (p.p1 - p.p0).normalized();
      const Eigen::Vector3d u = AnyPerpendicular(axis), v = axis.cross(u);
      const double parent_length_m = (p.p1 - p.p0).norm();
      const double azimuth0 = rng.Uniform(0.0, 2.0 * kPi);
      const double child_radius_m = p.radius_m / std::sqrt(static_cast<double>(b.forks));
      for (int64_t k = 0; k < b.forks; ++k) {
        const double azimuth = azimuth0 + 2.0 * kPi * static_cast<double>(k) / b.forks;
        const double angle = b.fork_angle_deg * kDeg * rng.Uniform(0.8, 1.2);
        const double length_m = parent_length_m * b.length_ratio * rng.Uniform(0.8, 1.2);
        const Eigen::Vector3d side = std::cos(azimuth) * u + std::sin(azimuth) * v;
        const Eigen::Vector3d dir = std::cos(angle) * axis + std::sin(angle) * side;
        g.segments.push_back({p.p1, p.p1 + length_m * dir, child_radius_m, true});
        next.push_back(static_cast<int>(g.segments.size()) - 1);
      }
    }
    generation = next;
  }
  for (size_t s = 0; s < g.segments.size(); ++s) {
    if (2.0 * g.segments[s].radius_m >= b.min_target_diameter_m)
      g.targets.push_back(static_cast<int>(s));
  }
  // foliage clusters spread along every terminal segment, the last one at its tip, each off the
  // axis by up to one cluster radius
  if (b.leaf_cluster_radius_m > 0.0) {
    for (const ObjectSegment& s : g.segments) {
      if (!s.free_tip) continue;
      for (int64_t k = 0; k < b.leaf_clusters_per_tip; ++k) {
        const double t = static_cast<double>(k + 1) / static_cast<double>(b.leaf_clusters_per_tip);
        const Eigen::Vector3d jitter(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1));
        const Eigen::Vector3d c =
            s.p0 + t * (s.p1 - s.p0) + b.leaf_cluster_radius_m * jitter / std::sqrt(3.0);
        g.leaves.emplace_back(c.x(), c.y(), c.z(), b.leaf_cluster_radius_m);
      }
    }
  }
  return g;
}

}  // namespace sonicboom::sim
