// Labels from geometry: object file readers, and the labeller against scenes whose contact point
// is known exactly (a tube driven into a sphere scan or a rod mesh along the surface normal).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>

#include "common/test_util.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/hardware/geometry.h"

namespace sonicboom::hardware {
namespace {

using sonicboom::testing::TempDir;
using sonicboom::testing::ThrownMessage;
using ::testing::HasSubstr;
using sonicboom::kPi;
constexpr double kR = 0.05355;

// A tetrahedron in every format.
void WriteTetra(const TempDir& dir) {
  std::ofstream(dir / "t.obj")
      << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2/5/5 4\nf -4 3 4\nf 2 3 4\n";
  std::ofstream(dir / "t.ply")
      << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n";
  std::ofstream(dir / "t.stl")
      << "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
         "endloop\nendfacet\nendsolid t\n";
  std::ofstream(dir / "t.pts") << "4\n0 0 0 9\n1 0 0 9\n0 1 0 9\n0 0 1 9\n";
  std::ofstream(dir / "t.xyz") << "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
  // binary PLY: 4 float vertices, no faces (a cloud)
  std::ofstream bin(dir / "b.ply", std::ios::binary);
  bin << "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float "
         "y\nproperty float z\nend_header\n";
  const float v[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  bin.write(reinterpret_cast<const char*>(v), sizeof(v));
}

TEST(GeometryTest, ReadsMeshesAndCloudsInEveryFormat) {
  TempDir dir;
  WriteTetra(dir);
  for (const char* name : {"t.obj", "t.ply"}) {
    const ObjectGeometry g = ReadObjectGeometry(dir / name, 0.5);
    EXPECT_EQ(g.vertices.cols(), 4) << name;
    EXPECT_EQ(g.triangles.cols(), 4) << name;
    EXPECT_FLOAT_EQ(g.vertices(2, 3), 0.5f) << name;
  }
  EXPECT_EQ(ReadObjectGeometry(dir / "t.stl").triangles.cols(), 1);
  for (const char* name : {"t.pts", "t.xyz", "b.ply"}) {
    const ObjectGeometry g = ReadObjectGeometry(dir / name);
    EXPECT_TRUE(g.is_cloud()) << name;
    EXPECT_EQ(g.vertices.cols(), 4) << name;
    EXPECT_FLOAT_EQ(g.vertices(1, 2), 1.0f) << name;
  }
  std::ofstream(dir / "bad.obj") << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadObjectGeometry(dir / "bad.obj"); }),
              HasSubstr("bad.obj:3: vertex index 6 is out of range"));
  std::ofstream(dir / "nan.xyz") << "0 0 0\nnan 1 2\n";
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadObjectGeometry(dir / "nan.xyz"); }),
              HasSubstr("nan.xyz:2: a coordinate is not finite"));
  std::ofstream(dir / "x.dae") << "<xml/>";
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadObjectGeometry(dir / "x.dae"); }),
              HasSubstr("unknown object format"));
}

TEST(GeometryTest, WrittenPlyReadsBackExactly) {
  TempDir dir;
  ObjectGeometry rod;
  AppendCylinder({0.1, -0.2, 0.3}, {0.4, 0.1, 0.35}, 0.011, 24, &rod);
  WriteObjectPly(dir / "rod.ply", rod);
  EXPECT_FALSE(std::filesystem::exists(dir / "rod.ply.partial"));
  const ObjectGeometry back = ReadObjectGeometry(dir / "rod.ply");
  EXPECT_EQ(back.vertices, rod.vertices);
  EXPECT_EQ(back.triangles, rod.triangles);
  EXPECT_THAT(ThrownMessage<IoError>([&] { WriteObjectPly(dir / "no/such/dir/x.ply", rod); }),
              HasSubstr("x.ply: cannot write"));
}

