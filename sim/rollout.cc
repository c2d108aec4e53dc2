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

#include "sonicboom/core/errors.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/sim/franka.h"
#include "sonicboom/sim/franka_mjcf.h"
#include "sonicboom/sim/mujoco_scene.h"

namespace sonicboom::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
// rod surface this far beyond the intended contact point at the kinematic contact pose, m
constexpr double kRodGapM = 0.001;
// largest |r - R_outer| of a raw contact point on the tube, m
constexpr double kSurfaceToleranceM = 0.001;
// a re-contact this soon after a release is a bounce, s
constexpr double kBounceWindowS = 0.05;
// a later contact lasting longer than this is a press, s
constexpr double kPressDurationS = 0.02;
// intended contact this far from the rod's free tip, m (the rod extends from there away from the
// joint-1 axis; the margin leaves room for the tube to slide along the rod while pressed)
constexpr double kTipMarginM = 0.05;
// joint-1 step (rad) of the finite difference that gives the direction of motion
constexpr double kDirectionStepRad = 1e-6;

// normalised time s in [0, 1] with MinJerk(s) = fraction (bisection; MinJerk is increasing)
double MinJerkInverse(double fraction) {
  double lo = 0.0, hi = 1.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (MinJerk(mid) < fraction ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// a step skips collision detection when every object pair is this much farther apart than it
// can close in one step, m
constexpr double kCollisionSkipSlackM = 0.001;

struct DataDeleter {
  void operator()(mjData* data) const { mj_deleteData(data); }
};
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

struct ModelDeleter {
  void operator()(mjModel* model) const { mj_deleteModel(model); }
};
using ModelPtr = std::unique_ptr<mjModel, ModelDeleter>;

// Shortest distance between segments [p0, p1] and [q0, q1] (Ericson, Real-Time Collision
// Detection, 5.1.9), m
double SegmentDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                       const Eigen::Vector3d& q0, const Eigen::Vector3d& q1) {
  constexpr double kTiny = 1e-18;
  const Eigen::Vector3d d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= kTiny && e <= kTiny) return r.norm();
  if (a <= kTiny) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= kTiny) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > kTiny ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p0 + s * d1 - (q0 + t * d2)).norm();
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

// The strike drawn from a seed, and where the rod goes.
struct SampledStrike {
  JointVector q0{JointVector::Zero()};       // rad, start (home with sampled j7 and tilt)
  double side{1.0};                          // joint-1 sweep direction
  double travel_rad{0.0};                    // joint-1 travel from q0 to the kinematic contact
  double z_m{0.0};                           // intended contact, tube frame
  double theta_rad{0.0};
  double onset_s{0.0};                       // intended contact time, audio clock
  Eigen::Vector3d rod_center_m{Eigen::Vector3d::Zero()};  // (3) base frame
  Eigen::Vector3d rod_axis{Eigen::Vector3d::UnitZ()};     // (3) base frame, unit
  std::string invalid_reason;
};

