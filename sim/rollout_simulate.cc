// StrikeRollout's simulation of one planned strike (rollout.h): the arm under joint impedance
// along its path, the tube's episodes with the object's segments and leaves, proprioception.
#include <fmt/format.h>
#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "internal/episodes.h"
#include "internal/mujoco_util.h"
#include "internal/strike_rollout.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::sim {

namespace internal {

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

double SegmentModalMassKg(const ObjectConfig& object, const ObjectSegment& seg,
                          const Eigen::Vector3d& p_object) {
  const Eigen::Vector3d axis = seg.p1 - seg.p0;
  const double length_m = axis.norm();
  const double x_m = std::clamp((p_object - seg.p0).dot(axis) / length_m, 0.0, length_m);
  const double area_scale =
      (seg.radius_m * seg.radius_m) / (0.25 * object.diameter_m * object.diameter_m);
  const double mass_kg = object.LinearDensityKgM() * area_scale * length_m;
  return BeamModalMassKg(mass_kg, length_m, x_m, object.clamp == Clamp::kBothEnds);
}
}  // namespace internal

using internal::AllFinite;
using internal::DataPtr;
using internal::GeomName;

// One rollout in progress: the arm's state, its gains and step multiples, the proprioception
// rows and the episode channels (one per object segment, then one per leaf cluster).
struct StrikeRollout::Simulation {
  const StrikeRollout& rollout;
  const Variant& var;
  const Plan& plan;
  const ObjectConfig& object;
  const mjModel* m;
  RolloutResult* result;
  DataPtr data;
  mjData* d{nullptr};
  double dt_s{0.0};
  // impedance gains (N m / rad, N m s / rad) and step multiples
  std::array<double, kPandaJoints> stiffness{}, damping{};
  int free_multiple{1}, press_multiple{1};
  const mjModel* free_model{nullptr};
  // the joint path on the audio clock
  double t_path_s{0.0};
  int64_t first_step{0};
  // rows on the audio clock: proprio (proprio_rows) and joint speed (the whole record)
  int64_t proprio_rows{0}, speed_rows{0}, rows{0}, next_row{0};
  Eigen::Matrix<float, 1, kProprioFeatures> last_row;
  // leaf clusters in the base frame: (centre, radius)
  std::vector<std::pair<Eigen::Vector3d, double>> leaves;
  internal::EpisodeTracker tracker;
  std::vector<int> leaf_channel;  // segment s is channel s; leaf l is leaf_channel[l]
  std::vector<mjtNum> scratch;
  // collision skipping: joint angles of the last step's kinematics; lower bounds of the object
  // pairs' gaps (m) at gap_qpos
  std::array<double, kPandaJoints> last_qpos{}, gap_qpos{};
  double tube_gap_m{-1.0}, arm_gap_m{-1.0};

  Simulation(const StrikeRollout& r, const Variant& v, const Plan& p, RolloutResult* out);
  Eigen::Matrix<float, 1, kProprioFeatures> TubeRow(bool with_velocity) const;
  Eigen::Isometry3d TubePose() const;
  internal::StepChoice Choose(double t_s, int64_t step);
  void Observe(double t_s, int64_t step);
  void Rows(double t_s);
  void Contacts(double t_s, int64_t step);
  void Segments(double t_s, const Eigen::Isometry3d& tube);
  void Leaves(double t_s, const Eigen::Isometry3d& tube);
  void Control(double t_s);
  void FinalRows();
};

