#include "sonicboom/sim/rollout.h"

#include <fmt/format.h>
#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "internal/mujoco_util.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/franka_mjcf.h"
#include "sonicboom/sim/mujoco_scene.h"

namespace sonicboom::sim {
namespace {

using internal::AllFinite;
using internal::DataPtr;
using internal::GeomName;
using internal::ModelPtr;
using internal::RaisedWarning;
using internal::RequireId;
using internal::SegmentDistance;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
// object surface this far beyond the intended contact point at the kinematic contact pose, m
constexpr double kObjectGapM = 0.001;
// a one-end-clamped rod is struck this far from its free tip, m (room to slide while pressed)
constexpr double kTipMarginM = 0.05;
// other targets are struck in this middle fraction of their length
constexpr double kMiddleLo = 0.2, kMiddleHi = 0.8;
// joint step (rad) of the finite difference that gives the direction of motion
constexpr double kDirectionStepRad = 1e-6;
// An episode ends after this many steps without contact: under friction MuJoCo's soft contact
// between the pressed tube and an object flickers off for single steps (with friction 0 it does
// not), which would otherwise count as bounces
constexpr int64_t kReleaseSteps = 2;
// Free flight (no object pair can touch) steps k timesteps at once, k <= kMaxFreeStepMultiple,
// with omega_max k dt <= kFreeStepOmegaDt for the stiffest joint's natural frequency
// omega_max = max_i sqrt(K_i / M_ii) (explicit impedance torques stay well inside stability)
constexpr int kMaxFreeStepMultiple = 4;
constexpr double kFreeStepOmegaDt = 0.75;
// A steady press (no episode opened or closed for kSteadyPressS) steps
// rollout.press_step_multiple timesteps at once (at most the free-flight multiple, for the arm)
constexpr double kSteadyPressS = 0.05;
// a step skips collision detection when every object pair is this much farther apart than it
// can close in one step, m
constexpr double kCollisionSkipSlackM = 0.001;
// guided mode: the motion starts this long into the record, s
constexpr double kGuidedStartS = 0.1;
// guided taps: joint (0-based) and direction of taps 0..3 (j1 +, j1 -, j6 +, j6 -)
constexpr std::array<std::pair<int, double>, 4> kGuidedTaps = {
    {{0, 1.0}, {0, -1.0}, {5, 1.0}, {5, -1.0}}};
constexpr std::array<const char*, 4> kGuidedTapNames = {"tap j1+", "tap j1-", "tap j6+", "tap j6-"};

// normalised time s in [0, 1] with MinJerk(s) = fraction (bisection; MinJerk is increasing)
double MinJerkInverse(double fraction) {
  double lo = 0.0, hi = 1.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (MinJerk(mid) < fraction ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Surface distance lower bound of two capsule or cylinder geoms at their poses in d: their axis
// segments' distance less both radii (a cylinder lies inside the capsule of its radius), m
double GeomGapLowerBound(const mjModel* m, const mjData* d, int g1, int g2) {
  auto axis = [&](int g, Eigen::Vector3d* a, Eigen::Vector3d* b) {
    const Eigen::Vector3d center(d->geom_xpos + 3 * g);
    const mjtNum* mat = d->geom_xmat + 9 * g;  // row-major: local z is column 2
    const Eigen::Vector3d half = m->geom_size[3 * g + 1] * Eigen::Vector3d(mat[2], mat[5], mat[8]);
    *a = center - half;
    *b = center + half;
  };
  Eigen::Vector3d a1, b1, a2, b2;
  axis(g1, &a1, &b1);
  axis(g2, &a2, &b2);
  return SegmentDistance(a1, b1, a2, b2) - m->geom_size[3 * g1] - m->geom_size[3 * g2];
}

// bounds of a config value that code (not only YAML) may set
void RequireInRange(double value, double lo, double hi, const char* key) {
  if (!(value >= lo && value <= hi)) {
    throw ConfigError(fmt::format("{} = {} must lie in [{}, {}]", key, value, lo, hi));
  }
}

// Modal mass (kg) of an object segment's fundamental mode seen at object-frame point p: the
// segment as a beam clamped at its base end (both ends for a both-ends-clamped rod or cross)
double SegmentModalMassKg(const ObjectConfig& object, const ObjectSegment& seg,
                          const Eigen::Vector3d& p_object) {
  const Eigen::Vector3d axis = seg.p1 - seg.p0;
  const double length_m = axis.norm();
  const double x_m = std::clamp((p_object - seg.p0).dot(axis) / length_m, 0.0, length_m);
  const double area_scale =
      (seg.radius_m * seg.radius_m) / (0.25 * object.diameter_m * object.diameter_m);
  const double mass_kg = object.LinearDensityKgM() * area_scale * length_m;
  return BeamModalMassKg(mass_kg, length_m, x_m, object.clamp == "both_ends");
}

}  // namespace

void RolloutConfig::Serialize(Archive* a) {
  a->Visit("timestep_s", &timestep_s, Bounds::Closed(0.0, 0.01));
  a->Visit("contact_timeconst_s", &contact_timeconst_s, Bounds::Open(0.0, 1.0));
  a->Visit("contact_dampratio", &contact_dampratio, Bounds::Open(0.0, 10.0));
  a->Visit("contact_friction", &contact_friction, Bounds::Closed(0.0, 5.0));
  a->Visit("stiffness_nm_rad", &stiffness_nm_rad, Bounds::Open(0.0, 1e12));
  a->Visit("lateral_stiffness_nm_rad", &lateral_stiffness_nm_rad, Bounds::Open(0.0, 1e12));
  a->Visit("damping_ratio", &damping_ratio, Bounds::Closed(0.0, 10.0));
  a->Visit("sweep_overshoot_deg", &sweep_overshoot_deg, Bounds::Closed(0.0, 30.0));
  a->Visit("penetration_limit_m", &penetration_limit_m, Bounds::Open(0.0, 0.1));
  a->Visit("settle_s", &settle_s, Bounds::Closed(0.0, 10.0));
  a->Visit("press_step_multiple", &press_step_multiple, Bounds::Closed(0.0, 8.0));
}

double RolloutConfig::ResolvedTimestep() const {
  return timestep_s > 0.0 ? timestep_s : 0.25 * contact_timeconst_s;
}

int64_t RolloutConfig::ResolvedPressStepMultiple() const {
  if (press_step_multiple > 0) return press_step_multiple;
  const double limit = contact_timeconst_s / (2.0 * ResolvedTimestep());
  return limit >= 2.0 * (1.0 - 1e-9) ? 2 : 1;
}

void RolloutConfig::Validate() const {
  RequireInRange(timestep_s, 0.0, 0.01, "rollout.timestep_s");
  RequireInRange(contact_timeconst_s, 1e-9, 1.0, "rollout.contact_timeconst_s");
  RequireInRange(contact_dampratio, 1e-9, 10.0, "rollout.contact_dampratio");
  RequireInRange(contact_friction, 0.0, 5.0, "rollout.contact_friction");
  RequireInRange(damping_ratio, 0.0, 10.0, "rollout.damping_ratio");
  RequireInRange(sweep_overshoot_deg, 0.0, 30.0, "rollout.sweep_overshoot_deg");
  RequireInRange(penetration_limit_m, 1e-12, 0.1, "rollout.penetration_limit_m");
  RequireInRange(settle_s, 0.0, 10.0, "rollout.settle_s");
  for (const auto& [key, gains] :
       {std::pair{"stiffness_nm_rad", &stiffness_nm_rad},
        std::pair{"lateral_stiffness_nm_rad", &lateral_stiffness_nm_rad}}) {
    if (gains->size() != kPandaJoints) {
      throw ConfigError(
          fmt::format("rollout.{} needs {} entries, got {}", key, kPandaJoints, gains->size()));
    }
    for (size_t i = 0; i < gains->size(); ++i) {
      if (!(std::isfinite((*gains)[i]) && (*gains)[i] > 0.0)) {
        throw ConfigError(fmt::format("rollout.{}[{}] = {} must be positive", key, i, (*gains)[i]));
      }
    }
  }
  // MuJoCo silently stiffens a contact time constant below two timesteps (its "refsafe" rule)
  const double dt_s = ResolvedTimestep();
  if (contact_timeconst_s < 2.0 * dt_s) {
    throw ConfigError(fmt::format(
        "rollout.contact_timeconst_s = {} s is below its limit of 2 timesteps (2 x {} s = {} s)",
        contact_timeconst_s, dt_s, 2.0 * dt_s));
  }
  RequireInRange(static_cast<double>(press_step_multiple), 0.0, 8.0, "rollout.press_step_multiple");
  if (contact_timeconst_s < 2.0 * static_cast<double>(press_step_multiple) * dt_s * (1.0 - 1e-9)) {
    throw ConfigError(
        fmt::format("rollout.press_step_multiple = {} needs rollout.contact_timeconst_s >= 2 x {} "
                    "x {} s = {} s "
                    "(MuJoCo's contact limit of 2 steps); it is {} s",
                    press_step_multiple, press_step_multiple, dt_s,
                    2.0 * press_step_multiple * dt_s, contact_timeconst_s));
  }
}

// One compiled scene: the Panda, the tube and one object geometry, with indices into it.
struct StrikeRollout::Variant {
  int object{0};
  int64_t variant{0};
  std::string name;         // recorded with every contact
  ObjectGeometry geometry;  // object frame
  std::unique_ptr<PandaScene> scene;
  std::array<int, kPandaJoints> qpos{};      // qpos index of panda_joint1..7
  std::array<int, kPandaJoints> dof{};       // dof index of panda_joint1..7
  std::array<int, kPandaJoints> actuator{};  // panda_motor1..7
  int tube_geom{-1};
  int object_mocap{-1};  // index into mjData's mocap arrays
  int flange_body{-1};   // body carrying the tube
  int tube_site{-1};
  std::vector<int> segment_of_geom;  // (ngeom) object segment of a geom, -1 otherwise
  // The scene with contacts disabled, stepped instead where no object pair can touch: its steps
  // equal the full model's whenever collision detection would find no contact. Twin k - 1 steps
  // k timesteps at once (free flight needs only the arm's own time scale, see Simulate).
  std::vector<ModelPtr> contact_free;
  // The scene with the tube-object pairs only, stepped where the arm cannot touch the object:
  // its steps equal the full model's whenever no arm pair would find a contact.
  ModelPtr tube_only;
  // The full and tube-only scenes stepping press_multiple timesteps at once, for a steady press
  ModelPtr press, press_tube_only;
  int press_multiple{1};
  std::vector<std::array<int, 2>> tube_pairs;  // geoms of the tube-object pairs
  std::vector<std::array<int, 2>> arm_pairs;   // geoms of the arm-object pairs
  double reach_m{0.0};  // bound on any geom point's distance to any joint axis
};

// Guided sampling: the fixed object pose and the candidate start configurations.
struct StrikeRollout::Guided {
  Eigen::Isometry3d object_pose{Eigen::Isometry3d::Identity()};
  std::vector<Eigen::Vector3d> points;  // tube centre, base frame, m
  std::vector<JointVector> joints;      // start configuration of each point, rad
};

// What one rollout does: start, goal and timing of the joint path, gains, object pose, target.
struct StrikeRollout::Plan {
  JointVector q_start{JointVector::Zero()};      // rad
  JointVector q_goal{JointVector::Zero()};       // rad
  double t_start_s{0.0};                         // path start, audio clock
  double duration_s{1.0};                        // path duration
  std::array<double, kPandaJoints> stiffness{};  // N m / rad
  Eigen::Isometry3d object_pose{Eigen::Isometry3d::Identity()};
  std::string motion;
  double target_z_m{0.0};
  double target_theta_rad{0.0};
  double target_time_s{0.0};
  bool timed{false};  // start earlier by the swept joint's lag D/K
  int swept_joint{0};
  double s_contact{0.0};  // path fraction (normalised time) at the target
  std::string invalid_reason;
};

StrikeRollout::StrikeRollout(const TubeConfig& tube, const AudioConfig& audio,
                             const StrikeConfig& strike, const SceneConfig& scene,
                             const RolloutConfig& rollout)
    : tube_(tube), audio_(audio), strike_(strike), scene_(scene), config_(rollout) {
  tube_.Validate();
  strike_.Validate();
  scene_.Validate();
  config_.Validate();
  if (scene_.mode != "strike" && scene_.mode != "guided") {
    throw ConfigError(
        fmt::format("scene.mode {} has no arm rollout (StrikeRollout runs modes "
                    "strike and guided)",
                    scene_.mode));
  }
  if (!(audio_.record_duration_s > 0.0 && audio_.onset_time_s >= 0.0)) {
    throw ConfigError(
        fmt::format("audio.record_duration_s = {} and audio.onset_time_s = {} must "
                    "be positive",
                    audio_.record_duration_s, audio_.onset_time_s));
  }
  timestep_s_ = config_.ResolvedTimestep();

  // one compiled scene per object geometry; guided mode uses the first object only
  const size_t objects = scene_.mode == "guided" ? 1 : scene_.objects.size();
  variants_.resize(objects);
  for (size_t o = 0; o < objects; ++o) {
    const ObjectConfig& object = scene_.objects[o];
    if (object.weight <= 0.0 && scene_.mode == "strike") continue;  // never drawn: not built
    const int64_t count = ObjectVariants(object);
    for (int64_t v = 0; v < count; ++v) {
      auto var = std::make_unique<Variant>();
      var->object = static_cast<int>(o);
      var->variant = v;
      var->name = count > 1 ? fmt::format("{} #{}", object.DisplayName(), v) : object.DisplayName();
      var->geometry = BuildObjectGeometry(object, v);
      if (var->geometry.targets.empty()) {
        throw ConfigError(
            fmt::format("scene.objects.{}: variant {} has no segment to aim at "
                        "(see branch.min_target_diameter_m)",
                        o, v));
      }
      PandaMjcfOptions options;
      options.timestep_s = timestep_s_;
      MjcfObject mjcf_object;
      mjcf_object.segments = var->geometry.segments;
      mjcf_object.contact_timeconst_s = config_.contact_timeconst_s;
      mjcf_object.contact_dampratio = config_.contact_dampratio;
      mjcf_object.friction = config_.contact_friction;
      options.objects.push_back(mjcf_object);
      options.elliptic_friction_cones = true;
      // only object contacts matter here (tube strikes, arm hits): no broad phase, no
      // self-collision
      options.object_contacts_only = true;
      var->scene = std::make_unique<PandaScene>(PandaMjcf(tube_, options));

      const mjModel* m = var->scene->model();
      for (int i = 0; i < kPandaJoints; ++i) {
        const int joint = RequireId(m, mjOBJ_JOINT, fmt::format("panda_joint{}", i + 1));
        var->qpos[i] = m->jnt_qposadr[joint];
        var->dof[i] = m->jnt_dofadr[joint];
        var->actuator[i] = RequireId(m, mjOBJ_ACTUATOR, fmt::format("panda_motor{}", i + 1));
      }
      var->tube_geom = RequireId(m, mjOBJ_GEOM, "tube");
      var->object_mocap = m->body_mocapid[RequireId(m, mjOBJ_BODY, "object0")];
      SONICBOOM_DEMAND(var->object_mocap >= 0);
      var->flange_body = m->geom_bodyid[var->tube_geom];
      var->tube_site = RequireId(m, mjOBJ_SITE, "tube_center");
      var->segment_of_geom.assign(static_cast<size_t>(m->ngeom), -1);
      for (size_t k = 0; k < var->geometry.segments.size(); ++k) {
        var->segment_of_geom[RequireId(m, mjOBJ_GEOM, fmt::format("object0_{}", k))] =
            static_cast<int>(k);
      }

      // contact-free twin and the pairs it may skip (capsules and cylinders only)
      for (int k = 1; k <= kMaxFreeStepMultiple; ++k) {
        ModelPtr twin(mj_copyModel(nullptr, m));
        SONICBOOM_DEMAND(twin != nullptr);
        twin->opt.disableflags |= mjDSBL_CONTACT;
        twin->opt.timestep = k * timestep_s_;
        var->contact_free.push_back(std::move(twin));
      }
      SONICBOOM_DEMAND(m->opt.collision == mjCOL_PAIR);
      for (int p = 0; p < m->npair; ++p) {
        const int g1 = m->pair_geom1[p], g2 = m->pair_geom2[p];
        for (int g : {g1, g2}) {
          SONICBOOM_DEMAND(m->geom_type[g] == mjGEOM_CAPSULE || m->geom_type[g] == mjGEOM_CYLINDER);
        }
        (g1 == var->tube_geom || g2 == var->tube_geom ? var->tube_pairs : var->arm_pairs)
            .push_back({g1, g2});
      }
      options.arm_object_pairs = false;
      var->tube_only = internal::CompileMjcf(PandaMjcf(tube_, options), "the tube-only Panda MJCF");
      SONICBOOM_DEMAND(var->tube_only->npair == static_cast<int>(var->tube_pairs.size()) &&
                       var->tube_only->ngeom == m->ngeom && var->tube_only->nv == m->nv);
      var->press_multiple = static_cast<int>(config_.ResolvedPressStepMultiple());
      var->press.reset(mj_copyModel(nullptr, m));
      var->press_tube_only.reset(mj_copyModel(nullptr, var->tube_only.get()));
      SONICBOOM_DEMAND(var->press != nullptr && var->press_tube_only != nullptr);
      var->press->opt.timestep = var->press_multiple * timestep_s_;
      var->press_tube_only->opt.timestep = var->press_multiple * timestep_s_;
      // chain length from any joint to any arm geom point: the arm's body and joint offsets,
      // plus the farthest geom point from its body origin (mocap objects do not move)
      double reach_m = 0.0;
      for (int b = 1; b < m->nbody; ++b) {
        if (m->body_mocapid[b] < 0) reach_m += mju_norm3(m->body_pos + 3 * b);
      }
      for (int j = 0; j < m->njnt; ++j) reach_m += mju_norm3(m->jnt_pos + 3 * j);
      double geom_extent_m = 0.0;
      for (int g = 0; g < m->ngeom; ++g) {
        if (m->body_mocapid[m->geom_bodyid[g]] >= 0) continue;
        geom_extent_m = std::max(geom_extent_m, mju_norm3(m->geom_pos + 3 * g) + m->geom_rbound[g]);
      }
      var->reach_m = reach_m + geom_extent_m;
      variants_[o].push_back(std::move(var));
    }
  }

  if (scene_.mode == "guided") BuildGuided();
}

StrikeRollout::~StrikeRollout() = default;

void StrikeRollout::BuildGuided() {
  // the object's fixed pose, and its segments in the base frame
  const GuidedConfig& g = scene_.guided;
  guided_ = std::make_unique<Guided>();
  guided_->object_pose.translation() =
      Eigen::Vector3d(g.object_position_m[0], g.object_position_m[1], g.object_position_m[2]);
  guided_->object_pose.linear() =
      Eigen::AngleAxisd(g.object_yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const ObjectGeometry& geometry = variants_[0][0]->geometry;

  // the tube's mapping orientation: the home pose with joint 7 at guided.joint7_rad
  JointVector q_home;
  for (int i = 0; i < kPandaJoints; ++i) q_home[i] = strike_.home_joints_rad[i];
  q_home[6] = g.joint7_rad;
  const Eigen::Isometry3d home = PandaForwardKinematics(q_home, tube_.center_from_flange_m).tube;
  const Eigen::Vector3d axis = home.linear().col(2);

  // grid on the plane, kept where the tube clears the object by clearance .. clearance + layer
  const int64_t side = std::max<int64_t>(
      1, static_cast<int64_t>(std::floor(std::sqrt(static_cast<double>(g.grid_points)))));
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int64_t ix = 0; ix < side; ++ix) {
    for (int64_t iy = 0; iy < side; ++iy) {
      const double fx = side > 1 ? static_cast<double>(ix) / (side - 1) : 0.5;
      const double fy = side > 1 ? static_cast<double>(iy) / (side - 1) : 0.5;
      const Eigen::Vector3d c(g.x_range_m[0] + fx * (g.x_range_m[1] - g.x_range_m[0]),
                              g.y_range_m[0] + fy * (g.y_range_m[1] - g.y_range_m[0]), g.plane_z_m);
      const Eigen::Vector3d a0 = c - 0.5 * tube_.length_m * axis,
                            a1 = c + 0.5 * tube_.length_m * axis;
      double gap_m = std::numeric_limits<double>::infinity();
      for (const ObjectSegment& s : geometry.segments) {
        gap_m = std::min(gap_m, SegmentDistance(a0, a1, guided_->object_pose * s.p0,
                                                guided_->object_pose * s.p1) -
                                    s.radius_m);
      }
      if (gap_m < g.clearance_m || gap_m > g.clearance_m + g.layer_m) continue;
      // reachable at the mapping orientation, taps within the joint limits
      Eigen::Isometry3d target = home;
      target.translation() = c;
      const IkResult ik = PandaInverseKinematics(target, q_home, tube_.center_from_flange_m);
      if (!ik.converged) continue;
      bool taps_fit = true;
      for (const auto& [joint, sign] : kGuidedTaps) {
        const double q_end = ik.q[joint] + sign * g.tap_deg * kDeg;
        taps_fit = taps_fit && q_end >= lo[joint] && q_end <= hi[joint];
      }
      if (!taps_fit) continue;
      guided_->points.push_back(c);
      guided_->joints.push_back(ik.q);
    }
  }
  if (guided_->points.empty()) {
    throw ConfigError(
        "scene.guided: no grid point clears the object, lies in its closest layer and is "
        "reachable (check object_position_m, plane_z_m, x_range_m, y_range_m, clearance_m, "
        "layer_m)");
  }
}

std::vector<Eigen::Vector3d> StrikeRollout::GuidedPoints() const {
  return guided_ ? guided_->points : std::vector<Eigen::Vector3d>{};
}

RolloutResult StrikeRollout::Run(uint64_t sample_index, uint64_t sample_seed) const {
  Plan plan;
  const Variant* variant = nullptr;
  if (scene_.mode == "guided") {
    // point index / 4 (cyclically), tap index % 4, from that point's start configuration
    const Guided& g = *guided_;
    const size_t point = static_cast<size_t>(sample_index / kGuidedTaps.size()) % g.points.size();
    const size_t tap = static_cast<size_t>(sample_index % kGuidedTaps.size());
    const auto [joint, sign] = kGuidedTaps[tap];
    variant = variants_[0][0].get();
    plan.q_start = g.joints[point];
    plan.q_goal = plan.q_start;
    plan.q_goal[joint] += sign * scene_.guided.tap_deg * kDeg;
    plan.t_start_s = kGuidedStartS;
    plan.duration_s = strike_.sweep_duration_s;
    const auto& gains = joint == 5 ? config_.lateral_stiffness_nm_rad : config_.stiffness_nm_rad;
    for (int i = 0; i < kPandaJoints; ++i) plan.stiffness[i] = gains[i];
    plan.object_pose = g.object_pose;
    plan.motion = kGuidedTapNames[tap];
    plan.swept_joint = joint;
  } else {
    const StrikeDraw draw = DrawStrike(sample_seed, strike_, scene_, tube_, audio_);
    variant = variants_[draw.object][static_cast<size_t>(draw.variant)].get();
    plan = PlanStrike(draw, *variant);
  }
  RolloutResult result = Simulate(*variant, plan);
  return result;
}

StrikeRollout::Plan StrikeRollout::PlanStrike(const StrikeDraw& draw, const Variant& var) const {
  const ObjectConfig& object = scene_.objects[draw.object];
  const double overshoot_rad = config_.sweep_overshoot_deg * kDeg;
  const int j = draw.joint;
  Plan plan;
  plan.motion = draw.motion;
  plan.swept_joint = j;
  plan.timed = true;
  plan.q_start = draw.q0;
  plan.duration_s = strike_.sweep_duration_s;
  const auto& gains = j == 5 ? config_.lateral_stiffness_nm_rad : config_.stiffness_nm_rad;
  for (int i = 0; i < kPandaJoints; ++i) plan.stiffness[i] = gains[i];
  const double travel_rad = draw.sweep_rad * MinJerk(draw.contact_fraction);
  const double goal_rad = travel_rad + overshoot_rad;
  plan.q_goal = draw.q0;
  plan.q_goal[j] += draw.side * goal_rad;
  plan.s_contact = goal_rad > 0.0 ? MinJerkInverse(travel_rad / goal_rad) : 0.0;
  plan.target_z_m = draw.z_m;
  plan.target_time_s = draw.onset_s;

  // the start pose and the commanded goal must lie within the joint limits
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int i = 0; i < kPandaJoints; ++i) {
    if (plan.q_start[i] < lo[i] || plan.q_start[i] > hi[i] || plan.q_goal[i] < lo[i] ||
        plan.q_goal[i] > hi[i]) {
      plan.invalid_reason = fmt::format("joint {} leaves its limits", i + 1);
    }
  }

  // kinematic contact pose and the direction of motion of the axis point at z (tube frame)
  JointVector q_contact = draw.q0;
  q_contact[j] += draw.side * travel_rad;
  JointVector q_next = q_contact;
  q_next[j] += draw.side * kDirectionStepRad;
  const Eigen::Isometry3d pose = PandaForwardKinematics(q_contact, tube_.center_from_flange_m).tube;
  const Eigen::Isometry3d next = PandaForwardKinematics(q_next, tube_.center_from_flange_m).tube;
  const Eigen::Vector3d axis_point(0, 0, draw.z_m);
  const Eigen::Vector3d motion_tube =
      pose.linear().transpose() * (next * axis_point - pose * axis_point);
  if (!(std::hypot(motion_tube.x(), motion_tube.y()) > 1e-12)) {
    plan.invalid_reason = "no approach direction at contact";
  }
  const double motion_theta_rad = std::atan2(motion_tube.y(), motion_tube.x());
  plan.target_theta_rad = WrapAngle(motion_theta_rad + draw.angle_offset_rad);

  // the target segment (by length among the targets) and the aim along it
  const ObjectGeometry& geometry = var.geometry;
  double total_m = 0.0;
  for (int t : geometry.targets) {
    total_m += (geometry.segments[t].p1 - geometry.segments[t].p0).norm();
  }
  int target = geometry.targets.back();
  double acc_m = 0.0;
  for (int t : geometry.targets) {
    acc_m += (geometry.segments[t].p1 - geometry.segments[t].p0).norm();
    if (draw.target_u * total_m < acc_m) {
      target = t;
      break;
    }
  }
  const ObjectSegment& seg = geometry.segments[target];
  const double seg_length_m = (seg.p1 - seg.p0).norm();
  const bool tip_strike = (object.kind == "rod" && object.clamp == "one_end");
  const double along = tip_strike ? std::max(0.5, 1.0 - kTipMarginM / seg_length_m)
                                  : kMiddleLo + (kMiddleHi - kMiddleLo) * draw.target_v;
  const Eigen::Vector3d aim_object = seg.p0 + along * (seg.p1 - seg.p0);

  // object frame: the segment axis a_o and the direction b_o to the rest of the object (a cross's
  // second rod sits at +y; a branch's centroid), perpendicular to the axis
  const Eigen::Vector3d a_o = (seg.p1 - seg.p0).normalized();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const ObjectSegment& s : geometry.segments) centroid += 0.5 * (s.p0 + s.p1);
  centroid /= static_cast<double>(geometry.segments.size());
  Eigen::Vector3d b_o = Eigen::Vector3d::UnitY();
  if (object.kind == "branch") {
    const Eigen::Vector3d to_rest = centroid - aim_object;
    const Eigen::Vector3d perp = to_rest - to_rest.dot(a_o) * a_o;
    b_o = perp.norm() > 1e-9 ? perp.normalized() : a_o.unitOrthogonal();
  }
  b_o = (b_o - b_o.dot(a_o) * a_o).normalized();

