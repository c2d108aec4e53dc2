#include "sonicboom/core/constants.h"
#include "sonicboom/sim/strike.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::sim {
namespace {


}  // namespace

double MinJerk(double s) {
  s = std::clamp(s, 0.0, 1.0);
  return s * s * s * (10 - 15 * s + 6 * s * s);
}

double MinJerkRate(double s) {
  if (s <= 0.0 || s >= 1.0) return 0.0;
  return 30 * s * s * (1 - s) * (1 - s);
}

StrikeDraw DrawStrike(uint64_t sample_seed, const StrikeConfig& c, const SceneConfig& scene,
                      const TubeConfig& tube, const AudioConfig& audio) {
  // joint 7 turns the tube about its axis (within its limits), the motion sweeps joint 1 (or 6)
  // towards the object on either side, so every theta can face the object
  Rng rng(sample_seed, Stream::kStrike);
  StrikeDraw d;
  for (int i = 0; i < kPandaJoints; ++i) d.q0[i] = c.home_joints_rad[i];
  d.q0[6] = rng.Uniform(PandaLowerLimits()[6], PandaUpperLimits()[6]);
  const std::optional<StrikeMotion> motion =
      EnumFromName<StrikeMotion>(c.motions[rng.UniformInt(c.motions.size())]);
  SONICBOOM_DEMAND(motion.has_value());  // StrikeConfig::Validate checked the names
  d.motion = *motion;
  const double coin = rng.Uniform();
  if (d.motion == StrikeMotion::kLateral) {
    d.joint = 5;
    d.side = coin < 0.5 ? -1.0 : 1.0;
  } else {
    d.joint = 0;
    d.side = d.motion == StrikeMotion::kOpposite ? -1.0 : 1.0;
  }
  const double tilt = rng.Uniform(-c.tilt_max_deg, 0.0) * kDeg;
  d.q0[1] += 0.5 * tilt;
  d.q0[3] += 0.5 * tilt;
  d.sweep_rad = rng.Uniform(c.sweep_min_deg, c.sweep_max_deg) * kDeg;
  d.contact_fraction = rng.Uniform(c.contact_fraction_min, c.contact_fraction_max);
  d.z_m = rng.Uniform(tube.contact_z_min_m, tube.contact_z_max_m);
  d.angle_offset_rad = rng.Uniform(-c.contact_angle_spread_deg, c.contact_angle_spread_deg) * kDeg;
  d.onset_s = audio.onset_time_s + rng.Uniform(-audio.onset_jitter_s, audio.onset_jitter_s);
  // the object, its variant and the aim on it
  Rng scene_rng(sample_seed, Stream::kScene);
  d.object = DrawObjectIndex(scene.objects, scene_rng.Uniform());
  d.variant = static_cast<int64_t>(
      scene_rng.UniformInt(static_cast<uint64_t>(ObjectVariants(scene.objects[d.object]))));
  d.target_u = scene_rng.Uniform();
  d.target_v = scene_rng.Uniform();
  return d;
}

std::vector<double> NoContactJointSpeed(const StrikeConfig& strike, const SceneConfig& scene,
                                        const AudioConfig& audio) {
  if (scene.mode == SceneMode::kStationary) return {};
  const double sweep_rad =
      0.5 * (strike.sweep_min_deg + strike.sweep_max_deg) * std::numbers::pi / 180.0;
  const double peak_speed = sweep_rad * MinJerkRate(0.5) / strike.sweep_duration_s;
  const auto rows =
      static_cast<int64_t>(std::ceil(audio.record_duration_s * strike.proprio_rate_hz));
  return std::vector<double>(static_cast<size_t>(rows), peak_speed);
}

void StrikeConfig::Serialize(Archive* a) {
  a->Visit("engine", &engine);
  a->Visit("home_joints_rad", &home_joints_rad);
  a->Visit("motions", &motions);
  a->Visit("sweep_min_deg", &sweep_min_deg, Bounds::Open(0.0, 90.0));
  a->Visit("sweep_max_deg", &sweep_max_deg, Bounds::Open(0.0, 90.0));
  a->Visit("sweep_duration_s", &sweep_duration_s, Bounds::Open(0.0, 10.0));
  a->Visit("contact_fraction_min", &contact_fraction_min, Bounds::Open(0.0, 1.0));
  a->Visit("contact_fraction_max", &contact_fraction_max, Bounds::Open(0.0, 1.0));
  a->Visit("contact_angle_spread_deg", &contact_angle_spread_deg, Bounds::Closed(0.0, 80.0));
  a->Visit("tilt_max_deg", &tilt_max_deg, Bounds::Closed(0.0, 30.0));
  a->Visit("proprio_rate_hz", &proprio_rate_hz, Bounds::Open(1.0, 10000.0));
  a->Visit("proprio_rows", &proprio_rows, Bounds::Closed(1, 100000));
}

