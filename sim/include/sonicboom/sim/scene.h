#pragma once
/// What a scene holds (keys under "scene"): the objects the tube may touch, one drawn per strike;
/// how strikes are made (mode); and the geometry every object becomes in the simulation.
///
/// Modes:
///  - strike: the robot strikes; each strike places its drawn object where the tube will meet it
///    (rollout.h). Rods, crosses and branch structures.
///  - stationary: the robot holds still while a hand-held striker hits commanded points on the
///    tube (stationary.h). The arm is not integrated. Objects of kind striker.
///  - guided: guided sampling for haptic mapping: one object fixed in the world, candidate tube
///    positions on a plane around it, four taps from each (rollout.h).
///
/// Object frames (m): a rod runs along +x from its clamped end (the origin) to its free tip at
/// x = length. A cross adds a second rod behind the first (+y) at its middle, along z. A branch
/// structure grows from its trunk base (the origin, clamped) along +x and forks.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::sim {

/// The second rod of a cross, bolted behind the struck rod at its middle, at 90 degrees.
struct CrossConfig {
  double diameter_m{0.015};
  double length_m{0.50};

  void Serialize(Archive* a);
};

/// A procedural branch structure: a trunk that forks `levels` times into `forks` children each,
/// child diameters by Leonardo's rule (d^2 = sum of the children's d^2), leaves at the tips.
struct BranchConfig {
  int64_t levels{3};                    // fork generations below the trunk
  int64_t forks{2};                     // children per fork
  double fork_angle_deg{35.0};          // child axis off the parent axis
  double length_ratio{0.7};             // child length / parent length
  int64_t variants{4};                  // distinct trees; each is compiled once
  int64_t shape_seed{1};                // tree v is drawn from (shape_seed, v)
  double min_target_diameter_m{0.006};  // thinner twigs are not aimed at (still touchable)
  double leaf_cluster_radius_m{0.0};    // foliage spheres; 0 = no leaves
  int64_t leaf_clusters_per_tip{1};     // spread along each terminal segment, last at its tip

  void Serialize(Archive* a);
};

enum class ObjectKind { kRod, kCross, kBranch, kStriker };
inline constexpr EnumName<ObjectKind> kObjectKindNames[] = {{ObjectKind::kRod, "rod"},
                                                            {ObjectKind::kCross, "cross"},
                                                            {ObjectKind::kBranch, "branch"},
                                                            {ObjectKind::kStriker, "striker"}};
inline std::span<const EnumName<ObjectKind>> EnumNames(ObjectKind) {
  return kObjectKindNames;
}

/// Where a rod or cross is held: at its base (a cantilever) or at both ends.
enum class Clamp { kOneEnd, kBothEnds };
inline constexpr EnumName<Clamp> kClampNames[] = {{Clamp::kOneEnd, "one_end"},
                                                  {Clamp::kBothEnds, "both_ends"}};
inline std::span<const EnumName<Clamp>> EnumNames(Clamp) {
  return kClampNames;
}

/// The material family an object is named after; its values are the object's `elastic` fields.
enum class ObjectMaterial { kWood, kAluminium, kPvc };
inline constexpr EnumName<ObjectMaterial> kObjectMaterialNames[] = {
    {ObjectMaterial::kWood, "wood"},
    {ObjectMaterial::kAluminium, "aluminium"},
    {ObjectMaterial::kPvc, "pvc"}};
inline std::span<const EnumName<ObjectMaterial>> EnumNames(ObjectMaterial) {
  return kObjectMaterialNames;
}

/// One object of a scene: a clamped rod, a cross, a branch structure or a hand-held striker.
/// Materials: wood (side-grain contact modulus), aluminium, pvc; values are per object. The
/// elastic values are the tube's MaterialConfig fields, read under the same keys as the object's
/// own (youngs_modulus_pa, poisson_ratio, density_kg_m3, loss_factor), with the object's bounds.
struct ObjectConfig {
  ObjectKind kind{ObjectKind::kRod};
  std::string name;          // "" = derived, e.g. "rod T22L42"
  double weight{1.0};        // relative probability of being drawn
  double diameter_m{0.022};  // rod, trunk or striker outer diameter
  double length_m{0.42};
  double wall_thickness_m{0.0};  // 0 = solid; a pipe otherwise
  Clamp clamp{Clamp::kOneEnd};   // rods and crosses
  ObjectMaterial material{ObjectMaterial::kWood};
  // youngs_modulus_pa: bending stiffness (along the grain for wood)
  MaterialConfig elastic{.youngs_modulus_pa = 1.0e10,
                         .poisson_ratio = 0.35,
                         .density_kg_m3 = 650.0,
                         .loss_factor = 0.01};
  double contact_youngs_modulus_pa{1.0e9};  // at the contact surface (side grain for wood)
  CrossConfig cross;                        // kind cross only
  BranchConfig branch;                      // kind branch only

  void Serialize(Archive* a);
  /// Throws ConfigError naming `key` (e.g. "scene.objects.2") and the offending field.
  void Validate(const std::string& key) const;
  /// The name recorded with every contact: `name`, or derived in the paper's notation
  /// ("rod T22L42", "cross T22L42+T15L50", "branch T25L30", "striker pvc T32L40").
  std::string DisplayName() const;
  /// Mass per metre of the rod, trunk or striker, kg/m.
  double LinearDensityKgM() const;
};

