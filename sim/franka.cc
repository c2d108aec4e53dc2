#include "sonicboom/sim/franka.h"

#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Craig (modified) DH rows: a_{i-1} (m), d_i (m), alpha_{i-1} (rad); joints 1-7, then flange
constexpr std::array<DhRow, kPandaJoints + 1> kPandaDh = {{
    {0.0, 0.333, 0.0},
    {0.0, 0.0, -kPi / 2},
    {0.0, 0.316, kPi / 2},
    {0.0825, 0.0, kPi / 2},
    {-0.0825, 0.384, -kPi / 2},
    {0.0, 0.0, kPi / 2},
    {0.088, 0.0, kPi / 2},
    {0.0, 0.107, 0.0},  // flange, fixed
}};

// T = RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
Eigen::Isometry3d DhTransform(const DhRow& row, double theta) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.rotate(Eigen::AngleAxisd(row.alpha_rad, Eigen::Vector3d::UnitX()));
  t.translate(Eigen::Vector3d(row.a_m, 0, 0));
  t.rotate(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()));
  t.translate(Eigen::Vector3d(0, 0, row.d_m));
  return t;
}

}  // namespace

const std::array<DhRow, kPandaJoints + 1>& PandaDhRows() { return kPandaDh; }

JointVector PandaLowerLimits() {
  JointVector q;
  q << -2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973;
  return q;
}

JointVector PandaUpperLimits() {
  JointVector q;
  q << 2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973;
  return q;
}

Eigen::Isometry3d PandaLinkPose(const JointVector& q, int frame) {
  SONICBOOM_DEMAND(frame >= 1 && frame <= 8);
  // chain the DH transforms up to the requested frame
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int i = 0; i < frame; ++i) t = t * DhTransform(kPandaDh[i], i < kPandaJoints ? q[i] : 0.0);
  return t;
}

PandaPoses PandaForwardKinematics(const JointVector& q, double tube_center_from_flange_m) {
  PandaPoses poses;
  poses.flange = PandaLinkPose(q, 8);
  // tube frame: flange frame shifted along its z axis, same orientation
  poses.tube = poses.flange;
  poses.tube.translate(Eigen::Vector3d(0, 0, tube_center_from_flange_m));
  return poses;
}

}  // namespace sonicboom::sim
