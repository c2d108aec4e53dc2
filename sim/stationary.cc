#include "sonicboom/core/constants.h"
#include "sonicboom/sim/stationary.h"

#include <fmt/format.h>
#include <mujoco/mujoco.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "internal/episodes.h"
#include "internal/mujoco_util.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/franka_mjcf.h"
#include "sonicboom/sim/mujoco_scene.h"

namespace sonicboom::sim {
namespace {

using internal::DataPtr;
using internal::ModelPtr;
using internal::RequireId;

// the striker starts this far (m) clear of the surface at least
constexpr double kMinStartGapM = 0.002;

std::string Num(double v) {
  return fmt::format("{:.17g}", v);
}

// MJCF of the fixed tube and one free striker along its body x (grip at the origin, tip at x = L)
std::string HandStrikeMjcf(const TubeConfig& tube, const Eigen::Isometry3d& tube_pose,
                           const ObjectConfig& striker, const RolloutConfig& rollout,
                           double timestep_s) {
  const double r_out = 0.5 * striker.diameter_m;
  const double r_in = striker.wall_thickness_m > 0.0 ? r_out - striker.wall_thickness_m : 0.0;
  const double mass_kg = striker.LinearDensityKgM() * striker.length_m;
  const double axial_kg_m2 = 0.5 * mass_kg * (r_out * r_out + r_in * r_in);
  const double transverse_kg_m2 =
      mass_kg * (3.0 * (r_out * r_out + r_in * r_in) + striker.length_m * striker.length_m) / 12.0;
  const Eigen::Quaterniond q(tube_pose.linear());
  const Eigen::Vector3d p = tube_pose.translation();
  std::string xml = "<mujoco model=\"sonicboom_hand_strike\">\n";
  xml += "  <compiler angle=\"radian\" inertiafromgeom=\"false\"/>\n";
  // held in the hand: no gravity; only the tube-striker pair is tested
  xml += fmt::format(
      "  <option timestep=\"{}\" gravity=\"0 0 0\" integrator=\"Euler\" cone=\"elliptic\" "
      "collision=\"predefined\"/>\n",
      Num(timestep_s));
  xml += "  <size nconmax=\"20\" njmax=\"60\"/>\n";
  xml += "  <worldbody>\n";
  xml += fmt::format("    <body name=\"tube_body\" pos=\"{} {} {}\" quat=\"{} {} {} {}\">\n",
                     Num(p.x()), Num(p.y()), Num(p.z()), Num(q.w()), Num(q.x()), Num(q.y()),
                     Num(q.z()));
  xml += fmt::format("      <geom name=\"tube\" type=\"cylinder\" size=\"{} {}\"/>\n",
                     Num(tube.outer_radius_m), Num(0.5 * tube.length_m));
  xml += "      <site name=\"tube_center\"/>\n";
  xml += "    </body>\n";
  xml += "    <body name=\"striker\" pos=\"0 0 -10\">\n";
  xml += "      <freejoint name=\"striker_joint\"/>\n";
  xml += fmt::format("      <inertial pos=\"{} 0 0\" mass=\"{}\" diaginertia=\"{} {} {}\"/>\n",
                     Num(0.5 * striker.length_m), Num(mass_kg), Num(axial_kg_m2),
                     Num(transverse_kg_m2), Num(transverse_kg_m2));
  xml += fmt::format(
      "      <geom name=\"striker\" type=\"cylinder\" fromto=\"0 0 0 {} 0 0\" size=\"{}\"/>\n",
      Num(striker.length_m), Num(r_out));
  xml += "    </body>\n";
  xml += "  </worldbody>\n";
  xml += "  <contact>\n";
  xml += fmt::format(
      "    <pair geom1=\"tube\" geom2=\"striker\" condim=\"3\" friction=\"{} {} 0.005 0.0001 "
      "0.0001\" solref=\"{} {}\" solimp=\"0.9 0.95 0.001 0.5 2\" margin=\"0\" gap=\"0\"/>\n",
      Num(rollout.contact_friction), Num(rollout.contact_friction),
      Num(rollout.contact_timeconst_s), Num(rollout.contact_dampratio));
  xml += "  </contact>\n";
  xml += "</mujoco>\n";
  return xml;
}

// The random part of one hand strike (streams kScene and kStrike of the sample seed): the
// striker, the commanded point (z snapped to the grid), speed, approach tilt, grip side, onset.
struct HandDraw {
  int object{0};
  double z_m{0.0}, theta_rad{0.0}, speed_m_s{0.0};
  double tilt_rad{0.0}, tilt_azimuth_rad{0.0};
  double grip_side{1.0};
  double onset_s{0.0};  // audio clock
};

HandDraw DrawHandStrike(uint64_t sample_seed, const SceneConfig& scene, const TubeConfig& tube,
                        const AudioConfig& audio) {
  const StationaryConfig& sc = scene.stationary;
  HandDraw h;
  Rng scene_rng(sample_seed, Stream::kScene);
  h.object = DrawObjectIndex(scene.objects, scene_rng.Uniform());
  Rng rng(sample_seed, Stream::kStrike);
  h.z_m = rng.Uniform(tube.contact_z_min_m, tube.contact_z_max_m);
  if (sc.z_grid_m > 0.0) {
    h.z_m = std::clamp(std::round(h.z_m / sc.z_grid_m) * sc.z_grid_m, tube.contact_z_min_m,
                       tube.contact_z_max_m);
  }
  h.theta_rad = rng.Uniform(-kPi, kPi);
  h.speed_m_s = rng.Uniform(sc.speed_min_m_s, sc.speed_max_m_s);
  h.tilt_rad = sc.approach_spread_deg * kDeg * std::sqrt(rng.Uniform());
  h.tilt_azimuth_rad = rng.Uniform(0.0, 2.0 * kPi);
  h.grip_side = rng.Uniform() < 0.5 ? -1.0 : 1.0;
  h.onset_s = audio.onset_time_s + rng.Uniform(-audio.onset_jitter_s, audio.onset_jitter_s);
  return h;
}

// Where the hand takes the striker's grip end (base frame): along a straight approach at the
// drawn speed, reaching the commanded point at the onset, stopping follow_through_m inside.
struct HandPath {
  // striker frame at the touch: x along the tube's tangent across the axis (grip on either
  // side), y = the outward normal (the striker lies outside the tube)
  Eigen::Matrix3d striker_rot;
  Eigen::Vector3d dir;         // approach direction (unit)
  Eigen::Vector3d grip_start;  // grip at the start, m
  double speed_m_s{0.0};
  double t0_s{0.0};    // start, audio clock
  double stop_m{0.0};  // travel at which the hand stops

