#pragma once
/// What one dynamic simulation of a strike produces (rollout.h, stationary.h): its tube contact
/// episodes, proprioception, joint log and the strike it aimed at. No MuJoCo in here.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/core/sample.h"

namespace sonicboom::sim {

/// One tube contact episode with one object segment (or a leaf cluster), from touch to release.
struct ContactRecord : ContactEpisode {
  // ContactEpisode: time and duration on the audio clock, raw MuJoCo point and outward
  // (tube to object) unit normal in the tube frame, z and theta from the raw point, approach
  // speed at touch, effective mass (robot side in series with the object side), impulse, peak
  // force, kind, object name and material. A brush has the tube point nearest the leaf cluster's
  // centre, no force and no effective mass.
  Eigen::Vector3d point_world_m{Eigen::Vector3d::Zero()};  // (3) raw MuJoCo point, base frame
  int segment{0};                                          // object segment (leaf cluster: -1)
  double segment_radius_m{0.0};                            // its radius (the contact's curvature)
  double segment_x_m{0.0};                                 // contact from the segment's base, m
  double robot_side_mass_kg{0.0};                          // tube side at the contact (0 = held)
};

/// Outcome of one rollout.
struct RolloutResult {
  bool valid{true};
  std::string invalid_reason;             // empty when valid
  std::vector<ContactRecord> contacts;    // in time order
  Eigen::MatrixXf proprio;                // (proprio_rows x 10) tube frame in the base frame:
                                          // pos m, quat wxyz, lin vel m/s; row k at k / rate
  Eigen::MatrixXd joints;                 // (proprio_rows x 7) arm joint angles, rad, same rows
                                          // (MuJoCo strikes only; empty where the arm is held)
  std::vector<double> joint_speed_rad_s;  // (ceil(record s x rate)) |qdot| 2-norm, rad/s
  double joint_speed_rate_hz{100.0};
  // the sampled strike
  double target_z_m{0.0};  // intended first contact, tube frame
  double target_theta_rad{0.0};
  double target_time_s{0.0};                                     // intended onset, audio clock
  int object{0};                                                 // index into scene.objects
  int64_t variant{0};                                            // its geometry variant
  Eigen::Isometry3d object_pose{Eigen::Isometry3d::Identity()};  // object frame -> base frame
  std::string motion;  // sweep, opposite, lateral; guided: tap name
  // the simulation
  double timestep_s{0.0};
  int64_t steps{0};
  double simulated_s{0.0};
};

}  // namespace sonicboom::sim