  // world: the segment crosses the tube at 90 degrees, tangent at (z, theta), 1 mm beyond the
  // surface; the rest of the object behind (along n); the base end away from the joint-1 axis
  const Eigen::Vector3d normal_world = pose.linear() * SurfaceNormal(plan.target_theta_rad);
  const Eigen::Vector3d axis_world = pose.linear().col(2);
  const Eigen::Vector3d touch_m = pose * SurfacePoint(tube_, draw.z_m, plan.target_theta_rad) +
                                  (seg.radius_m + kObjectGapM) * normal_world;
  Eigen::Vector3d a_w = axis_world.cross(normal_world).normalized();
  const Eigen::Vector3d radial(touch_m.x(), touch_m.y(), 0.0);
  if (a_w.dot(radial) > 0.0) a_w = -a_w;  // base end (towards -a) points outwards
  Eigen::Matrix3d frame_o, frame_w;
  frame_o << a_o, b_o, a_o.cross(b_o);
  frame_w << a_w, normal_world, a_w.cross(normal_world);
  plan.object_pose.linear() = frame_w * frame_o.transpose();
  plan.object_pose.translation() = touch_m - plan.object_pose.linear() * aim_object;
  return plan;
}

RolloutResult StrikeRollout::Simulate(const Variant& var, const Plan& plan) const {
  const mjModel* m = var.scene->model();
  const double dt_s = timestep_s_;
  const ObjectConfig& object = scene_.objects[var.object];
  const ObjectGeometry& geometry = var.geometry;

  RolloutResult result;
  result.timestep_s = dt_s;
  result.joint_speed_rate_hz = strike_.proprio_rate_hz;
  result.target_z_m = plan.target_z_m;
  result.target_theta_rad = plan.target_theta_rad;
  result.target_time_s = plan.target_time_s;
  result.object = var.object;
  result.variant = var.variant;
  result.object_pose = plan.object_pose;
  result.motion = plan.motion;
  auto fail = [&result](std::string reason) {
    if (!result.valid) return;  // keep the first reason
    result.valid = false;
    result.invalid_reason = std::move(reason);
  };
  if (!plan.invalid_reason.empty()) fail(plan.invalid_reason);

  // fresh state: arm at q_start at rest, object placed (mocap pose = object pose)
  DataPtr data(mj_makeData(m));
  SONICBOOM_DEMAND(data != nullptr);
  mjData* d = data.get();
  for (int i = 0; i < kPandaJoints; ++i) d->qpos[var.qpos[i]] = plan.q_start[i];
  const Eigen::Quaterniond object_quat(plan.object_pose.linear());
  for (int k = 0; k < 3; ++k)
    d->mocap_pos[3 * var.object_mocap + k] = plan.object_pose.translation()[k];
  d->mocap_quat[4 * var.object_mocap + 0] = object_quat.w();
  d->mocap_quat[4 * var.object_mocap + 1] = object_quat.x();
  d->mocap_quat[4 * var.object_mocap + 2] = object_quat.y();
  d->mocap_quat[4 * var.object_mocap + 3] = object_quat.z();
  mj_forward(m, d);

  // impedance gains: K from the plan, D from the mass matrix diagonal at the start
  std::array<double, kPandaJoints> stiffness = plan.stiffness, damping{};
  for (int i = 0; i < kPandaJoints; ++i) {
    const double m_ii = d->qM[m->dof_Madr[var.dof[i]]];
    damping[i] = 2.0 * config_.damping_ratio * std::sqrt(stiffness[i] * m_ii);
  }

  // free-flight step multiple from the stiffest joint's natural frequency at the start
  double omega_max = 0.0;
  for (int i = 0; i < kPandaJoints; ++i) {
    omega_max = std::max(omega_max, std::sqrt(stiffness[i] / d->qM[m->dof_Madr[var.dof[i]]]));
  }
  const int free_multiple = std::clamp(
      static_cast<int>(std::floor(kFreeStepOmegaDt / (omega_max * dt_s))), 1, kMaxFreeStepMultiple);
  const mjModel* free_model = var.contact_free[static_cast<size_t>(free_multiple - 1)].get();
  const int press_multiple = std::min(var.press_multiple, free_multiple);

  // path timing: a timed strike reaches the object at the onset, started earlier by the lag D/K
  const double duration_s = plan.duration_s;
  double t_path_s = plan.t_start_s;
  if (plan.timed) {
    const int j = plan.swept_joint;
    t_path_s = plan.target_time_s - plan.s_contact * duration_s - damping[j] / stiffness[j];
  }
  // step grid: multiples of dt on the audio clock from the path start. Before it the arm holds
  // q_start at rest (the impedance torque is the bias force there), so rows due earlier are the
  // held pose at zero velocity, written at the first step
  const int64_t first_step = static_cast<int64_t>(std::floor(t_path_s / dt_s));

  // rows on the audio clock: proprio (proprio_rows) and joint speed (the whole record)
  const int64_t proprio_rows = strike_.proprio_rows;
  const int64_t speed_rows =
      static_cast<int64_t>(std::ceil(audio_.record_duration_s * strike_.proprio_rate_hz));
  const int64_t rows = std::max(proprio_rows, speed_rows);
  result.proprio.setZero(proprio_rows, kProprioFeatures);
  result.joints.setZero(proprio_rows, kPandaJoints);
  result.joint_speed_rad_s.assign(static_cast<size_t>(speed_rows), 0.0);
  // tube-frame pose (from the kinematics in d) and velocity (from its com velocities)
  auto tube_row = [&](bool with_velocity) {
    const mjtNum* pos = d->site_xpos + 3 * var.tube_site;
    const Eigen::Matrix3d rot = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
        d->site_xmat + 9 * var.tube_site);
    const Eigen::Quaterniond quat(rot);
    mjtNum velocity[6] = {0, 0, 0, 0, 0, 0};  // angular (3), linear (3), world axes
    if (with_velocity) mj_objectVelocity(m, d, mjOBJ_SITE, var.tube_site, velocity, 0);
    Eigen::Matrix<float, 1, kProprioFeatures> row;
    row << pos[0], pos[1], pos[2], quat.w(), quat.x(), quat.y(), quat.z(), velocity[3], velocity[4],
        velocity[5];
    return row;
  };
  Eigen::Matrix<float, 1, kProprioFeatures> last_row = tube_row(false);
  int64_t next_row = 0;
  auto tube_pose = [&] {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Map<const Eigen::Vector3d>(d->site_xpos + 3 * var.tube_site);
    pose.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
        d->site_xmat + 9 * var.tube_site);
    return pose;
  };

  // leaf clusters in the base frame: (centre, radius)
  std::vector<std::pair<Eigen::Vector3d, double>> leaves;
  for (const Eigen::Vector4d& leaf : geometry.leaves) {
    leaves.emplace_back(plan.object_pose * Eigen::Vector3d(leaf.head<3>()), leaf[3]);
  }

  // contact episode bookkeeping: one open episode per segment and per leaf cluster at most
  const int segments = static_cast<int>(geometry.segments.size());
  std::vector<int> open_segment(static_cast<size_t>(segments), -1);  // index into contacts
  std::vector<int> open_leaf(leaves.size(), -1);
  std::vector<int64_t> missing_steps(static_cast<size_t>(segments), 0);     // steps without contact
  std::vector<double> missing_since_s(static_cast<size_t>(segments), 0.0);  // first of them, s
  double last_change_s = -1.0;  // when an episode last opened or closed, s
  std::vector<std::vector<int>> segment_contacts(static_cast<size_t>(segments));  // this step
  std::vector<double> since_release_s;  // per contact: time since the last release at touch
  int first_hard = -1;                  // index of the first hard contact
  internal::EpisodeClassifier kinds;
  auto close_episode = [&](int index, double t_s) {
    last_change_s = t_s;
    ContactRecord& rec = result.contacts[static_cast<size_t>(index)];
    rec.duration_s = t_s - rec.time_s;
    if (rec.kind == ContactEpisode::Kind::kBrush) return;
    rec.kind = kinds.Release(since_release_s[static_cast<size_t>(index)], rec.duration_s,
                             index == first_hard, t_s);
  };
  auto push_record = [&](ContactRecord rec) {
    last_change_s = rec.time_s;
    since_release_s.push_back(kinds.SinceRelease(rec.time_s));
    result.contacts.push_back(std::move(rec));
    return static_cast<int>(result.contacts.size()) - 1;
  };

  // the path ends; without a contact, the simulation ends settle_s later
  double t_end_s = std::min(audio_.record_duration_s, t_path_s + duration_s + config_.settle_s);
  std::vector<mjtNum> scratch(static_cast<size_t>(5 * m->nv));
  int64_t step = 0;  // MuJoCo steps taken
  int64_t grid = 0;  // timesteps simulated (a free-flight step counts free_multiple)
  // joint angles of the last step's kinematics; lower bound of the object pairs' gaps (m) at
  // gap_qpos
  std::array<double, kPandaJoints> last_qpos{}, gap_qpos{};
  double tube_gap_m = -1.0, arm_gap_m = -1.0;
  double t_s = first_step * dt_s;
  while (result.valid) {
    t_s = static_cast<double>(first_step + grid) * dt_s;
    if (t_s >= t_end_s - 0.5 * dt_s) break;
    // Contact-free step where no pair can touch, tube-only step where no arm pair can: each arm
    // point has moved at most reach * |q - gap_qpos|_1 since the pair gaps were bounded (at
    // gap_qpos); re-bound them from the last step's geom poses (at last_qpos) once a budget is
    // spent
    auto budget_left = [&](double gap) {
      double travel_rad = 0.0;
      for (int i = 0; i < kPandaJoints; ++i) {
        travel_rad += std::abs(d->qpos[var.qpos[i]] - gap_qpos[i]);
      }
      return gap - var.reach_m * travel_rad - kCollisionSkipSlackM > 0.0;
    };
    bool tube_may_touch = step == 0, arm_may_touch = step == 0;
    if (step > 0 && !(budget_left(tube_gap_m) && budget_left(arm_gap_m))) {
      auto lowest_gap = [&](const std::vector<std::array<int, 2>>& pairs) {
        double gap = std::numeric_limits<double>::infinity();
        for (const auto& [g1, g2] : pairs) gap = std::min(gap, GeomGapLowerBound(m, d, g1, g2));
        return gap;
      };
      tube_gap_m = lowest_gap(var.tube_pairs);
      arm_gap_m = lowest_gap(var.arm_pairs);
      gap_qpos = last_qpos;
      tube_may_touch = !budget_left(tube_gap_m);
      arm_may_touch = !budget_left(arm_gap_m);
    }
    const bool may_touch = tube_may_touch || arm_may_touch;
    // a free-flight or steady-press step must not pass the end
    const bool free = !may_touch && t_s + free_multiple * dt_s < t_end_s + 0.5 * dt_s;
    const bool steady = may_touch && press_multiple > 1 && first_hard >= 0 &&
                        t_s - last_change_s >= kSteadyPressS - 0.5 * dt_s &&
                        t_s + press_multiple * dt_s < t_end_s + 0.5 * dt_s;
    const mjModel* step_model =
        arm_may_touch ? (steady ? var.press.get() : m)
                      : (tube_may_touch ? (steady ? var.press_tube_only.get() : var.tube_only.get())
                                        : (free ? free_model : var.contact_free[0].get()));
    const int64_t advance = free ? free_multiple : (steady ? press_multiple : 1);
    for (int i = 0; i < kPandaJoints; ++i) last_qpos[i] = d->qpos[var.qpos[i]];

    // positions and velocities at t: kinematics, collisions, mass matrix, bias forces
    mj_step1(step_model, d);
    if (const char* warning = RaisedWarning(d)) {
      fail(fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }

    // rows due at t
    while (next_row < rows && next_row / strike_.proprio_rate_hz <= t_s + 0.5 * dt_s) {
      last_row = tube_row(true);
      if (next_row < proprio_rows) {
        result.proprio.row(next_row) = last_row;
        for (int i = 0; i < kPandaJoints; ++i) result.joints(next_row, i) = d->qpos[var.qpos[i]];
      }
      if (next_row < speed_rows) {
        double sum_sq = 0.0;
        for (int i = 0; i < kPandaJoints; ++i) sum_sq += d->qvel[var.dof[i]] * d->qvel[var.dof[i]];
        result.joint_speed_rad_s[next_row] = std::sqrt(sum_sq);
      }
      ++next_row;
    }

    // contacts with the object at t, grouped by segment
    for (auto& list : segment_contacts) list.clear();
    for (int i = 0; i < d->ncon && result.valid; ++i) {
      const mjContact& c = d->contact[i];
      if (c.exclude != 0) continue;
      const int seg1 = var.segment_of_geom[c.geom1], seg2 = var.segment_of_geom[c.geom2];
      if (seg1 < 0 && seg2 < 0) continue;
      const int segment = seg1 >= 0 ? seg1 : seg2;
      const int other = seg1 >= 0 ? c.geom2 : c.geom1;
      if (step == 0) {
        fail(fmt::format("the object overlaps {} at the start pose", GeomName(m, other)));
      } else if (c.dist < -config_.penetration_limit_m) {
        fail(
            fmt::format("penetration {:.4f} mm of {} into the object at t = {:.4f} s exceeds "
                        "rollout.penetration_limit_m = {} mm",
                        -1e3 * c.dist, GeomName(m, other), t_s, 1e3 * config_.penetration_limit_m));
      } else if (other == var.tube_geom) {
        segment_contacts[static_cast<size_t>(segment)].push_back(i);
      } else if (first_hard < 0) {
        fail(fmt::format("arm hit the object before the tube ({} at t = {:.4f} s)",
                         GeomName(m, other), t_s));
      }
    }
    if (!result.valid) break;

    // tube pose at t (kinematics of this step)
    const Eigen::Isometry3d tube = tube_pose();
    const Eigen::Matrix3d tube_rot = tube.linear();

    // episodes: touch when a segment's first tube contact appears, release when none remains
    for (int segment = 0; segment < segments && result.valid; ++segment) {
      const std::vector<int>& list = segment_contacts[static_cast<size_t>(segment)];
      int& open = open_segment[static_cast<size_t>(segment)];
      int64_t& missing = missing_steps[static_cast<size_t>(segment)];
      if (list.empty()) {
        // released once the contact has stayed away for kReleaseSteps steps, at its first
        // missing step
        if (open >= 0 && ++missing == 1) missing_since_s[static_cast<size_t>(segment)] = t_s;
        if (open >= 0 && missing >= kReleaseSteps) {
          close_episode(open, missing_since_s[static_cast<size_t>(segment)]);
          open = -1;
        }
        continue;
      }
      missing = 0;
      if (open >= 0) continue;
      const mjContact& c = internal::DeepestContact(d, list);
      Eigen::Vector3d normal_world;
      ContactRecord rec = internal::TouchRecord(c, var.tube_geom, tube, t_s, &normal_world);
      rec.segment = segment;
      rec.segment_radius_m = geometry.segments[static_cast<size_t>(segment)].radius_m;
      rec.object = var.name;
      rec.material = object.material;

      // approach speed: tube-point velocity (J qdot) along the outward normal; the object is
      // fixed. Effective mass: robot side 1 / (n^T J M^-1 J^T n) in series with the segment's
      // modal mass at the contact
      rec.normal_speed_m_s =
          internal::PointVelocityAlong(m, d, var.flange_body, c.pos, normal_world, scratch.data());
      const double robot_inverse_kg = internal::InverseEffectiveMass(m, d, var.flange_body, c.pos,
                                                                     normal_world, scratch.data());
      const double object_mass_kg =
          SegmentModalMassKg(object, geometry.segments[static_cast<size_t>(segment)],
                             plan.object_pose.inverse() * rec.point_world_m);
      rec.effective_mass_kg = 1.0 / (robot_inverse_kg + 1.0 / object_mass_kg);
      rec.robot_side_mass_kg = 1.0 / robot_inverse_kg;
      {
        const ObjectSegment& seg = geometry.segments[static_cast<size_t>(segment)];
        const Eigen::Vector3d axis = (seg.p1 - seg.p0).normalized();
        rec.segment_x_m = (plan.object_pose.inverse() * rec.point_world_m - seg.p0).dot(axis);
      }

      const bool first = first_hard < 0;
      const std::string problem = internal::TouchProblem(rec, tube_, first);
      open = push_record(rec);
      if (first) first_hard = open;
      if (!problem.empty()) fail(problem);
      if (first) t_end_s = std::min(audio_.record_duration_s, t_s + config_.settle_s);
    }
    if (!result.valid) break;

    // foliage: a leaf cluster brushes the tube while it overlaps the tube's cylinder
    for (size_t l = 0; l < leaves.size(); ++l) {
      const Eigen::Vector3d local = tube.inverse() * leaves[l].first;
      const double half_length_m = 0.5 * tube_.length_m;
      const double z_m = std::clamp(local.z(), -half_length_m, half_length_m);
      const double radial_m = std::hypot(local.x(), local.y());
      const double gap_to_leaf_m =
          std::hypot(std::max(radial_m - tube_.outer_radius_m, 0.0), local.z() - z_m);
      const bool touching = gap_to_leaf_m < leaves[l].second;
      int& open = open_leaf[l];
      if (!touching) {
        if (open >= 0) close_episode(open, t_s);
        open = -1;
        continue;
      }
      if (open >= 0) continue;
      ContactRecord rec;
      rec.kind = ContactEpisode::Kind::kBrush;
      rec.time_s = t_s;
      rec.theta_rad = WrapAngle(std::atan2(local.y(), local.x()));
      rec.z_m = z_m;
      rec.point_m = SurfacePoint(tube_, rec.z_m, rec.theta_rad);
      rec.normal = SurfaceNormal(rec.theta_rad);
      rec.point_world_m = tube * rec.point_m;
      rec.segment = -1;
      rec.object = "leaves";
      rec.material = "foliage";
      // speed of the tube surface towards the cluster
      mjtNum point[3] = {rec.point_world_m.x(), rec.point_world_m.y(), rec.point_world_m.z()};
      rec.normal_speed_m_s = internal::PointVelocityAlong(m, d, var.flange_body, point,
                                                          tube_rot * rec.normal, scratch.data());
      open = push_record(rec);
    }

    // joint-space impedance with gravity and Coriolis compensation, clamped to the motors
    const double s = MinJerk((t_s - t_path_s) / duration_s);
    for (int i = 0; i < kPandaJoints; ++i) {
      const double q_des = plan.q_start[i] + (plan.q_goal[i] - plan.q_start[i]) * s;
      const int dof = var.dof[i], act = var.actuator[i];
      const double tau_nm = stiffness[i] * (q_des - d->qpos[var.qpos[i]]) -
                            damping[i] * d->qvel[dof] + d->qfrc_bias[dof];
      d->ctrl[act] =
          std::clamp(tau_nm, m->actuator_ctrlrange[2 * act], m->actuator_ctrlrange[2 * act + 1]);
    }

    // actuation, constraint forces, integration to t + dt
    mj_step2(step_model, d);
    ++step;
    grid += advance;
    if (const char* warning = RaisedWarning(d)) {
      fail(fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }
    if (!AllFinite(d->qpos, m->nq) || !AllFinite(d->qvel, m->nv)) {
      fail(fmt::format("non-finite state at t = {:.4f} s", t_s + dt_s));
      break;
    }
    // normal force of this step's tube contacts per open segment (solved in mj_step2)
    for (int segment = 0; segment < segments; ++segment) {
      const int open = open_segment[static_cast<size_t>(segment)];
      if (open < 0) continue;
      internal::AccumulateForce(m, d, segment_contacts[static_cast<size_t>(segment)],
                                static_cast<double>(advance) * dt_s,
                                &result.contacts[static_cast<size_t>(open)]);
    }
  }
  const double t_final_s = static_cast<double>(first_step + grid) * dt_s;
  for (int open : open_segment) {
    if (open >= 0) close_episode(open, t_final_s);
  }
  for (int open : open_leaf) {
    if (open >= 0) close_episode(open, t_final_s);
  }
  result.steps = step;
  result.simulated_s = static_cast<double>(grid) * dt_s;
  if (result.valid && first_hard < 0) fail("no tube contact with the object within the record");

  // rows after the end hold the last state at rest
  if (AllFinite(d->qpos, m->nq)) {
    mj_kinematics(m, d);
    last_row = tube_row(false);
  }
  last_row.tail<3>().setZero();
  for (; next_row < rows; ++next_row) {
    if (next_row >= proprio_rows) continue;
    result.proprio.row(next_row) = last_row;
    for (int i = 0; i < kPandaJoints; ++i) result.joints(next_row, i) = d->qpos[var.qpos[i]];
  }
  return result;
}

bool FirstHardContact(const RolloutResult& result, const SceneConfig& scene, ContactEvent* event,
                      ContactLabel* label) {
  for (const ContactRecord& c : result.contacts) {
    if (c.kind == ContactEpisode::Kind::kBrush) continue;
    const ObjectConfig& object = scene.objects[static_cast<size_t>(result.object)];
    label->z_m = c.z_m;
    label->theta_rad = c.theta_rad;
    label->point_m = c.point_m;  // raw contact point, within 1 mm of the surface
    label->normal = c.normal;
    label->time_s = c.time_s;
    label->normal_speed_m_s = c.normal_speed_m_s;
    event->time_s = c.time_s;
    event->z_m = c.z_m;
    event->theta_rad = c.theta_rad;
    event->normal_speed_m_s = c.normal_speed_m_s;
    event->effective_mass_kg = c.effective_mass_kg;
    event->striker_radius_m = c.segment_radius_m;
    event->striker_youngs_modulus_pa = object.contact_youngs_modulus_pa;
    event->striker_poisson_ratio = object.poisson_ratio;
    event->robot_side_mass_kg = c.robot_side_mass_kg;
    // the struck rod (segment 0 of a rod or cross) rings in the contact
    if (c.segment == 0) DescribeStruckBeam(object, c.segment_x_m, event);
    return true;
  }
  return false;
}

}  // namespace sonicboom::sim