  HandPath(const HandDraw& draw, const ObjectConfig& object, const StationaryConfig& sc,
           const TubeConfig& tube, const Eigen::Isometry3d& tube_pose) {
    const Eigen::Matrix3d rot = tube_pose.linear();
    const Eigen::Vector3d n = rot * SurfaceNormal(draw.theta_rad);
    const Eigen::Vector3d axis = rot.col(2);
    const Eigen::Vector3d x_s = draw.grip_side * axis.cross(n).normalized();
    striker_rot << x_s, n, x_s.cross(n);
    const double r_s = 0.5 * object.diameter_m;
    const double aim_x_m = std::max(object.length_m - sc.tip_margin_m, 0.5 * object.length_m);
    const Eigen::Vector3d surface_point = tube_pose * SurfacePoint(tube, draw.z_m, draw.theta_rad);
    // the striker origin (grip) when its surface just touches the commanded point
    const Eigen::Vector3d grip_touch = surface_point + r_s * n - aim_x_m * x_s;
    // approach direction: the inward normal tilted within the spread
    const Eigen::Vector3d t1 = axis, t2 = n.cross(axis);
    dir = (-std::cos(draw.tilt_rad) * n +
           std::sin(draw.tilt_rad) *
               (std::cos(draw.tilt_azimuth_rad) * t1 + std::sin(draw.tilt_azimuth_rad) * t2))
              .normalized();
    speed_m_s = draw.speed_m_s;
    const double approach_m = std::max(speed_m_s * sc.approach_s, kMinStartGapM);
    const double approach_s = approach_m / speed_m_s;
    t0_s = draw.onset_s - approach_s;
    grip_start = grip_touch - approach_m * dir;
    // the hand stops once follow_through_m inside the surface (along the normal)
    stop_m = approach_m + sc.follow_through_m / std::max(-dir.dot(n), 1e-3);
  }