// The strike drawn as for the kinematic engine (DrawStrike), and the rod placed (see rollout.h).
SampledStrike SampleStrike(uint64_t sample_seed, const StrikeConfig& c, const TubeConfig& tube,
                           const AudioConfig& audio, double overshoot_rad) {
  const StrikeDraw draw = DrawStrike(sample_seed, c, tube, audio);
  SampledStrike s;
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  s.q0 = draw.q0;
  s.side = draw.side;
  s.z_m = draw.z_m;
  s.onset_s = draw.onset_s;
  s.travel_rad = draw.sweep_rad * MinJerk(draw.contact_fraction);

  // the start pose and the commanded goal must lie within the joint limits
  for (int i = 0; i < kPandaJoints; ++i) {
    const double q_goal = s.q0[i] + (i == 0 ? s.side * (s.travel_rad + overshoot_rad) : 0.0);
    if (s.q0[i] < lo[i] || s.q0[i] > hi[i] || q_goal < lo[i] || q_goal > hi[i]) {
      s.invalid_reason = fmt::format("joint {} leaves its limits", i + 1);
    }
  }

  // kinematic contact pose and the direction of motion of the axis point at z (tube frame)
  JointVector q_contact = s.q0;
  q_contact[0] += s.side * s.travel_rad;
  JointVector q_next = q_contact;
  q_next[0] += s.side * kDirectionStepRad;
  const Eigen::Isometry3d pose = PandaForwardKinematics(q_contact, tube.center_from_flange_m).tube;
  const Eigen::Isometry3d next = PandaForwardKinematics(q_next, tube.center_from_flange_m).tube;
  const Eigen::Vector3d axis_point = Eigen::Vector3d(0, 0, s.z_m);
  const Eigen::Vector3d motion_tube =
      pose.linear().transpose() * (next * axis_point - pose * axis_point);
  if (!(std::hypot(motion_tube.x(), motion_tube.y()) > 1e-12)) {
    s.invalid_reason = "no approach direction at contact";
  }
  const double motion_theta_rad = std::atan2(motion_tube.y(), motion_tube.x());
  s.theta_rad = WrapAngle(motion_theta_rad + draw.angle_offset_rad);

  // rod crossing the tube at 90 degrees, tangent to it at (z, theta), 1 mm beyond the surface;
  // its free tip kTipMarginM past that point, its clamped end away from the joint-1 (base z) axis
  const Eigen::Vector3d normal_world = pose.linear() * SurfaceNormal(s.theta_rad);
  const Eigen::Vector3d axis_world = pose.linear().col(2);
  const Eigen::Vector3d touch_m = pose * SurfacePoint(tube, s.z_m, s.theta_rad) +
                                  (0.5 * c.rod_diameter_m + kRodGapM) * normal_world;
  s.rod_axis = axis_world.cross(normal_world).normalized();
  const Eigen::Vector3d radial(touch_m.x(), touch_m.y(), 0.0);
  if (s.rod_axis.dot(radial) < 0.0) s.rod_axis = -s.rod_axis;
  const double tip_to_center_m = std::max(0.5 * c.rod_length_m - kTipMarginM, 0.0);
  s.rod_center_m = touch_m + tip_to_center_m * s.rod_axis;
  return s;
}

// Name of the first MuJoCo warning raised on `d` that makes a rollout untrustworthy, or nullptr.
const char* RaisedWarning(const mjData* d) {
  static constexpr std::array<std::pair<int, const char*>, 6> kWarnings = {{
      {mjWARN_BADQACC, "mjWARN_BADQACC (bad acceleration)"},
      {mjWARN_BADQPOS, "mjWARN_BADQPOS (bad position)"},
      {mjWARN_BADQVEL, "mjWARN_BADQVEL (bad velocity)"},
      {mjWARN_CONTACTFULL, "mjWARN_CONTACTFULL (contact buffer full)"},
      {mjWARN_CNSTRFULL, "mjWARN_CNSTRFULL (constraint buffer full)"},
      {mjWARN_INERTIA, "mjWARN_INERTIA (singular inertia)"},
  }};
  for (const auto& [index, name] : kWarnings) {
    if (d->warning[index].number > 0) return name;
  }
  return nullptr;
}

bool AllFinite(const mjtNum* values, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(values[i])) return false;
  }
  return true;
}

std::string GeomName(const mjModel* m, int geom) {
  const char* name = mj_id2name(m, mjOBJ_GEOM, geom);
  return name != nullptr ? name : fmt::format("geom {}", geom);
}

int RequireId(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw ConfigError(fmt::format("rollout: the MuJoCo scene has no {}", name));
  return id;
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
  a->Visit("damping_ratio", &damping_ratio, Bounds::Closed(0.0, 10.0));
  a->Visit("sweep_overshoot_deg", &sweep_overshoot_deg, Bounds::Closed(0.0, 30.0));
  a->Visit("penetration_limit_m", &penetration_limit_m, Bounds::Open(0.0, 0.1));
  a->Visit("settle_s", &settle_s, Bounds::Closed(0.0, 10.0));
}

