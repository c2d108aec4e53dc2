#include "sonicboom/core/constants.h"
#include "sonicboom/sim/franka.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::sim {
namespace {


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

// Frames of joints 1-7 and the flange, chained in one pass.
std::array<Eigen::Isometry3d, kPandaJoints + 1> ChainFrames(const JointVector& q) {
  std::array<Eigen::Isometry3d, kPandaJoints + 1> frames;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int i = 0; i <= kPandaJoints; ++i) {
    t = t * DhTransform(kPandaDh[i], i < kPandaJoints ? q[i] : 0.0);
    frames[i] = t;
  }
  return frames;
}

Eigen::Isometry3d TubeFromFlange(const Eigen::Isometry3d& flange,
                                 double tube_center_from_flange_m) {
  Eigen::Isometry3d tube = flange;
  tube.translate(Eigen::Vector3d(0, 0, tube_center_from_flange_m));
  return tube;
}

using Jacobian6 = Eigen::Matrix<double, 6, kPandaJoints>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// column i: [z_i x (p - o_i); z_i]; in Craig's convention frame i's z axis is joint i's axis
Jacobian6 JacobianFromFrames(const std::array<Eigen::Isometry3d, kPandaJoints + 1>& frames,
                             const Eigen::Vector3d& point) {
  Jacobian6 jacobian;
  for (int i = 0; i < kPandaJoints; ++i) {
    const Eigen::Vector3d z = frames[i].linear().col(2);
    jacobian.col(i) << z.cross(point - frames[i].translation()), z;
  }
  return jacobian;
}

// State of one IK iterate: chain frames, tube pose and the pose error towards the target.
struct IkState {
  std::array<Eigen::Isometry3d, kPandaJoints + 1> frames;
  Eigen::Isometry3d tube;
  Vector6d error;  // [p_target - p (m); rotation vector of R_target R^T (rad, base frame)]
  double position_error_m{0.0};
  double rotation_error_rad{0.0};
  double cost{0.0};  // weighted squared error, m^2
};

// weight of the rotation error against the position error, m/rad (about the wrist's reach)
constexpr double kRotationWeightM = 0.2;

IkState EvaluateIk(const JointVector& q, const Eigen::Isometry3d& target, double offset_m) {
  IkState state;
  state.frames = ChainFrames(q);
  state.tube = TubeFromFlange(state.frames[kPandaJoints], offset_m);
  state.error.head<3>() = target.translation() - state.tube.translation();
  // rotation that takes the current orientation onto the target one, in the base frame
  const Eigen::AngleAxisd rotation(target.linear() * state.tube.linear().transpose());
  state.error.tail<3>() = rotation.angle() * rotation.axis();
  state.position_error_m = state.error.head<3>().norm();
  state.rotation_error_rad = std::abs(rotation.angle());
  state.cost =
      state.position_error_m * state.position_error_m +
      kRotationWeightM * kRotationWeightM * state.rotation_error_rad * state.rotation_error_rad;
  return state;
}

}  // namespace

const std::array<DhRow, kPandaJoints + 1>& PandaDhRows() {
  return kPandaDh;
}

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

Eigen::Matrix<double, 6, kPandaJoints> PandaTubeJacobian(const JointVector& q,
                                                         double tube_center_from_flange_m) {
  const auto frames = ChainFrames(q);
  const Eigen::Isometry3d tube = TubeFromFlange(frames[kPandaJoints], tube_center_from_flange_m);
  return JacobianFromFrames(frames, tube.translation());
}