StrikeRollout::Simulation::Simulation(const StrikeRollout& r, const Variant& v, const Plan& p,
                                      RolloutResult* out)
    : rollout(r),
      var(v),
      plan(p),
      object(r.scene_.objects[v.object]),
      m(v.scene->model()),
      result(out),
      data(mj_makeData(m)),
      dt_s(r.timestep_s_),
      tracker(out, r.tube_, r.audio_.record_duration_s, r.config_.settle_s),
      scratch(static_cast<size_t>(5 * m->nv)) {
  // fresh state: arm at q_start at rest, object placed (mocap pose = object pose)
  SONICBOOM_DEMAND(data != nullptr);
  d = data.get();
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
  stiffness = plan.stiffness;
  for (int i = 0; i < kPandaJoints; ++i) {
    const double m_ii = d->qM[m->dof_Madr[var.dof[i]]];
    damping[i] = 2.0 * rollout.config_.damping_ratio * std::sqrt(stiffness[i] * m_ii);
  }

  // free-flight step multiple from the stiffest joint's natural frequency at the start
  double omega_max = 0.0;
  for (int i = 0; i < kPandaJoints; ++i) {
    omega_max = std::max(omega_max, std::sqrt(stiffness[i] / d->qM[m->dof_Madr[var.dof[i]]]));
  }
  free_multiple =
      std::clamp(static_cast<int>(std::floor(internal::kFreeStepOmegaDt / (omega_max * dt_s))), 1,
                 internal::kMaxFreeStepMultiple);
  // the exact and plain schedulers step one timestep at a time
  if (rollout.config_.stepping != StepScheduler::kFast) free_multiple = 1;
  free_model = var.contact_free[static_cast<size_t>(free_multiple - 1)].get();
  press_multiple = std::min(var.press_multiple, free_multiple);

  // path timing: a timed strike reaches the object at the onset, started earlier by the lag D/K
  t_path_s = plan.t_start_s;
  if (plan.timed) {
    const int j = plan.swept_joint;
    t_path_s = plan.target_time_s - plan.s_contact * plan.duration_s - damping[j] / stiffness[j];
  }
  // step grid: multiples of dt on the audio clock from the path start. Before it the arm holds
  // q_start at rest (the impedance torque is the bias force there), so rows due earlier are the
  // held pose at zero velocity, written at the first step
  first_step = static_cast<int64_t>(std::floor(t_path_s / dt_s));
  // the path ends; without a contact, the simulation ends settle_s later
  tracker.set_end_s(t_path_s + plan.duration_s + rollout.config_.settle_s);

  // rows on the audio clock: proprio (proprio_rows) and joint speed (the whole record)
  const StrikeConfig& strike = rollout.strike_;
  proprio_rows = strike.proprio_rows;
  speed_rows =
      static_cast<int64_t>(std::ceil(rollout.audio_.record_duration_s * strike.proprio_rate_hz));
  rows = std::max(proprio_rows, speed_rows);
  result->proprio.setZero(proprio_rows, kProprioFeatures);
  result->joints.setZero(proprio_rows, kPandaJoints);
  result->joint_speed_rad_s.assign(static_cast<size_t>(speed_rows), 0.0);
  last_row = TubeRow(false);

  // leaf clusters in the base frame
  for (const Eigen::Vector4d& leaf : var.geometry.leaves) {
    leaves.emplace_back(plan.object_pose * Eigen::Vector3d(leaf.head<3>()), leaf[3]);
  }
  // episode channels: every segment, then every leaf cluster
  for (size_t s = 0; s < var.geometry.segments.size(); ++s) {
    tracker.AddHardChannel(internal::kReleaseSteps);
  }
  for (size_t l = 0; l < leaves.size(); ++l) leaf_channel.push_back(tracker.AddSoftChannel());
}

// tube-frame pose (from the kinematics in d) and velocity (from its com velocities)
Eigen::Matrix<float, 1, kProprioFeatures> StrikeRollout::Simulation::TubeRow(
    bool with_velocity) const {
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
}

Eigen::Isometry3d StrikeRollout::Simulation::TubePose() const {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Map<const Eigen::Vector3d>(d->site_xpos + 3 * var.tube_site);
  pose.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d->site_xmat +
                                                                                 9 * var.tube_site);
  return pose;
}