double RolloutConfig::ResolvedTimestep() const {
  return timestep_s > 0.0 ? timestep_s : 0.25 * contact_timeconst_s;
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
  if (stiffness_nm_rad.size() != kPandaJoints) {
    throw ConfigError(fmt::format("rollout.stiffness_nm_rad needs {} entries, got {}",
                                  kPandaJoints, stiffness_nm_rad.size()));
  }
  for (size_t i = 0; i < stiffness_nm_rad.size(); ++i) {
    if (!(std::isfinite(stiffness_nm_rad[i]) && stiffness_nm_rad[i] > 0.0)) {
      throw ConfigError(fmt::format("rollout.stiffness_nm_rad[{}] = {} must be positive", i,
                                    stiffness_nm_rad[i]));
    }
  }
  // MuJoCo silently stiffens a contact time constant below two timesteps (its "refsafe" rule)
  const double dt_s = ResolvedTimestep();
  if (contact_timeconst_s < 2.0 * dt_s) {
    throw ConfigError(fmt::format(
        "rollout.contact_timeconst_s = {} s is below its limit of 2 timesteps (2 x {} s = {} s)",
        contact_timeconst_s, dt_s, 2.0 * dt_s));
  }
}

// Indices into the compiled model.
struct StrikeRollout::Ids {
  std::array<int, kPandaJoints> qpos{};      // qpos index of panda_joint1..7
  std::array<int, kPandaJoints> dof{};       // dof index of panda_joint1..7
  std::array<int, kPandaJoints> actuator{};  // panda_motor1..7
  int tube_geom{-1};
  int rod_geom{-1};
  int rod_mocap{-1};                         // index into mjData's mocap arrays
  int flange_body{-1};                       // body carrying the tube
  int tube_site{-1};
  double rod_modal_mass_kg{0.0};             // clamped rod, tip modal mass m / 4
  // The scene with contacts disabled, stepped instead where no object pair can touch: its steps
  // equal the full model's whenever collision detection would find no contact.
  ModelPtr contact_free;
  std::vector<std::array<int, 2>> pairs;     // geoms of every predefined (object) pair
  double reach_m{0.0};                       // bound on any geom point's distance to any joint axis
};

StrikeRollout::StrikeRollout(const TubeConfig& tube, const AudioConfig& audio,
                             const StrikeConfig& strike, const RolloutConfig& rollout)
    : tube_(tube), audio_(audio), strike_(strike), config_(rollout) {
  tube_.Validate();
  strike_.Validate();
  config_.Validate();
  if (!(audio_.record_duration_s > 0.0 && audio_.onset_time_s >= 0.0)) {
    throw ConfigError(fmt::format("audio.record_duration_s = {} and audio.onset_time_s = {} must "
                                  "be positive",
                                  audio_.record_duration_s, audio_.onset_time_s));
  }
  timestep_s_ = config_.ResolvedTimestep();

  // the Panda, the tube and one clamped rod
  PandaMjcfOptions options;
  options.timestep_s = timestep_s_;
  MjcfRod rod;
  rod.diameter_m = strike_.rod_diameter_m;
  rod.length_m = strike_.rod_length_m;
  rod.contact_timeconst_s = config_.contact_timeconst_s;
  rod.contact_dampratio = config_.contact_dampratio;
  rod.friction = config_.contact_friction;
  options.rods.push_back(rod);
  options.elliptic_friction_cones = true;
  // only rod contacts matter here (tube strikes, arm hits): no broad phase, no self-collision
  options.object_contacts_only = true;
  scene_ = std::make_unique<PandaScene>(PandaMjcf(tube_, options));

  const mjModel* m = scene_->model();
  ids_ = std::make_unique<Ids>();
  for (int i = 0; i < kPandaJoints; ++i) {
    const int joint = RequireId(m, mjOBJ_JOINT, fmt::format("panda_joint{}", i + 1));
    ids_->qpos[i] = m->jnt_qposadr[joint];
    ids_->dof[i] = m->jnt_dofadr[joint];
    ids_->actuator[i] = RequireId(m, mjOBJ_ACTUATOR, fmt::format("panda_motor{}", i + 1));
  }
  ids_->tube_geom = RequireId(m, mjOBJ_GEOM, "tube");
  ids_->rod_geom = RequireId(m, mjOBJ_GEOM, "rod0");
  ids_->rod_mocap = m->body_mocapid[RequireId(m, mjOBJ_BODY, "rod0")];
  SONICBOOM_DEMAND(ids_->rod_mocap >= 0);
  ids_->flange_body = m->geom_bodyid[ids_->tube_geom];
  ids_->tube_site = RequireId(m, mjOBJ_SITE, "tube_center");
  const double rod_mass_kg = strike_.rod_density_kg_m3 * 0.25 * kPi * strike_.rod_diameter_m *
                             strike_.rod_diameter_m * strike_.rod_length_m;
  ids_->rod_modal_mass_kg = 0.25 * rod_mass_kg;

  // contact-free twin and the pairs it may skip (capsules and cylinders only)
  ids_->contact_free.reset(mj_copyModel(nullptr, m));
  SONICBOOM_DEMAND(ids_->contact_free != nullptr);
  ids_->contact_free->opt.disableflags |= mjDSBL_CONTACT;
  SONICBOOM_DEMAND(m->opt.collision == mjCOL_PAIR);
  for (int p = 0; p < m->npair; ++p) {
    const int g1 = m->pair_geom1[p], g2 = m->pair_geom2[p];
    for (int g : {g1, g2}) {
      SONICBOOM_DEMAND(m->geom_type[g] == mjGEOM_CAPSULE || m->geom_type[g] == mjGEOM_CYLINDER);
    }
    ids_->pairs.push_back({g1, g2});
  }
  // chain length from any joint to any arm geom point: the arm's body and joint offsets, plus the
  // farthest geom point from its body origin (mocap rods do not move with the joints)
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
  ids_->reach_m = reach_m + geom_extent_m;
}

