// Contact labels from geometry: Embree point queries from samples of the tube surface to an
// object mesh (triangles) or point cloud (one user primitive per point), pose by pose along a
// logged trajectory.
#include "sonicboom/core/constants.h"
#include "sonicboom/hardware/geometry.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::hardware {
namespace {

using Vec = Eigen::Vector3f;

// The point of triangle abc closest to p (by the Voronoi region of p: a vertex, an edge or the
// face).
Vec ClosestOnTriangle(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
  const Vec ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  }
  const float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

struct ContactLabeler::Impl {
  ContactRule rule;
  ObjectGeometry object;
  RTCDevice device{nullptr};
  RTCScene scene{nullptr};
  Eigen::AlignedBox3f bounds;       // the object's, base frame
  Eigen::Matrix3Xf samples;         // (3 x rows*ring) tube-frame surface samples, row-major
  int64_t rows{0}, ring{0};         // axial rows (z ascending) of `ring` samples each
  std::vector<float> sample_theta;  // (S)

  // one point query: the squared distance from p to the object, kept below the query radius
  struct Query {
    const Impl* impl;
    float best2;
    bool found;
  };
  static bool Visit(RTCPointQueryFunctionArguments* args) {
    auto* q = static_cast<Query*>(args->userPtr);
    const ObjectGeometry& o = q->impl->object;
    const Vec p(args->query->x, args->query->y, args->query->z);
    Vec closest;
    if (o.is_cloud()) {
      closest = o.vertices.col(args->primID);
    } else {
      const Eigen::Vector3i t = o.triangles.col(args->primID);
      closest =
          ClosestOnTriangle(p, o.vertices.col(t[0]), o.vertices.col(t[1]), o.vertices.col(t[2]));
    }
    const float d2 = (closest - p).squaredNorm();
    if (d2 >= q->best2) return false;
    q->best2 = d2;
    q->found = true;
    args->query->radius = std::sqrt(d2);
    return true;
  }
  static void PointBounds(const RTCBoundsFunctionArguments* args) {
    const auto* impl = static_cast<const Impl*>(args->geometryUserPtr);
    const auto p = impl->object.vertices.col(args->primID);
    *args->bounds_o = RTCBounds{p.x(), p.y(), p.z(), 0.0f, p.x(), p.y(), p.z(), 0.0f};
  }
  // distance from p to the object, or infinity when it is farther than `radius`
  float Distance(const Vec& p, float radius) const {
    RTCPointQuery query{p.x(), p.y(), p.z(), 0.0f, radius};
    RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    Query q{this, radius * radius, false};
    rtcPointQuery(scene, &query, &context, &Impl::Visit, &q);
    return q.found ? std::sqrt(q.best2) : std::numeric_limits<float>::infinity();
  }
};

ContactLabeler::ContactLabeler(const ObjectGeometry& object, const ContactRule& rule)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  if (object.vertices.cols() == 0) throw IoError("contact labels: the object has no vertices");
  if (!(rule.tolerance_m > 0) || !(rule.patch_margin_m >= 0) || !(rule.surface_spacing_m > 0) ||
      !(rule.outer_radius_m > 0) || !(rule.length_m > 0)) {
    throw ConfigError(
        fmt::format("contact rule: tolerance {} m, spacing {} m, radius {} m and "
                    "length {} m must be positive, patch margin {} m >= 0",
                    rule.tolerance_m, rule.surface_spacing_m, rule.outer_radius_m, rule.length_m,
                    rule.patch_margin_m));
  }
  s.rule = rule;
  s.object = object;
  for (Eigen::Index i = 0; i < object.vertices.cols(); ++i) s.bounds.extend(object.vertices.col(i));

  // the BVH: triangles, or points of negligible radius
  s.device = rtcNewDevice(nullptr);
  s.scene = rtcNewScene(s.device);
  RTCGeometry geometry;
  if (object.is_cloud()) {
    // a user primitive per point: its bounds are the point itself
    geometry = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(object.vertices.cols()));
    rtcSetGeometryUserData(geometry, &s);  // what the bounds function receives
    rtcSetGeometryBoundsFunction(geometry, &Impl::PointBounds, nullptr);
  } else {
    geometry = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                          RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                          object.vertices.cols()));
    std::copy_n(object.vertices.data(), object.vertices.size(), v);
    auto* t = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0,
                                                             RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                             object.triangles.cols()));
    for (Eigen::Index i = 0; i < object.triangles.size(); ++i)
      t[i] = static_cast<unsigned>(object.triangles.data()[i]);
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(s.scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(s.scene);

  // samples of the outer surface, tube frame: axial rows by rings
  const int64_t rows = static_cast<int64_t>(std::ceil(rule.length_m / rule.surface_spacing_m)) + 1;
  const int64_t ring =
      static_cast<int64_t>(std::ceil(2 * kPi * rule.outer_radius_m / rule.surface_spacing_m));
  s.rows = rows;
  s.ring = ring;
  s.samples.resize(3, rows * ring);
  s.sample_theta.resize(rows * ring);
  for (int64_t r = 0; r < rows; ++r) {
    const double z = -0.5 * rule.length_m + rule.length_m * r / double(rows - 1);
    for (int64_t k = 0; k < ring; ++k) {
      const double theta = -kPi + 2 * kPi * (k + 0.5) / double(ring);
      s.samples.col(r * ring + k) =
          Vec(rule.outer_radius_m * std::cos(theta), rule.outer_radius_m * std::sin(theta), z);
      s.sample_theta[r * ring + k] = static_cast<float>(theta);
    }
  }
}

