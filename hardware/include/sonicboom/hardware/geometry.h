#pragma once
/// Labels from geometry: where a tube moving along a logged trajectory first meets an object
/// given as a mesh or a scanned point cloud (docs/captures.md). Embree stays in geometry.cc.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

namespace sonicboom::hardware {

/// An object in the robot base frame (m): a triangle mesh, or a point cloud (no triangles).
struct ObjectGeometry {
  Eigen::Matrix3Xf vertices;   // (3 x V)
  Eigen::Matrix3Xi triangles;  // (3 x F) vertex indices; empty for a point cloud
  bool is_cloud() const { return triangles.cols() == 0; }
};

/// Reads a mesh (.ply with faces, .obj, .stl ASCII or binary) or a point cloud (.ply without
/// faces, .pts: whitespace text whose first line, a point count, is skipped; .xyz: whitespace
/// text; the first three columns are x y z). `scale` multiplies every coordinate (0.001 for
/// millimetres). Throws IoError naming the file and line for a malformed or empty file, an
/// index out of range or a non-finite coordinate.
ObjectGeometry ReadObjectGeometry(const std::string& path, double scale = 1.0);

/// Writes `object` as a binary little-endian PLY (float32 vertices, triangle faces) to
/// "<path>.partial" and renames it into place. Throws IoError naming the file.
void WriteObjectPly(const std::string& path, const ObjectGeometry& object);

/// Appends a cylinder from p0 to p1 (m) of `radius_m` to `mesh` as a closed prism of `sides`
/// faces with capped ends (for objects known as cylinders: simulated rods and branches).
void AppendCylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius_m,
                    int sides, ObjectGeometry* mesh);

/// The tube surface and the contact rule.
struct ContactRule {
  double outer_radius_m{0.05355};
  double length_m{0.3048};
  double tolerance_m{0.002};        // contact: the object comes this close to the tube surface
  double patch_margin_m{0.001};     // the patch: surface points within this of the closest one
  double surface_spacing_m{0.001};  // sampling of the tube surface, axially and around
};

/// Where and when the object first met the tube.
struct GeometryLabel {
  double z_m{0.0};  // tube frame (docs/conventions.md)
  double theta_rad{0.0};
  int64_t step{0};          // first pose with the object within tolerance
  double distance_m{0.0};   // the closest surface point's distance at that step
  int64_t patch_points{0};  // surface samples averaged into the label
};

/// An object prepared once (a bounding-volume hierarchy over its triangles or points) for
/// labelling any number of trajectories. Label() is const and may run on several threads.
class ContactLabeler {
 public:
  ContactLabeler(const ObjectGeometry& object, const ContactRule& rule);
  ~ContactLabeler();
  ContactLabeler(const ContactLabeler&) = delete;
  ContactLabeler& operator=(const ContactLabeler&) = delete;

  /// `tube_poses`: the tube frame in the base frame at each logged step. The label is the
  /// inverse-distance weighted mean (z, circular mean of θ) of the surface samples within
  /// patch_margin_m of the closest one, at the first step whose closest sample lies within
  /// tolerance_m. Throws IoError when no step comes within tolerance (never a fallback).
  GeometryLabel Label(const std::vector<Eigen::Isometry3d>& tube_poses) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonicboom::hardware