// A sphere scan (Fibonacci points) of radius r around c.
ObjectGeometry SphereCloud(const Eigen::Vector3d& c, double r, int n) {
  ObjectGeometry g;
  g.vertices.resize(3, n);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, phi = i * kPi * (3.0 - std::sqrt(5.0));
    const double s = std::sqrt(1.0 - z * z);
    g.vertices.col(i) =
        (c + r * Eigen::Vector3d(s * std::cos(phi), s * std::sin(phi), z)).cast<float>();
  }
  return g;
}

// A rod of radius r and length l along unit u through c, as a closed 32-sided prism mesh.
ObjectGeometry RodMesh(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double r, double l) {
  ObjectGeometry g;
  AppendCylinder(c - 0.5 * l * u, c + 0.5 * l * u, r, 32, &g);
  return g;
}

TEST(GeometryTest, LabelsKnownContactsOfSphereScansAndRodMeshes) {
  // 100 scenes: a random tube pose, a random contact point (z0, θ0), the object placed 10-30 mm
  // off the surface along its normal there, the tube driven into it at 1 mm per logged pose
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> errors_mm;
  for (int scene = 0; scene < 100; ++scene) {
    const double z0 = -0.12 + 0.24 * unit(rng), theta0 = -kPi + 2 * kPi * unit(rng);
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
    start.linear() = Eigen::Quaterniond::UnitRandom().toRotationMatrix();  // std rng not used here
    start.translation() = Eigen::Vector3d(0.4, -0.2, 0.5);
    const Eigen::Vector3d normal(std::cos(theta0), std::sin(theta0), 0.0);
    const Eigen::Vector3d tangent(-std::sin(theta0), std::cos(theta0), 0.0);
    const double gap = 0.010 + 0.020 * unit(rng);
    ObjectGeometry object;
    if (scene % 2 == 0) {
      const double r = 0.02 + 0.02 * unit(rng);
      object = SphereCloud(start * ((kR + gap + r) * normal + Eigen::Vector3d(0, 0, z0)), r, 6000);
    } else {
      const double r = 0.005 + 0.010 * unit(rng), tilt = -1.2 + 2.4 * unit(rng);  // off the axis
      const Eigen::Vector3d along =
          start.linear() * (std::cos(tilt) * tangent + std::sin(tilt) * Eigen::Vector3d::UnitZ());
      object =
          RodMesh(start * ((kR + gap + r) * normal + Eigen::Vector3d(0, 0, z0)), along, r, 0.4);
    }
    std::vector<Eigen::Isometry3d> poses;
    for (int k = 0; k < 60; ++k) {
      Eigen::Isometry3d pose = start;
      pose.translation() += start.linear() * normal * (0.001 * k);
      poses.push_back(pose);
    }
    const GeometryLabel label = ContactLabeler(object, ContactRule{}).Label(poses);
    errors_mm.push_back(1e3 *
                        SurfaceDistance(TubeConfig{}, label.z_m, label.theta_rad, z0, theta0));
  }
  std::sort(errors_mm.begin(), errors_mm.end());
  const double median = errors_mm[50], p95 = errors_mm[95];
  std::cout << "label error over 100 scenes: median " << median << " mm, p95 " << p95
            << " mm, worst " << errors_mm.back() << " mm, failures 0\n";
  EXPECT_LT(median, 0.5);
  EXPECT_LT(p95, 1.0);
}

TEST(GeometryTest, NoContactIsAnErrorNeverAFallback) {
  const ObjectGeometry far = SphereCloud(Eigen::Vector3d(1.0, 0, 0), 0.02, 500);
  std::vector<Eigen::Isometry3d> still(20, Eigen::Isometry3d::Identity());
  EXPECT_THAT(ThrownMessage<IoError>([&] { ContactLabeler(far, ContactRule{}).Label(still); }),
              HasSubstr("no contact: the object never comes within 0.002 m"));
  ContactRule bad;
  bad.tolerance_m = 0;
  EXPECT_THROW(ContactLabeler(far, bad), ConfigError);
}

}  // namespace
}  // namespace sonicboom::hardware
