#include "sonicboom/core/constants.h"
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
#include "internal/strike_rollout.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/franka_mjcf.h"
#include "sonicboom/sim/mujoco_scene.h"

namespace sonicboom::sim {
namespace {

using internal::ModelPtr;
using internal::RequireId;
using internal::SegmentDistance;

// object surface this far beyond the intended contact point at the kinematic contact pose, m
constexpr double kObjectGapM = 0.001;
// a one-end-clamped rod is struck this far from its free tip, m (room to slide while pressed)
constexpr double kTipMarginM = 0.05;
// other targets are struck in this middle fraction of their length
constexpr double kMiddleLo = 0.2, kMiddleHi = 0.8;
// joint step (rad) of the finite difference that gives the direction of motion
constexpr double kDirectionStepRad = 1e-6;
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

// bounds of a config value that code (not only YAML) may set
void RequireInRange(double value, double lo, double hi, const char* key) {
  if (!(value >= lo && value <= hi)) {
    throw ConfigError(fmt::format("{} = {} must lie in [{}, {}]", key, value, lo, hi));
  }
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
  a->Visit("stepping", &stepping);
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

// Guided sampling: the fixed object pose and the candidate start configurations.
struct StrikeRollout::Guided {
  Eigen::Isometry3d object_pose{Eigen::Isometry3d::Identity()};
  std::vector<Eigen::Vector3d> points;  // tube centre, base frame, m
  std::vector<JointVector> joints;      // start configuration of each point, rad
};

StrikeRollout::StrikeRollout(const TubeConfig& tube, const AudioConfig& audio,
                             const StrikeConfig& strike, const SceneConfig& scene,
                             const RolloutConfig& rollout)
    : tube_(tube), audio_(audio), strike_(strike), scene_(scene), config_(rollout) {
  tube_.Validate();
  strike_.Validate();
  scene_.Validate();
  config_.Validate();
  if (scene_.mode != SceneMode::kStrike && scene_.mode != SceneMode::kGuided) {
    throw ConfigError(
        fmt::format("scene.mode {} has no arm rollout (StrikeRollout runs modes "
                    "strike and guided)",
                    NameOf(scene_.mode)));
  }
  if (!(audio_.record_duration_s > 0.0 && audio_.onset_time_s >= 0.0)) {
    throw ConfigError(
        fmt::format("audio.record_duration_s = {} and audio.onset_time_s = {} must "
                    "be positive",
                    audio_.record_duration_s, audio_.onset_time_s));
  }
  timestep_s_ = config_.ResolvedTimestep();

  // one compiled scene per object geometry; guided mode uses the first object only
  const size_t objects = scene_.mode == SceneMode::kGuided ? 1 : scene_.objects.size();
  variants_.resize(objects);
  for (size_t o = 0; o < objects; ++o) {
    const ObjectConfig& object = scene_.objects[o];
    if (object.weight <= 0.0 && scene_.mode == SceneMode::kStrike)
      continue;  // never drawn: not built
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
      for (int k = 1; k <= internal::kMaxFreeStepMultiple; ++k) {
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
      // the tube-only model: a copy of the full one whose arm pairs detect nothing (a contact
      // needs dist < margin), so that it is the same model in every other respect
      var->tube_only.reset(mj_copyModel(nullptr, m));
      SONICBOOM_DEMAND(var->tube_only != nullptr);
      for (int p = 0; p < m->npair; ++p) {
        if (m->pair_geom1[p] != var->tube_geom && m->pair_geom2[p] != var->tube_geom) {
          var->tube_only->pair_margin[p] = -mjMAXVAL;
        }
      }
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

  if (scene_.mode == SceneMode::kGuided) BuildGuided();
}

StrikeRollout::~StrikeRollout() = default;

void StrikeRollout::BuildGuided() {
  // the object's fixed pose, and its segments in the base frame
  const GuidedConfig& g = scene_.guided;
  guided_ = std::make_unique<Guided>();
  guided_->object_pose = GuidedObjectPose(g);
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
  if (scene_.mode == SceneMode::kGuided) {
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
  plan.motion = std::string(NameOf(draw.motion));
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
  const bool tip_strike = (object.kind == ObjectKind::kRod && object.clamp == Clamp::kOneEnd);
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
  if (object.kind == ObjectKind::kBranch) {
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
    event->striker_poisson_ratio = object.elastic.poisson_ratio;
    event->robot_side_mass_kg = c.robot_side_mass_kg;
    // the struck rod (segment 0 of a rod or cross) rings in the contact
    if (c.segment == 0) DescribeStruckBeam(object, c.segment_x_m, event);
    return true;
  }
  return false;
}

}  // namespace sonicboom::sim