IkResult PandaInverseKinematics(const Eigen::Isometry3d& target, const JointVector& q_seed,
                                double tube_center_from_flange_m, double tol_m, double tol_rad,
                                int max_iterations) {
  constexpr double kMaxStepRad = 0.3;   // largest joint change per iteration
  constexpr double kNullGain = 0.1;     // fraction of (q_seed - q) pulled per iteration
  constexpr double kLambdaInit = 1e-3;  // damping, m^2 (J J^T eigenvalues are ~1e-2..1)
  constexpr double kLambdaMin = 1e-12;
  constexpr double kLambdaMax = 1e3;  // beyond this the steps are negligible: stalled
  constexpr double kLambdaDown = 0.2, kLambdaUp = 10.0;
  constexpr double kLimitEps = 1e-12;   // rad: "on the limit"
  constexpr double kStallRatio = 1e-6;  // relative error decrease below which a step stalls
  constexpr int kStallSteps = 5;        // consecutive stalled steps that end the solve

  const JointVector lo = PandaLowerLimits(), hi = PandaUpperLimits();
  JointVector seed = q_seed;
  for (int i = 0; i < kPandaJoints; ++i) {
    seed[i] = std::isfinite(seed[i]) ? std::clamp(seed[i], lo[i], hi[i]) : 0.5 * (lo[i] + hi[i]);
  }
  IkResult result;
  result.q = seed;
  result.position_error_m = std::numeric_limits<double>::infinity();
  result.rotation_error_rad = std::numeric_limits<double>::infinity();
  if (!target.matrix().allFinite() || !std::isfinite(tube_center_from_flange_m)) return result;

  const auto converged = [&](const IkState& s) {
    return s.position_error_m < tol_m && s.rotation_error_rad < tol_rad;
  };
  const Vector6d weights =
      (Vector6d() << 1, 1, 1, kRotationWeightM, kRotationWeightM, kRotationWeightM).finished();

  // damped least-squares step on the joints that are free to move; a joint on a limit that the
  // step pushes outwards leaves the active set and the step is solved again without it
  const auto solve_step = [&](const Jacobian6& jw, const Vector6d& ew, const JointVector& q,
                              double lambda, bool pull) {
    Eigen::Array<bool, kPandaJoints, 1> free;
    free.setConstant(true);
    JointVector dq = JointVector::Zero();
    for (int pass = 0; pass <= kPandaJoints; ++pass) {
      Jacobian6 jf = jw;
      for (int i = 0; i < kPandaJoints; ++i) {
        if (!free[i]) jf.col(i).setZero();
      }
      const Eigen::Matrix<double, 6, 6> a =
          jf * jf.transpose() + lambda * Eigen::Matrix<double, 6, 6>::Identity();
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(a);
      dq = jf.transpose() * ldlt.solve(ew);
      if (pull) {
        JointVector toward_seed = kNullGain * (seed - q);
        for (int i = 0; i < kPandaJoints; ++i) {
          if (!free[i]) toward_seed[i] = 0.0;
        }
        // (I - J^+ J) with the damped pseudo-inverse J^+ = J^T (J J^T + lambda I)^-1
        dq += toward_seed - jf.transpose() * ldlt.solve(jf * toward_seed);
      }
      bool changed = false;
      for (int i = 0; i < kPandaJoints; ++i) {
        const bool pushed_out = (q[i] <= lo[i] + kLimitEps && dq[i] < 0.0) ||
                                (q[i] >= hi[i] - kLimitEps && dq[i] > 0.0);
        if (free[i] && pushed_out) {
          free[i] = false;
          changed = true;
        }
      }
      if (!changed) break;
    }
    for (int i = 0; i < kPandaJoints; ++i) {
      if (!free[i]) dq[i] = 0.0;
    }
    const double largest = dq.cwiseAbs().maxCoeff();
    if (largest > kMaxStepRad) dq *= kMaxStepRad / largest;
    return dq;
  };

  JointVector q = seed;
  IkState state = EvaluateIk(q, target, tube_center_from_flange_m);
  double lambda = kLambdaInit;
  int iteration = 0;
  int stalled_steps = 0;
  while (iteration < max_iterations && !converged(state)) {
    ++iteration;
    const Vector6d ew = weights.cwiseProduct(state.error);
    const Jacobian6 jw =
        weights.asDiagonal() * JacobianFromFrames(state.frames, state.tube.translation());
    bool accepted = false;
    // first with the null-space pull; if that does not lower the error, without it
    for (int variant = 0; variant < 2 && !accepted; ++variant) {
      const JointVector dq = solve_step(jw, ew, q, lambda, variant == 0);
      if (!dq.allFinite()) continue;
      const JointVector q_new = (q + dq).cwiseMax(lo).cwiseMin(hi);
      IkState trial = EvaluateIk(q_new, target, tube_center_from_flange_m);
      if (trial.cost < state.cost) {
        stalled_steps = trial.cost > (1.0 - kStallRatio) * state.cost ? stalled_steps + 1 : 0;
        q = q_new;
        state = std::move(trial);
        accepted = true;
      }
    }
    if (accepted) {
      lambda = std::max(lambda * kLambdaDown, kLambdaMin);
      if (stalled_steps >= kStallSteps) break;  // creeping along a local minimum
    } else {
      lambda *= kLambdaUp;
      if (lambda > kLambdaMax) break;  // no step lowers the error: a local minimum
    }
  }
  result.converged = converged(state);
  result.q = q;
  result.position_error_m = state.position_error_m;
  result.rotation_error_rad = state.rotation_error_rad;
  result.iterations = iteration;
  return result;
}

}  // namespace sonicboom::sim