  // the hand target at t_s: position (m) and velocity (m/s)
  void HandAt(double t_s, Eigen::Vector3d* pos, Eigen::Vector3d* vel) const {
    const double travelled_m = std::clamp(speed_m_s * (t_s - t0_s), 0.0, stop_m);
    *pos = grip_start + travelled_m * dir;
    *vel = travelled_m < stop_m ? Eigen::Vector3d(speed_m_s * dir) : Eigen::Vector3d::Zero();
  }
};

// The hand's hold on the grip: a spring and damper to the hand target (linear k and c from the
// striker mass), and a rotational spring to the striker's start orientation that gives every
// principal axis the same natural frequency and damping ratio (inertia-scaled gains); applied as
// a wrench at the centre of mass.
struct Grip {
  int body;
  Eigen::Vector3d inertia_kg_m2;  // principal, body frame
  Eigen::Matrix3d rot;            // the striker's start orientation
  double damping_ratio, k_n_m, omega_n, c_ns_m;

  Grip(int striker_body, double mass_kg, const Eigen::Matrix3d& inertia, const Eigen::Matrix3d& r,
       const StationaryConfig& sc)
      : body(striker_body),
        inertia_kg_m2(inertia.diagonal()),
        rot(r),
        damping_ratio(sc.hand_damping_ratio),
        k_n_m(sc.hand_stiffness_n_m),
        omega_n(std::sqrt(k_n_m / mass_kg)),
        c_ns_m(2.0 * damping_ratio * omega_n * mass_kg) {}

  void Apply(const mjModel* m, mjData* d, const Eigen::Vector3d& hand_pos,
             const Eigen::Vector3d& hand_vel) const {
    const Eigen::Vector3d grip(d->xpos + 3 * body);
    const Eigen::Vector3d com(d->xipos + 3 * body);
    mjtNum velocity[6];  // angular (3), linear (3) at the body origin, world axes
    mj_objectVelocity(m, d, mjOBJ_BODY, body, velocity, 0);
    const Eigen::Vector3d omega(velocity[0], velocity[1], velocity[2]);
    const Eigen::Vector3d grip_vel(velocity[3], velocity[4], velocity[5]);
    const Eigen::Vector3d force = k_n_m * (hand_pos - grip) + c_ns_m * (hand_vel - grip_vel);
    const Eigen::Matrix3d body_rot =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d->xmat + 9 * body);
    const Eigen::AngleAxisd error(rot * body_rot.transpose());
    const Eigen::Vector3d error_body = body_rot.transpose() * (error.angle() * error.axis());
    const Eigen::Vector3d omega_body = body_rot.transpose() * omega;
    const Eigen::Vector3d spring_body = inertia_kg_m2.cwiseProduct(
        omega_n * omega_n * error_body - 2.0 * damping_ratio * omega_n * omega_body);
    const Eigen::Vector3d torque = body_rot * spring_body + (grip - com).cross(force);
    for (int k = 0; k < 3; ++k) {
      d->xfrc_applied[6 * body + k] = force[k];
      d->xfrc_applied[6 * body + 3 + k] = torque[k];
    }
  }
};

}  // namespace

struct HandStrikeRollout::Striker {
  ModelPtr model;
  int body{-1};
  int qpos{-1};  // free joint: position (3) and quaternion (4)
  int dof{-1};   // free joint: linear (3) and angular (3) velocity
  int striker_geom{-1};
  int tube_geom{-1};
  double mass_kg{0.0};
  Eigen::Matrix3d inertia_kg_m2{Eigen::Matrix3d::Zero()};  // about the COM, body frame
};