/// The robot holds still; a hand-held striker hits commanded points (scene.mode stationary).
struct StationaryConfig {
  double speed_min_m_s{0.3};  // hand speed at the strike, uniform in [min, max]
  double speed_max_m_s{1.5};
  double z_grid_m{0.02};              // commanded heights on this grid (0 = continuous)
  double approach_spread_deg{20.0};   // approach direction off the surface normal
  double hand_stiffness_n_m{3000.0};  // grip: spring from the hand to the striker
  double hand_damping_ratio{0.7};
  double follow_through_m{0.003};  // the hand aims this far inside the surface
  double tip_margin_m{0.05};       // contact this far from the striker's free tip
  double approach_s{0.05};         // the striker starts this long before the contact

  void Serialize(Archive* a);
  void Validate() const;
};

/// Guided sampling for haptic mapping (scene.mode guided): the first object stands fixed in the
/// world; the tube centre visits grid points on a horizontal plane that keep clear of it and lie
/// in its closest layer; from each, four taps (joint 1 +-, joint 6 +-). Sample i uses point
/// i / 4 (cyclically) and direction i % 4.
struct GuidedConfig {
  std::vector<double> object_position_m{0.005, 0.40, 0.31};  // (3) object origin, base frame
  double object_yaw_deg{0.0};                  // object x axis about base z from base x
  double plane_z_m{0.315};                     // tube-centre plane
  std::vector<double> x_range_m{-0.22, 0.22};  // (2)
  std::vector<double> y_range_m{0.20, 0.55};   // (2)
  int64_t grid_points{484};                    // floor(sqrt(n))^2 points
  double clearance_m{0.0715};                  // tube axis to object surface, at least
  double layer_m{0.10};                        // and at most this farther than the clearance
  double joint7_rad{-2.1};                     // joint 7 during mapping
  double tap_deg{15.0};                        // joint 1 or 6 travel of a tap
  double amplitude_threshold{0.02};  // audio peak (full scale) below which a tap is dropped

  void Serialize(Archive* a);
  void Validate() const;
};

/// How strikes are made (the modes at the top of this file).
enum class SceneMode { kStrike, kStationary, kGuided };
inline constexpr EnumName<SceneMode> kSceneModeNames[] = {{SceneMode::kStrike, "strike"},
                                                          {SceneMode::kStationary, "stationary"},
                                                          {SceneMode::kGuided, "guided"}};
inline std::span<const EnumName<SceneMode>> EnumNames(SceneMode) {
  return kSceneModeNames;
}

struct SceneConfig {
  SceneMode mode{SceneMode::kStrike};
  std::vector<ObjectConfig> objects{ObjectConfig{}};  // default: one T22L42 wooden rod
  StationaryConfig stationary;
  GuidedConfig guided;

  void Serialize(Archive* a);
  void Validate() const;
};

/// One cylinder of an object, object frame, m.
struct ObjectSegment {
  Eigen::Vector3d p0{Eigen::Vector3d::Zero()};  // (3) base end (towards the clamp or trunk)
  Eigen::Vector3d p1{Eigen::Vector3d::Zero()};  // (3) far end
  double radius_m{0.0};
  bool free_tip{true};  // p1 is a free end (no child)
};

/// An object as the simulation sees it (object frame, m).
struct ObjectGeometry {
  std::vector<ObjectSegment> segments;
  std::vector<int> targets;             // segments a strike may aim at
  std::vector<Eigen::Vector4d> leaves;  // (x, y, z, radius) foliage spheres
};

/// The geometry of `object` (variant v of a branch structure; other kinds have one variant).
ObjectGeometry BuildObjectGeometry(const ObjectConfig& object, int64_t variant);

/// Guided mode's mapped object placed in the base frame: scene.guided.object_position_m, turned
/// by object_yaw_deg about base z (object frame to base frame).
Eigen::Isometry3d GuidedObjectPose(const GuidedConfig& guided);

/// Guided mode: the mapped object's segments (the first object's first variant, the one the
/// taps visit) in the base frame, m; empty in any other mode or without objects.
std::vector<ObjectSegment> GuidedSegmentsInBase(const SceneConfig& scene);

/// Number of distinct geometries of an object (branch variants; 1 otherwise).
int64_t ObjectVariants(const ObjectConfig& object);

/// Index of the object drawn with probability proportional to its weight, from u in [0, 1).
int DrawObjectIndex(const std::vector<ObjectConfig>& objects, double u);

/// Modal mass of the fundamental bending mode of a beam seen at distance x from its clamped end,
/// kg: m / phi(x)^2, mode shape normalised to integral(phi^2) = L (docs/physics.md, "Beam modes"):
/// a cantilever (clamped_both_ends false) has m / 4 at its tip. Infinite at a clamp.
double BeamModalMassKg(double mass_kg, double length_m, double x_m, bool clamped_both_ends);

/// Describes the struck rod of a rod or cross object as a beam for acoustics (its bending modes
/// take part in the contact): length, E I, rho A, clamping, loss, and the contact's distance from
/// the clamped base. Other kinds (branches, strikers) are left as rigid bodies.
void DescribeStruckBeam(const ObjectConfig& object, double contact_from_clamp_m,
                        ContactEvent* event);

}  // namespace sonicboom::sim