void StrikeConfig::Validate() const {
  if (home_joints_rad.size() != kPandaJoints) {
    throw ConfigError(fmt::format("strike.home_joints_rad needs {} entries, got {}", kPandaJoints,
                                  home_joints_rad.size()));
  }
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  for (int i = 0; i < kPandaJoints; ++i) {
    if (home_joints_rad[i] < lo[i] || home_joints_rad[i] > hi[i]) {
      throw ConfigError(
          fmt::format("strike.home_joints_rad[{}] = {} is outside the joint limits "
                      "[{}, {}] rad",
                      i, home_joints_rad[i], lo[i], hi[i]));
    }
  }
  if (motions.empty())
    throw ConfigError("strike.motions is empty: name sweep, opposite or lateral");
  for (const std::string& m : motions) {
    if (!EnumFromName<StrikeMotion>(m)) {
      throw ConfigError(
          fmt::format("strike.motions: '{}' is not one of sweep, opposite, lateral", m));
    }
  }
  if (sweep_min_deg > sweep_max_deg) {
    throw ConfigError(fmt::format("strike.sweep_min_deg = {} exceeds strike.sweep_max_deg = {}",
                                  sweep_min_deg, sweep_max_deg));
  }
  if (contact_fraction_min > contact_fraction_max) {
    throw ConfigError(
        fmt::format("strike.contact_fraction_min = {} exceeds strike.contact_fraction_max = {}",
                    contact_fraction_min, contact_fraction_max));
  }
}

StrikeModel::StrikeModel(const StrikeConfig& strike, const SceneConfig& scene,
                         const TubeConfig& tube, const AudioConfig& audio)
    : strike_(strike), scene_(scene), tube_(tube), audio_(audio) {
  strike_.Validate();
  scene_.Validate();
  tube_.Validate();
  if (scene_.mode != SceneMode::kStrike) {
    throw ConfigError(
        fmt::format("strike.engine = kinematic cannot simulate scene.mode {}; use "
                    "strike.engine = mujoco",
                    NameOf(scene_.mode)));
  }
}