StrikeRollout::~StrikeRollout() = default;

RolloutResult StrikeRollout::Run(uint64_t sample_seed) const {
  const mjModel* m = scene_->model();
  const Ids& ids = *ids_;
  const double dt_s = timestep_s_;
  const double overshoot_rad = config_.sweep_overshoot_deg * kDeg;
  const SampledStrike strike = SampleStrike(sample_seed, strike_, tube_, audio_, overshoot_rad);

  RolloutResult result;
  result.timestep_s = dt_s;
  result.joint_speed_rate_hz = strike_.proprio_rate_hz;
  result.target_z_m = strike.z_m;
  result.target_theta_rad = strike.theta_rad;
  result.target_time_s = strike.onset_s;
  result.rod_center_world_m = strike.rod_center_m;
  result.rod_axis_world = strike.rod_axis;
  auto fail = [&result](std::string reason) {
    if (!result.valid) return;  // keep the first reason
    result.valid = false;
    result.invalid_reason = std::move(reason);
  };
  if (!strike.invalid_reason.empty()) fail(strike.invalid_reason);

  // fresh state: arm at q0 at rest, rod placed (mocap quat turns body z onto the rod axis)
  DataPtr data(mj_makeData(m));
  SONICBOOM_DEMAND(data != nullptr);
  mjData* d = data.get();
  for (int i = 0; i < kPandaJoints; ++i) d->qpos[ids.qpos[i]] = strike.q0[i];
  const Eigen::Quaterniond rod_quat =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), strike.rod_axis);
  for (int k = 0; k < 3; ++k) d->mocap_pos[3 * ids.rod_mocap + k] = strike.rod_center_m[k];
  d->mocap_quat[4 * ids.rod_mocap + 0] = rod_quat.w();
  d->mocap_quat[4 * ids.rod_mocap + 1] = rod_quat.x();
  d->mocap_quat[4 * ids.rod_mocap + 2] = rod_quat.y();
  d->mocap_quat[4 * ids.rod_mocap + 3] = rod_quat.z();
  mj_forward(m, d);

  // impedance gains: K from the config, D from the mass matrix diagonal at the start
  std::array<double, kPandaJoints> stiffness{}, damping{};
  for (int i = 0; i < kPandaJoints; ++i) {
    stiffness[i] = config_.stiffness_nm_rad[i];
    const double m_ii = d->qM[m->dof_Madr[ids.dof[i]]];
    damping[i] = 2.0 * config_.damping_ratio * std::sqrt(stiffness[i] * m_ii);
  }

  // joint-1 profile: reaches the rod at the onset, started earlier by the impedance lag D/K
  const double goal_rad = strike.travel_rad + overshoot_rad;
  const double s_contact = goal_rad > 0.0 ? MinJerkInverse(strike.travel_rad / goal_rad) : 0.0;
  const double lag_s = damping[0] / stiffness[0];
  const double sweep_s = strike_.sweep_duration_s;
  const double t_sweep_s = strike.onset_s - s_contact * sweep_s - lag_s;
  // step grid: multiples of dt on the audio clock from the sweep start. Before it the arm holds
  // q0 at rest (the impedance torque is the bias force at q0), so rows due earlier are the held
  // pose at zero velocity, written at the first step
  const int64_t first_step = static_cast<int64_t>(std::floor(t_sweep_s / dt_s));

  // rows on the audio clock: proprio (proprio_rows) and joint speed (the whole record)
  const int64_t proprio_rows = strike_.proprio_rows;
  const int64_t speed_rows =
      static_cast<int64_t>(std::ceil(audio_.record_duration_s * strike_.proprio_rate_hz));
  const int64_t rows = std::max(proprio_rows, speed_rows);
  result.proprio.setZero(proprio_rows, kProprioFeatures);
  result.joint_speed_rad_s.assign(static_cast<size_t>(speed_rows), 0.0);
  Eigen::Matrix<float, 1, kProprioFeatures> last_row;
  // tube-frame pose (from the kinematics in d) and velocity (from its com velocities)
  auto tube_row = [&](bool with_velocity) {
    const mjtNum* pos = d->site_xpos + 3 * ids.tube_site;
    const Eigen::Matrix3d rot =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d->site_xmat +
                                                                       9 * ids.tube_site);
    const Eigen::Quaterniond quat(rot);
    mjtNum velocity[6] = {0, 0, 0, 0, 0, 0};  // angular (3), linear (3), world axes
    if (with_velocity) mj_objectVelocity(m, d, mjOBJ_SITE, ids.tube_site, velocity, 0);
    Eigen::Matrix<float, 1, kProprioFeatures> row;
    row << pos[0], pos[1], pos[2], quat.w(), quat.x(), quat.y(), quat.z(), velocity[3],
        velocity[4], velocity[5];
    return row;
  };
  last_row = tube_row(false);
  int64_t next_row = 0;

  // contact episode bookkeeping (one rod: object 0)
  bool episode_active = false;
  bool any_release = false;
  double last_release_s = 0.0;
  std::vector<int> tube_contacts;  // indices into d->contact of tube-rod contacts, this step
  auto close_episode = [&](double t_s) {
    ContactRecord& rec = result.contacts.back();
    rec.duration_s = t_s - rec.time_s;
    const bool first = result.contacts.size() == 1;
    const double since_release_s = any_release ? rec.time_s - last_release_s : 1e9;
    if (first) {
      rec.kind = ContactEpisode::Kind::kImpact;
    } else if (rec.duration_s > kPressDurationS) {
      rec.kind = ContactEpisode::Kind::kPress;
    } else if (since_release_s <= kBounceWindowS) {
      rec.kind = ContactEpisode::Kind::kBounce;
    } else {
      rec.kind = ContactEpisode::Kind::kImpact;
    }
    episode_active = false;
    any_release = true;
    last_release_s = t_s;
  };

  double t_end_s = audio_.record_duration_s;
  std::vector<mjtNum> jacp(static_cast<size_t>(3 * m->nv)), jt_n(m->nv), minv_jt_n(m->nv);
  int64_t step = 0;
  // joint angles of the last step's kinematics; lower bound of the object pairs' gaps (m) at
  // gap_qpos
  std::array<double, kPandaJoints> last_qpos{}, gap_qpos{};
  double gap_m = -1.0;
  double t_s = first_step * dt_s;
  while (result.valid) {
    t_s = static_cast<double>(first_step + step) * dt_s;
    if (t_s >= t_end_s - 0.5 * dt_s) break;
    // Contact-free step where no pair can touch: each arm point has moved at most
    // reach * |q - gap_qpos|_1 since the pair gaps were bounded (at gap_qpos); re-bound them from
    // the last step's geom poses (at last_qpos) once that budget is spent
    auto budget_left = [&] {
      double travel_rad = 0.0;
      for (int i = 0; i < kPandaJoints; ++i) {
        travel_rad += std::abs(d->qpos[ids.qpos[i]] - gap_qpos[i]);
      }
      return gap_m - ids.reach_m * travel_rad - kCollisionSkipSlackM > 0.0;
    };
    bool may_touch = step == 0;
    if (!may_touch && !budget_left()) {
      gap_m = std::numeric_limits<double>::infinity();
      for (const auto& [g1, g2] : ids.pairs) {
        gap_m = std::min(gap_m, GeomGapLowerBound(m, d, g1, g2));
      }
      gap_qpos = last_qpos;
      may_touch = !budget_left();
    }
    const mjModel* step_model = may_touch ? m : ids.contact_free.get();
    for (int i = 0; i < kPandaJoints; ++i) last_qpos[i] = d->qpos[ids.qpos[i]];

    // positions and velocities at t: kinematics, collisions, mass matrix, bias forces
    mj_step1(step_model, d);
    if (const char* warning = RaisedWarning(d)) {
      fail(fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }

    // rows due at t
    while (next_row < rows && next_row / strike_.proprio_rate_hz <= t_s + 0.5 * dt_s) {
      last_row = tube_row(true);
      if (next_row < proprio_rows) result.proprio.row(next_row) = last_row;
      if (next_row < speed_rows) {
        double sum_sq = 0.0;
        for (int i = 0; i < kPandaJoints; ++i) sum_sq += d->qvel[ids.dof[i]] * d->qvel[ids.dof[i]];
        result.joint_speed_rad_s[next_row] = std::sqrt(sum_sq);
      }
      ++next_row;
    }

    // contacts with the rod at t
    tube_contacts.clear();
    for (int i = 0; i < d->ncon && result.valid; ++i) {
      const mjContact& c = d->contact[i];
      if (c.exclude != 0) continue;
      const bool rod_first = c.geom1 == ids.rod_geom;
      if (!rod_first && c.geom2 != ids.rod_geom) continue;
      const int other = rod_first ? c.geom2 : c.geom1;
      if (step == 0) {
        fail(fmt::format("the rod overlaps {} at the start pose", GeomName(m, other)));
      } else if (c.dist < -config_.penetration_limit_m) {
        fail(fmt::format("penetration {:.4f} mm of {} into the rod at t = {:.4f} s exceeds "
                         "rollout.penetration_limit_m = {} mm",
                         -1e3 * c.dist, GeomName(m, other), t_s,
                         1e3 * config_.penetration_limit_m));
      } else if (other == ids.tube_geom) {
        tube_contacts.push_back(i);
      } else if (result.contacts.empty()) {
        fail(fmt::format("arm hit the object before the tube ({} at t = {:.4f} s)",
                         GeomName(m, other), t_s));
      }
    }
    if (!result.valid) break;

    // episodes: touch when the first tube contact appears, release when none remains
    if (!tube_contacts.empty() && !episode_active) {
      int deepest = tube_contacts.front();
      for (int i : tube_contacts) {
        if (d->contact[i].dist < d->contact[deepest].dist) deepest = i;
      }
      const mjContact& c = d->contact[deepest];
      // outward normal: MuJoCo's normal points from geom1 to geom2
      Eigen::Vector3d normal_world(c.frame[0], c.frame[1], c.frame[2]);
      if (c.geom1 != ids.tube_geom) normal_world = -normal_world;
      const Eigen::Vector3d point_world(c.pos[0], c.pos[1], c.pos[2]);
      const Eigen::Vector3d tube_origin =
          Eigen::Map<const Eigen::Vector3d>(d->site_xpos + 3 * ids.tube_site);
      const Eigen::Matrix3d tube_rot =
          Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d->site_xmat +
                                                                         9 * ids.tube_site);

      ContactRecord rec;
      rec.time_s = t_s;
      rec.point_world_m = point_world;
      rec.point_m = tube_rot.transpose() * (point_world - tube_origin);
      rec.normal = tube_rot.transpose() * normal_world;
      rec.z_m = rec.point_m.z();
      rec.theta_rad = WrapAngle(std::atan2(rec.point_m.y(), rec.point_m.x()));
      rec.object_index = 0;

      // approach speed: tube-point velocity (J qdot) along the outward normal; the rod is fixed
      mj_jac(m, d, jacp.data(), nullptr, c.pos, ids.flange_body);
      const Eigen::Map<const Eigen::Matrix<mjtNum, Eigen::Dynamic, Eigen::Dynamic,
                                           Eigen::RowMajor>>
          jac(jacp.data(), 3, m->nv);
      const Eigen::Map<const Eigen::VectorXd> qvel(d->qvel, m->nv);
      rec.normal_speed_m_s = normal_world.dot(jac * qvel);
      // effective mass: robot side 1 / (n^T J M^-1 J^T n), in series with the rod's modal mass
      Eigen::Map<Eigen::VectorXd>(jt_n.data(), m->nv) = jac.transpose() * normal_world;
      mj_solveM(m, d, minv_jt_n.data(), jt_n.data(), 1);
      double inverse_mass = 0.0;
      for (int k = 0; k < m->nv; ++k) inverse_mass += jt_n[k] * minv_jt_n[k];
      rec.effective_mass_kg = 1.0 / (inverse_mass + 1.0 / ids.rod_modal_mass_kg);

      const double radius_m = std::hypot(rec.point_m.x(), rec.point_m.y());
      const double off_surface_m = std::abs(radius_m - tube_.outer_radius_m);
      const bool first = result.contacts.empty();
      result.contacts.push_back(rec);
      episode_active = true;
      if (off_surface_m >= kSurfaceToleranceM) {
        fail(fmt::format("contact point off the tube surface by {:.3f} mm at t = {:.4f} s",
                         1e3 * off_surface_m, t_s));
      } else if (first && (rec.z_m < tube_.contact_z_min_m || rec.z_m > tube_.contact_z_max_m)) {
        fail(fmt::format("first contact at z = {:.4f} m outside the contact region [{}, {}] m",
                         rec.z_m, tube_.contact_z_min_m, tube_.contact_z_max_m));
      }
      if (first) t_end_s = std::min(t_end_s, t_s + config_.settle_s);
    } else if (tube_contacts.empty() && episode_active) {
      close_episode(t_s);
    }
    if (!result.valid) break;

    // joint-space impedance with gravity and Coriolis compensation, clamped to the motors
    const double q1_des =
        strike.q0[0] + strike.side * goal_rad * MinJerk((t_s - t_sweep_s) / sweep_s);
    for (int i = 0; i < kPandaJoints; ++i) {
      const double q_des = i == 0 ? q1_des : strike.q0[i];
      const int dof = ids.dof[i], act = ids.actuator[i];
      const double tau_nm = stiffness[i] * (q_des - d->qpos[ids.qpos[i]]) -
                            damping[i] * d->qvel[dof] + d->qfrc_bias[dof];
      d->ctrl[act] = std::clamp(tau_nm, m->actuator_ctrlrange[2 * act],
                                m->actuator_ctrlrange[2 * act + 1]);
    }

    // actuation, constraint forces, integration to t + dt
    mj_step2(step_model, d);
    ++step;
    if (const char* warning = RaisedWarning(d)) {
      fail(fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }
    if (!AllFinite(d->qpos, m->nq) || !AllFinite(d->qvel, m->nv)) {
      fail(fmt::format("non-finite state at t = {:.4f} s", t_s + dt_s));
      break;
    }
    // normal force of this step's tube contacts (solved in mj_step2)
    if (episode_active) {
      double normal_force_n = 0.0;
      for (int i : tube_contacts) {
        mjtNum force[6];
        mj_contactForce(m, d, i, force);
        normal_force_n += force[0];
      }
      ContactRecord& rec = result.contacts.back();
      rec.impulse_Ns += normal_force_n * dt_s;
      rec.peak_force_N = std::max(rec.peak_force_N, normal_force_n);
    }
  }
  const double t_final_s = static_cast<double>(first_step + step) * dt_s;
  if (episode_active) close_episode(t_final_s);
  result.steps = step;
  result.simulated_s = static_cast<double>(step) * dt_s;
  if (result.valid && result.contacts.empty()) fail("no tube contact within the record");

  // rows after the end hold the last state at rest
  if (AllFinite(d->qpos, m->nq)) {
    mj_kinematics(m, d);
    last_row = tube_row(false);
  }
  last_row.tail<3>().setZero();
  for (; next_row < rows; ++next_row) {
    if (next_row < proprio_rows) result.proprio.row(next_row) = last_row;
  }
  return result;
}

}  // namespace sonicboom::sim