HandStrikeRollout::HandStrikeRollout(const TubeConfig& tube, const AudioConfig& audio,
                                     const StrikeConfig& strike, const SceneConfig& scene,
                                     const RolloutConfig& rollout)
    : tube_(tube), audio_(audio), strike_(strike), scene_(scene), config_(rollout) {
  tube_.Validate();
  strike_.Validate();
  scene_.Validate();
  config_.Validate();
  if (scene_.mode != SceneMode::kStationary) {
    throw ConfigError(fmt::format("HandStrikeRollout needs scene.mode stationary (mode is {})",
                                  NameOf(scene_.mode)));
  }
  timestep_s_ = config_.ResolvedTimestep();

  // the held pose and its proprioception row (zero velocity)
  for (int i = 0; i < kPandaJoints; ++i) q_home_[i] = strike_.home_joints_rad[i];
  tube_pose_ = PandaForwardKinematics(q_home_, tube_.center_from_flange_m).tube;
  const Eigen::Quaterniond quat(tube_pose_.linear());
  const Eigen::Vector3d p = tube_pose_.translation();
  held_row_ << p.x(), p.y(), p.z(), quat.w(), quat.x(), quat.y(), quat.z(), 0, 0, 0;
  arm_ = std::make_unique<PandaScene>(PandaMjcf(tube_));

  // one striker scene per object drawn
  for (size_t o = 0; o < scene_.objects.size(); ++o) {
    const ObjectConfig& object = scene_.objects[o];
    auto s = std::make_unique<Striker>();
    if (object.weight > 0.0) {
      s->model =
          internal::CompileMjcf(HandStrikeMjcf(tube_, tube_pose_, object, config_, timestep_s_),
                                fmt::format("the striker scene of scene.objects.{}", o));
      const mjModel* m = s->model.get();
      s->body = RequireId(m, mjOBJ_BODY, "striker");
      const int joint = RequireId(m, mjOBJ_JOINT, "striker_joint");
      s->qpos = m->jnt_qposadr[joint];
      s->dof = m->jnt_dofadr[joint];
      s->striker_geom = RequireId(m, mjOBJ_GEOM, "striker");
      s->tube_geom = RequireId(m, mjOBJ_GEOM, "tube");
      s->mass_kg = m->body_mass[s->body];
      s->inertia_kg_m2 = Eigen::Vector3d(m->body_inertia + 3 * s->body).asDiagonal();
    }
    strikers_.push_back(std::move(s));
  }
}

HandStrikeRollout::~HandStrikeRollout() = default;