StrikeEvents StrikeModel::Generate(uint64_t sample_seed) const {
  StrikeEvents ev;
  const StrikeConfig& c = strike_;
  const StrikeDraw draw = DrawStrike(sample_seed, c, scene_, tube_, audio_);
  const ObjectConfig& object = scene_.objects[draw.object];
  const int joint = draw.joint;
  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  const JointVector q0 = draw.q0;
  const double sweep = draw.side * draw.sweep_rad;
  const double contact_fraction = draw.contact_fraction;
  const double z_contact = draw.z_m;
  const double angle_offset = draw.angle_offset_rad;

  // a tilt or sweep that leaves the joint limits cannot be executed
  for (int i = 0; i < kPandaJoints; ++i) {
    const double q_end = q0[i] + (i == joint ? sweep : 0.0);
    if (q0[i] < lo[i] || q0[i] > hi[i] || q_end < lo[i] || q_end > hi[i]) {
      ev.valid = false;
      ev.invalid_reason = fmt::format("joint {} leaves its limits", i + 1);
    }
  }

  // timing on the audio clock: contact at the nominal onset (+ jitter)
  const double t_contact = draw.onset_s;
  const double s_contact = contact_fraction;  // fraction of the sweep time at contact
  const double t_start = t_contact - s_contact * c.sweep_duration_s;
  auto joints_at = [&](double t) {
    JointVector q = q0;
    // the rod stops the sweep at contact; the tube then stays pressed against it
    const double s = std::min((t - t_start) / c.sweep_duration_s, s_contact);
    q[joint] += sweep * MinJerk(s);
    return q;
  };
  auto joint_rate = [&](double t) {
    const double s = (t - t_start) / c.sweep_duration_s;
    return s >= s_contact ? 0.0 : sweep * MinJerkRate(s) / c.sweep_duration_s;
  };

  // contact kinematics: tube velocity just before contact, by central difference
  const double dt = 1e-5;
  const auto pose_at = [&](double t) {
    return PandaForwardKinematics(joints_at(t), tube_.center_from_flange_m).tube;
  };
  const Eigen::Isometry3d tube_pose = pose_at(t_contact - dt);
  const Eigen::Isometry3d tube_pose_prev = pose_at(t_contact - 2 * dt);
  const Eigen::Vector3d axis_point_world = tube_pose * Eigen::Vector3d(0, 0, z_contact);
  const Eigen::Vector3d axis_point_prev = tube_pose_prev * Eigen::Vector3d(0, 0, z_contact);
  const Eigen::Vector3d v_world = (axis_point_world - axis_point_prev) / dt;
  const Eigen::Vector3d v_tube = tube_pose.linear().transpose() * v_world;

  // the face moving towards the rod: direction of motion about the axis, offset by the rod's place
  const double motion_theta = std::atan2(v_tube.y(), v_tube.x());
  const double theta = WrapAngle(motion_theta + angle_offset);
  const double speed_perp = std::hypot(v_tube.x(), v_tube.y());
  const double normal_speed = speed_perp * std::cos(angle_offset);

  ContactLabel& label = ev.label;
  label.z_m = z_contact;
  label.theta_rad = theta;
  label.point_m = SurfacePoint(tube_, z_contact, theta);
  label.normal = SurfaceNormal(theta);
  label.time_s = t_contact;
  label.normal_speed_m_s = normal_speed;
  ev.point_world_m = tube_pose * label.point_m;
  if (!(normal_speed > 1e-4)) {
    ev.valid = false;
    ev.invalid_reason = "no approach speed at contact";
  }

  // struck object: its fundamental's modal mass near the free tip (docs/physics.md, "Beam modes")
  const bool both_ends = object.clamp == Clamp::kBothEnds;
  const double aim_m = both_ends ? 0.5 * object.length_m : std::max(object.length_m - 0.05, 0.0);
  ContactEvent& contact = ev.contact;
  contact.time_s = t_contact;
  contact.z_m = z_contact;
  contact.theta_rad = theta;
  contact.normal_speed_m_s = normal_speed;
  contact.effective_mass_kg = BeamModalMassKg(object.LinearDensityKgM() * object.length_m,
                                              object.length_m, aim_m, both_ends);
  contact.striker_radius_m = 0.5 * object.diameter_m;
  contact.striker_youngs_modulus_pa = object.contact_youngs_modulus_pa;
  contact.striker_poisson_ratio = object.elastic.poisson_ratio;
  DescribeStruckBeam(object, aim_m, &contact);
  ev.object = object.DisplayName();
  ev.material = std::string(NameOf(object.material));

  // proprioception rows on the audio clock: tube pose (wxyz) and velocity in the base frame
  ev.proprio.resize(c.proprio_rows, kProprioFeatures);
  for (int64_t k = 0; k < c.proprio_rows; ++k) {
    const double t = k / c.proprio_rate_hz;
    const Eigen::Isometry3d pose = pose_at(t);
    const Eigen::Isometry3d next = pose_at(t + dt);
    const Eigen::Vector3d vel = (next.translation() - pose.translation()) / dt;
    const Eigen::Quaterniond quat(pose.linear());
    ev.proprio.row(k) << pose.translation().x(), pose.translation().y(), pose.translation().z(),
        quat.w(), quat.x(), quat.y(), quat.z(), vel.x(), vel.y(), vel.z();
  }

  // joint speed over the whole record, for motor noise
  const int64_t rows =
      static_cast<int64_t>(std::ceil(audio_.record_duration_s * c.proprio_rate_hz));
  ev.joint_speed_rate_hz = c.proprio_rate_hz;
  ev.joint_speed_rad_s.resize(rows);
  for (int64_t k = 0; k < rows; ++k)
    ev.joint_speed_rad_s[k] = std::abs(joint_rate(k / c.proprio_rate_hz));
  return ev;
}

}  // namespace sonicboom::sim