ContactLabeler::~ContactLabeler() {
  if (impl_->scene) rtcReleaseScene(impl_->scene);
  if (impl_->device) rtcReleaseDevice(impl_->device);
}

GeometryLabel ContactLabeler::Label(const std::vector<Eigen::Isometry3d>& tube_poses) const {
  const Impl& s = *impl_;
  const float reach = static_cast<float>(s.rule.tolerance_m + s.rule.patch_margin_m);
  double closest_ever = std::numeric_limits<double>::infinity();
  for (size_t step = 0; step < tube_poses.size(); ++step) {
    const Eigen::Isometry3f pose = tube_poses[step].cast<float>();
    // the object's bounds in the tube frame, grown by the reach: samples outside cannot touch
    Eigen::AlignedBox3f box;
    const Eigen::Isometry3f to_tube = pose.inverse();
    for (int c = 0; c < 8; ++c)
      box.extend(to_tube * s.bounds.corner(Eigen::AlignedBox3f::CornerType(c)));
    box.min().array() -= reach;
    box.max().array() += reach;
    // where along the axis the object comes near: points of the axis every `h` whose distance
    // to the object is within R + reach (+ h, the spacing's own error); none: nothing touches
    const float h = 0.002f, radius = static_cast<float>(s.rule.outer_radius_m);
    float z_lo = std::numeric_limits<float>::infinity(), z_hi = -z_lo;
    const float half = static_cast<float>(0.5 * s.rule.length_m);
    for (float z = -half; z <= half + 0.5f * h; z += h) {
      if (s.Distance(pose * Vec(0, 0, z), radius + reach + h) <= radius + reach + h) {
        z_lo = std::min(z_lo, z - h), z_hi = std::max(z_hi, z + h);
      }
    }
    // distance of every nearby sample to the object
    std::vector<std::pair<float, Eigen::Index>> near;
    float best = std::numeric_limits<float>::infinity();
    // only the rows in [z_lo, z_hi] (one row of slack each side; the test below decides)
    const double row_pitch = s.rule.length_m / double(s.rows - 1);
    const auto row_of = [&](float z) { return (z + 0.5 * s.rule.length_m) / row_pitch; };
    const int64_t first =
        z_lo <= z_hi ? std::max<int64_t>(0, int64_t(std::floor(row_of(z_lo))) - 1) : 0;
    const int64_t last =
        z_lo <= z_hi ? std::min<int64_t>(s.rows - 1, int64_t(std::ceil(row_of(z_hi))) + 1) : -1;
    for (Eigen::Index i = first * s.ring; i < (last + 1) * s.ring; ++i) {
      const float z = s.samples(2, i);
      if (z < z_lo || z > z_hi || !box.contains(s.samples.col(i))) continue;
      const float d = s.Distance(pose * Vec(s.samples.col(i)), reach);
      if (d < reach) near.emplace_back(d, i);
      best = std::min(best, d);
    }
    closest_ever = std::min<double>(closest_ever, best);
    if (best > s.rule.tolerance_m) continue;
    // the patch: inverse-distance weighted mean of z and of θ on the circle
    GeometryLabel label;
    label.step = static_cast<int64_t>(step);
    label.distance_m = best;
    double w_sum = 0, z_sum = 0, c_sum = 0, s_sum = 0;
    for (const auto& [d, i] : near) {
      if (d > best + s.rule.patch_margin_m) continue;
      const double w = 1.0 / (d + 1e-4);
      w_sum += w;
      z_sum += w * s.samples(2, i);
      c_sum += w * std::cos(s.sample_theta[i]);
      s_sum += w * std::sin(s.sample_theta[i]);
      ++label.patch_points;
    }
    label.z_m = z_sum / w_sum;
    label.theta_rad = std::atan2(s_sum, c_sum);
    return label;
  }
  throw IoError(
      fmt::format("no contact: the object never comes within {} m of the tube over {} "
                  "poses (closest {})",
                  s.rule.tolerance_m, tube_poses.size(),
                  std::isfinite(closest_ever) ? fmt::format("{:.4f} m", closest_ever)
                                              : std::string("farther than that")));
}

}  // namespace sonicboom::hardware