RolloutResult HandStrikeRollout::Run(uint64_t sample_index, uint64_t sample_seed) const {
  RolloutResult result;
  result.timestep_s = timestep_s_;
  result.joint_speed_rate_hz = strike_.proprio_rate_hz;
  result.motion = "hand strike";

  // the draws, and the striker's path to the commanded point
  const HandDraw draw = DrawHandStrike(sample_seed, scene_, tube_, audio_);
  result.object = draw.object;
  result.target_z_m = draw.z_m;
  result.target_theta_rad = WrapAngle(draw.theta_rad);
  result.target_time_s = draw.onset_s;
  const ObjectConfig& object = scene_.objects[static_cast<size_t>(draw.object)];
  const Striker& st = *strikers_[static_cast<size_t>(draw.object)];
  const HandPath path(draw, object, scene_.stationary, tube_, tube_pose_);
  const Grip grip(st.body, st.mass_kg, st.inertia_kg_m2, path.striker_rot, scene_.stationary);

  // proprioception: the held pose at rest, all rows
  const int64_t speed_rows =
      static_cast<int64_t>(std::ceil(audio_.record_duration_s * strike_.proprio_rate_hz));
  result.proprio = held_row_.replicate(strike_.proprio_rows, 1);
  result.joint_speed_rad_s.assign(static_cast<size_t>(speed_rows), 0.0);

  // fresh state: the striker at the start, moving with the hand
  const mjModel* m = st.model.get();
  DataPtr data(mj_makeData(m));
  SONICBOOM_DEMAND(data != nullptr);
  mjData* d = data.get();
  const Eigen::Quaterniond striker_quat(path.striker_rot);
  for (int k = 0; k < 3; ++k) d->qpos[st.qpos + k] = path.grip_start[k];
  d->qpos[st.qpos + 3] = striker_quat.w();
  d->qpos[st.qpos + 4] = striker_quat.x();
  d->qpos[st.qpos + 5] = striker_quat.y();
  d->qpos[st.qpos + 6] = striker_quat.z();
  for (int k = 0; k < 3; ++k) d->qvel[st.dof + k] = draw.speed_m_s * path.dir[k];
  mj_forward(m, d);

  // the step loop: contacts with the striker, its one episode channel, the hand's wrench
  internal::EpisodeTracker tracker(&result, tube_, audio_.record_duration_s, config_.settle_s);
  tracker.set_end_s(draw.onset_s + config_.settle_s);
  const int channel = tracker.AddHardChannel(1);
  std::vector<mjtNum> scratch(static_cast<size_t>(5 * m->nv));
  internal::StepLoop loop;
  loop.model = m;
  loop.data = d;
  loop.dt_s = timestep_s_;
  loop.first_step = static_cast<int64_t>(std::floor(path.t0_s / timestep_s_));
  loop.choose = [m](double, int64_t) { return internal::StepChoice{m, 1}; };
  loop.observe = [&](double t_s, int64_t step) {
    // every contact is the striker's on the tube; none at the start
    std::vector<int>& contacts = tracker.contacts(channel);
    for (int i = 0; i < d->ncon; ++i) {
      const mjContact& c = d->contact[i];
      if (c.dist < -config_.penetration_limit_m) {
        internal::Fail(&result, fmt::format("penetration {:.4f} mm of the striker into the tube "
                                            "at t = {:.4f} s exceeds "
                                            "rollout.penetration_limit_m = {} mm",
                                            -1e3 * c.dist, t_s, 1e3 * config_.penetration_limit_m));
      }
      contacts.push_back(i);
    }
    if (!result.valid) return;
    if (step == 0 && !contacts.empty()) {
      internal::Fail(&result, "the striker overlaps the tube at its start");
      return;
    }
    tracker.ObserveHard(channel, t_s, d, [&](const mjContact& c) {
      Eigen::Vector3d normal_world;
      ContactRecord rec = internal::TouchRecord(c, st.tube_geom, tube_pose_, t_s, &normal_world);
      rec.segment = 0;
      rec.segment_radius_m = 0.5 * object.diameter_m;
      rec.object = object.DisplayName();
      rec.material = std::string(NameOf(object.material));
      // approach speed: the striker point's velocity towards the tube (the tube is held still)
      rec.normal_speed_m_s =
          -internal::PointVelocityAlong(m, d, st.body, c.pos, normal_world, scratch.data());
      // striker (rigid, at the point) in series with the held arm at the tube point
      const double striker_inverse_kg =
          internal::InverseEffectiveMass(m, d, st.body, c.pos, normal_world, scratch.data());
      const double arm_kg = arm_->FlangeEffectiveMassKg(q_home_, rec.point_world_m, normal_world);
      rec.effective_mass_kg = 1.0 / (striker_inverse_kg + 1.0 / arm_kg);
      return rec;
    });
    if (!result.valid) return;
    Eigen::Vector3d hand_pos, hand_vel;
    path.HandAt(t_s, &hand_pos, &hand_vel);
    grip.Apply(m, d, hand_pos, hand_vel);
  };
  internal::RunSteps(loop, &tracker, &result);
  if (result.valid && tracker.first_hard() < 0) {
    internal::Fail(&result, "the striker never touched the tube");
  }
  (void)sample_index;
  return result;
}

}  // namespace sonicboom::sim