// Contact-free step where no pair can touch, tube-only step where no arm pair can: each arm point
// has moved at most reach * |q - gap_qpos|_1 since the pair gaps were bounded (at gap_qpos);
// re-bound them from the last step's geom poses (at last_qpos) once a budget is spent
internal::StepChoice StrikeRollout::Simulation::Choose(double t_s, int64_t step) {
  if (rollout.config_.stepping == StepScheduler::kPlain) return {m, 1};
  auto budget_left = [&](double gap) {
    double travel_rad = 0.0;
    for (int i = 0; i < kPandaJoints; ++i)
      travel_rad += std::abs(d->qpos[var.qpos[i]] - gap_qpos[i]);
    return gap - var.reach_m * travel_rad - internal::kCollisionSkipSlackM > 0.0;
  };
  bool tube_may_touch = step == 0, arm_may_touch = step == 0;
  if (step > 0 && !(budget_left(tube_gap_m) && budget_left(arm_gap_m))) {
    auto lowest_gap = [&](const std::vector<std::array<int, 2>>& pairs) {
      double gap = std::numeric_limits<double>::infinity();
      for (const auto& [g1, g2] : pairs) {
        gap = std::min(gap, internal::GeomGapLowerBound(m, d, g1, g2));
      }
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
  const double t_end_s = tracker.end_s();
  const bool free = !may_touch && t_s + free_multiple * dt_s < t_end_s + 0.5 * dt_s;
  const bool steady = may_touch && press_multiple > 1 && tracker.first_hard() >= 0 &&
                      t_s - tracker.last_change_s() >= internal::kSteadyPressS - 0.5 * dt_s &&
                      t_s + press_multiple * dt_s < t_end_s + 0.5 * dt_s;
  const mjModel* step_model =
      arm_may_touch ? (steady ? var.press.get() : m)
                    : (tube_may_touch ? (steady ? var.press_tube_only.get() : var.tube_only.get())
                                      : (free ? free_model : var.contact_free[0].get()));
  for (int i = 0; i < kPandaJoints; ++i) last_qpos[i] = d->qpos[var.qpos[i]];
  return {step_model, free ? free_multiple : (steady ? press_multiple : 1)};
}

void StrikeRollout::Simulation::Observe(double t_s, int64_t step) {
  Rows(t_s);
  Contacts(t_s, step);
  if (!result->valid) return;
  const Eigen::Isometry3d tube = TubePose();  // kinematics of this step
  Segments(t_s, tube);
  if (!result->valid) return;
  Leaves(t_s, tube);
  Control(t_s);
}

// proprioception and joint-speed rows due at t
void StrikeRollout::Simulation::Rows(double t_s) {
  const double rate_hz = rollout.strike_.proprio_rate_hz;
  while (next_row < rows && next_row / rate_hz <= t_s + 0.5 * dt_s) {
    last_row = TubeRow(true);
    if (next_row < proprio_rows) {
      result->proprio.row(next_row) = last_row;
      for (int i = 0; i < kPandaJoints; ++i) result->joints(next_row, i) = d->qpos[var.qpos[i]];
    }
    if (next_row < speed_rows) {
      double sum_sq = 0.0;
      for (int i = 0; i < kPandaJoints; ++i) sum_sq += d->qvel[var.dof[i]] * d->qvel[var.dof[i]];
      result->joint_speed_rad_s[next_row] = std::sqrt(sum_sq);
    }
    ++next_row;
  }
}

// contacts with the object at t, grouped by segment; the object must touch the tube first
void StrikeRollout::Simulation::Contacts(double t_s, int64_t step) {
  const double limit_m = rollout.config_.penetration_limit_m;
  for (int i = 0; i < d->ncon && result->valid; ++i) {
    const mjContact& c = d->contact[i];
    if (c.exclude != 0) continue;
    const int seg1 = var.segment_of_geom[c.geom1], seg2 = var.segment_of_geom[c.geom2];
    if (seg1 < 0 && seg2 < 0) continue;
    const int segment = seg1 >= 0 ? seg1 : seg2;
    const int other = seg1 >= 0 ? c.geom2 : c.geom1;
    if (step == 0) {
      internal::Fail(result,
                     fmt::format("the object overlaps {} at the start pose", GeomName(m, other)));
    } else if (c.dist < -limit_m) {
      internal::Fail(result,
                     fmt::format("penetration {:.4f} mm of {} into the object at t = {:.4f} s "
                                 "exceeds rollout.penetration_limit_m = {} mm",
                                 -1e3 * c.dist, GeomName(m, other), t_s, 1e3 * limit_m));
    } else if (other == var.tube_geom) {
      tracker.contacts(segment).push_back(i);
    } else if (tracker.first_hard() < 0) {
      internal::Fail(result, fmt::format("arm hit the object before the tube ({} at t = {:.4f} s)",
                                         GeomName(m, other), t_s));
    }
  }
}

// episodes: touch when a segment's first tube contact appears, release when none remains
void StrikeRollout::Simulation::Segments(double t_s, const Eigen::Isometry3d& tube) {
  const ObjectGeometry& geometry = var.geometry;
  const int segments = static_cast<int>(geometry.segments.size());
  for (int segment = 0; segment < segments && result->valid; ++segment) {
    const ObjectSegment& seg = geometry.segments[static_cast<size_t>(segment)];
    tracker.ObserveHard(segment, t_s, d, [&](const mjContact& c) {
      Eigen::Vector3d normal_world;
      ContactRecord rec = internal::TouchRecord(c, var.tube_geom, tube, t_s, &normal_world);
      rec.segment = segment;
      rec.segment_radius_m = seg.radius_m;
      rec.object = var.name;
      rec.material = std::string(NameOf(object.material));
      // approach speed: tube-point velocity (J qdot) along the outward normal; the object is
      // fixed. Effective mass: robot side 1 / (n^T J M^-1 J^T n) in series with the segment's
      // modal mass at the contact
      rec.normal_speed_m_s =
          internal::PointVelocityAlong(m, d, var.flange_body, c.pos, normal_world, scratch.data());
      const double robot_inverse_kg = internal::InverseEffectiveMass(m, d, var.flange_body, c.pos,
                                                                     normal_world, scratch.data());
      const Eigen::Vector3d p_object = plan.object_pose.inverse() * rec.point_world_m;
      const double object_mass_kg = internal::SegmentModalMassKg(object, seg, p_object);
      rec.effective_mass_kg = 1.0 / (robot_inverse_kg + 1.0 / object_mass_kg);
      rec.robot_side_mass_kg = 1.0 / robot_inverse_kg;
      const Eigen::Vector3d axis = (seg.p1 - seg.p0).normalized();
      rec.segment_x_m = (p_object - seg.p0).dot(axis);
      return rec;
    });
  }
}

// foliage: a leaf cluster brushes the tube while it overlaps the tube's cylinder
void StrikeRollout::Simulation::Leaves(double t_s, const Eigen::Isometry3d& tube) {
  const TubeConfig& tube_config = rollout.tube_;
  for (size_t l = 0; l < leaves.size(); ++l) {
    const Eigen::Vector3d local = tube.inverse() * leaves[l].first;
    const double half_length_m = 0.5 * tube_config.length_m;
    const double z_m = std::clamp(local.z(), -half_length_m, half_length_m);
    const double radial_m = std::hypot(local.x(), local.y());
    const double gap_to_leaf_m =
        std::hypot(std::max(radial_m - tube_config.outer_radius_m, 0.0), local.z() - z_m);
    const bool touching = gap_to_leaf_m < leaves[l].second;
    tracker.ObserveSoft(leaf_channel[l], touching, t_s, [&] {
      ContactRecord rec;
      rec.kind = ContactEpisode::Kind::kBrush;
      rec.time_s = t_s;
      rec.theta_rad = WrapAngle(std::atan2(local.y(), local.x()));
      rec.z_m = z_m;
      rec.point_m = SurfacePoint(tube_config, rec.z_m, rec.theta_rad);
      rec.normal = SurfaceNormal(rec.theta_rad);
      rec.point_world_m = tube * rec.point_m;
      rec.segment = -1;
      rec.object = "leaves";
      rec.material = "foliage";
      // speed of the tube surface towards the cluster
      mjtNum point[3] = {rec.point_world_m.x(), rec.point_world_m.y(), rec.point_world_m.z()};
      rec.normal_speed_m_s = internal::PointVelocityAlong(
          m, d, var.flange_body, point, tube.linear() * rec.normal, scratch.data());
      return rec;
    });
  }
}

// joint-space impedance with gravity and Coriolis compensation, clamped to the motors
void StrikeRollout::Simulation::Control(double t_s) {
  const double s = MinJerk((t_s - t_path_s) / plan.duration_s);
  for (int i = 0; i < kPandaJoints; ++i) {
    const double q_des = plan.q_start[i] + (plan.q_goal[i] - plan.q_start[i]) * s;
    const int dof = var.dof[i], act = var.actuator[i];
    const double tau_nm = stiffness[i] * (q_des - d->qpos[var.qpos[i]]) -
                          damping[i] * d->qvel[dof] + d->qfrc_bias[dof];
    d->ctrl[act] =
        std::clamp(tau_nm, m->actuator_ctrlrange[2 * act], m->actuator_ctrlrange[2 * act + 1]);
  }
}

// rows after the end hold the last state at rest
void StrikeRollout::Simulation::FinalRows() {
  if (AllFinite(d->qpos, m->nq)) {
    mj_kinematics(m, d);
    last_row = TubeRow(false);
  }
  last_row.tail<3>().setZero();
  for (; next_row < rows; ++next_row) {
    if (next_row >= proprio_rows) continue;
    result->proprio.row(next_row) = last_row;
    for (int i = 0; i < kPandaJoints; ++i) result->joints(next_row, i) = d->qpos[var.qpos[i]];
  }
}

RolloutResult StrikeRollout::Simulate(const Variant& var, const Plan& plan) const {
  RolloutResult result;
  result.timestep_s = timestep_s_;
  result.joint_speed_rate_hz = strike_.proprio_rate_hz;
  result.target_z_m = plan.target_z_m;
  result.target_theta_rad = plan.target_theta_rad;
  result.target_time_s = plan.target_time_s;
  result.object = var.object;
  result.variant = var.variant;
  result.object_pose = plan.object_pose;
  result.motion = plan.motion;
  if (!plan.invalid_reason.empty()) internal::Fail(&result, plan.invalid_reason);

  Simulation sim(*this, var, plan, &result);
  internal::StepLoop loop;
  loop.model = sim.m;
  loop.data = sim.d;
  loop.dt_s = sim.dt_s;
  loop.first_step = sim.first_step;
  loop.choose = [&sim](double t_s, int64_t step) { return sim.Choose(t_s, step); };
  loop.observe = [&sim](double t_s, int64_t step) { sim.Observe(t_s, step); };
  internal::RunSteps(loop, &sim.tracker, &result);
  if (result.valid && sim.tracker.first_hard() < 0) {
    internal::Fail(&result, "no tube contact with the object within the record");
  }
  sim.FinalRows();
  return result;
}

}  // namespace sonicboom::sim
