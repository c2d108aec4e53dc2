#include "sonicboom/sim/mujoco_scene.h"

#include <fmt/format.h>
#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <array>
#include <vector>

#include "internal/mujoco_util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::sim {
namespace {

constexpr const char* kFlangeSite = "flange";
constexpr const char* kTubeSite = "tube_center";

using internal::DataPtr;

Eigen::Isometry3d SitePose(const mjData* data, int site) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Map<const Eigen::Vector3d>(data->site_xpos + 3 * site);
  pose.linear() =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(data->site_xmat + 9 * site);
  return pose;
}

}  // namespace

struct PandaScene::Impl {
  mjModel* model{nullptr};
  std::array<int, kPandaJoints> qpos_address{};  // qpos index of panda_joint1..7
  std::array<int, kPandaJoints> dof_address{};   // dof index of panda_joint1..7
  int flange_site{-1};
  int tube_site{-1};

  ~Impl() {
    if (model != nullptr) mj_deleteModel(model);
  }

  // fresh mjData with the Panda joints at q (rad), other coordinates at the model's reference
  DataPtr MakeData(const JointVector& q) const {
    DataPtr data(mj_makeData(model));
    SONICBOOM_DEMAND(data != nullptr);
    for (int i = 0; i < kPandaJoints; ++i) data->qpos[qpos_address[i]] = q[i];
    return data;
  }
};

PandaScene::PandaScene(const std::string& mjcf_xml) : impl_(std::make_unique<Impl>()) {
  impl_->model = internal::CompileMjcf(mjcf_xml, "the Panda MJCF").release();

  // the joints and sites every query needs
  const mjModel* m = impl_->model;
  for (int i = 0; i < kPandaJoints; ++i) {
    const std::string name = fmt::format("panda_joint{}", i + 1);
    const int joint = mj_name2id(m, mjOBJ_JOINT, name.c_str());
    if (joint < 0 || m->jnt_type[joint] != mjJNT_HINGE) {
      throw ConfigError(fmt::format("MuJoCo Panda MJCF has no hinge joint named {}", name));
    }
    impl_->qpos_address[i] = m->jnt_qposadr[joint];
    impl_->dof_address[i] = m->jnt_dofadr[joint];
  }
  impl_->flange_site = mj_name2id(m, mjOBJ_SITE, kFlangeSite);
  impl_->tube_site = mj_name2id(m, mjOBJ_SITE, kTubeSite);
  if (impl_->flange_site < 0 || impl_->tube_site < 0) {
    throw ConfigError(
        fmt::format("MuJoCo Panda MJCF needs sites named {} and {}", kFlangeSite, kTubeSite));
  }
}

PandaScene::~PandaScene() = default;

int PandaScene::nq() const {
  return impl_->model->nq;
}

double PandaScene::timestep_s() const {
  return impl_->model->opt.timestep;
}

double PandaScene::TotalMass() const {
  return mj_getTotalmass(impl_->model);
}

std::vector<MujocoJointInfo> PandaScene::Joints() const {
  const mjModel* m = impl_->model;
  std::vector<MujocoJointInfo> joints(static_cast<size_t>(m->njnt));
  for (int j = 0; j < m->njnt; ++j) {
    const char* name = mj_id2name(m, mjOBJ_JOINT, j);
    joints[j].name = name != nullptr ? name : "";
    joints[j].is_hinge = m->jnt_type[j] == mjJNT_HINGE;
    joints[j].is_limited = m->jnt_limited[j] != 0;
    joints[j].lower_rad = m->jnt_range[2 * j];
    joints[j].upper_rad = m->jnt_range[2 * j + 1];
  }
  return joints;
}

std::vector<std::pair<double, double>> PandaScene::JointRanges() const {
  std::vector<std::pair<double, double>> ranges;
  for (const auto& joint : Joints()) ranges.emplace_back(joint.lower_rad, joint.upper_rad);
  return ranges;
}

std::vector<std::pair<double, double>> PandaScene::ControlRanges() const {
  const mjModel* m = impl_->model;
  std::vector<std::pair<double, double>> ranges;
  for (int a = 0; a < m->nu; ++a) {
    ranges.emplace_back(m->actuator_ctrlrange[2 * a], m->actuator_ctrlrange[2 * a + 1]);
  }
  return ranges;
}

PandaPoses PandaScene::SitePoses(const JointVector& q) const {
  DataPtr data = impl_->MakeData(q);
  mj_kinematics(impl_->model, data.get());
  PandaPoses poses;
  poses.flange = SitePose(data.get(), impl_->flange_site);
  poses.tube = SitePose(data.get(), impl_->tube_site);
  return poses;
}

JointVector PandaScene::GravityTorques(const JointVector& q) const {
  // at zero velocity the bias force qfrc_bias is the gravity torque alone
  DataPtr data = impl_->MakeData(q);
  mj_forward(impl_->model, data.get());
  JointVector tau_nm;
  for (int i = 0; i < kPandaJoints; ++i) tau_nm[i] = data->qfrc_bias[impl_->dof_address[i]];
  return tau_nm;
}

const mjModel* PandaScene::model() const {
  return impl_->model;
}

double PandaScene::FlangeEffectiveMassKg(const JointVector& q, const Eigen::Vector3d& point_m,
                                         const Eigen::Vector3d& normal) const {
  DataPtr data = impl_->MakeData(q);
  mj_forward(impl_->model, data.get());
  const int body = impl_->model->site_bodyid[impl_->flange_site];
  std::vector<mjtNum> scratch(static_cast<size_t>(5 * impl_->model->nv));
  const mjtNum point[3] = {point_m.x(), point_m.y(), point_m.z()};
  return 1.0 / internal::InverseEffectiveMass(impl_->model, data.get(), body, point, normal,
                                              scratch.data());
}

int PandaScene::ContactCount(const JointVector& q) const {
  DataPtr data = impl_->MakeData(q);
  mj_forward(impl_->model, data.get());
  return data->ncon;
}

}  // namespace sonicboom::sim
