#pragma once
/// Haptic mapping (paper §V-C): localized taps placed in the world with the arm's logged tube
/// pose form a point cloud of what the tube touched, scored against the true contact points.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <vector>

#include "sonicboom/sim/scene.h"

namespace sonicboom::experiments {

/// Unidirectional RMS Chamfer distance from the points `from` (3 x N) to the set `to` (3 x M):
/// sqrt(mean over i of min over j |from_i - to_j|^2), in the points' unit; NaN when either set is
/// empty. Brute force, O(N M): a map holds hundreds to thousands of taps.
double RmsChamfer(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to);

/// A point of the tube's outer surface at (z, theta) of the tube frame, in the frame `tube_pose`
/// maps the tube frame to (the base frame for a logged pose), m.
Eigen::Vector3d TubeSurfacePoint(const Eigen::Isometry3d& tube_pose, double z_m, double theta_rad,
                                 double radius_m);

/// Distance from p to the object made of the capsules `segments` (each its axis p0-p1 and its
/// radius, one frame with p), m: |min over capsules of (distance to the axis - radius)|, exact
/// outside the object and the depth in the deepest capsule inside it; NaN without segments.
double SurfaceDistance(const std::vector<sim::ObjectSegment>& segments, const Eigen::Vector3d& p);

/// The scores of a map, cm: MED between corresponding predicted and true points, the RMS Chamfer
/// distance from the predicted cloud to the true one (the paper's) and back, and, where the
/// mapped object's geometry is known, the RMS distance of each cloud to its surface (the true
/// cloud's is the check that the placement is right: a contact lies on what it touched).
struct MapScores {
  int64_t taps{0};
  double med_cm{0.0};
  double chamfer_cm{0.0};          // predicted -> true
  double reverse_chamfer_cm{0.0};  // true -> predicted
  double surface_cm{std::numeric_limits<double>::quiet_NaN()};       // predicted -> surface
  double true_surface_cm{std::numeric_limits<double>::quiet_NaN()};  // true -> surface
};
/// surface: the mapped object's segments in the points' frame (empty: unknown, NaN scores).
MapScores ScoreMap(const Eigen::Matrix3Xd& predicted_m, const Eigen::Matrix3Xd& true_m,
                   const std::vector<sim::ObjectSegment>& surface = {});

}  // namespace sonicboom::experiments
