#include "sonicboom/sim/mujoco_scene.h"

#include <fmt/format.h>
#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <array>
#include <cstring>
#include <mutex>

#include "sonicboom/core/errors.h"

namespace sonicboom::sim {
namespace {

constexpr const char* kVfsFileName = "sonicboom_panda.xml";
constexpr const char* kFlangeSite = "flange";
constexpr const char* kTubeSite = "tube_center";

// MuJoCo's contract: mju_user_error must not return. We log and abort rather than throw, since an
// exception must not unwind through MuJoCo's C frames. Load errors never get here: mj_loadXML
// reports them through its error buffer, which PandaScene turns into ConfigError.
[[noreturn]] void MujocoErrorHandler(const char* message) {
  spdlog::critical("MuJoCo error: {}", message);
  std::abort();
}

void MujocoWarningHandler(const char* message) { spdlog::warn("MuJoCo warning: {}", message); }

// Process-global MuJoCo hooks, installed once; handlers someone else installed are kept
void InstallMujocoHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (mju_user_error == nullptr) mju_user_error = MujocoErrorHandler;
    if (mju_user_warning == nullptr) mju_user_warning = MujocoWarningHandler;
  });
}

// Owns one mjData for the duration of a query
struct DataDeleter {
  void operator()(mjData* data) const { mj_deleteData(data); }
};
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

// Owns a heap mjVFS (it is ~2 MB) and the file buffers MuJoCo allocated in it
struct VfsDeleter {
  void operator()(mjVFS* vfs) const {
    mj_deleteVFS(vfs);
    delete vfs;
  }
};

Eigen::Isometry3d SitePose(const mjData* data, int site) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Map<const Eigen::Vector3d>(data->site_xpos + 3 * site);
  pose.linear() = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
      data->site_xmat + 9 * site);
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
  InstallMujocoHandlers();
  // hand the text to MuJoCo as an in-memory file
  std::unique_ptr<mjVFS, VfsDeleter> vfs(new mjVFS);
  mj_defaultVFS(vfs.get());
  const int size = static_cast<int>(mjcf_xml.size());
  if (mj_makeEmptyFileVFS(vfs.get(), kVfsFileName, size) != 0) {
    throw ConfigError("MuJoCo model: cannot create the in-memory MJCF file");
  }
  const int file = mj_findFileVFS(vfs.get(), kVfsFileName);
  SONICBOOM_DEMAND(file >= 0);
  std::memcpy(vfs->filedata[file], mjcf_xml.data(), mjcf_xml.size());

  char error[1024] = "";
  impl_->model = mj_loadXML(kVfsFileName, vfs.get(), error, sizeof(error));
  if (impl_->model == nullptr) {
    throw ConfigError(fmt::format("MuJoCo could not load the Panda MJCF: {}", error));
  }
  if (error[0] != '\0') spdlog::warn("MuJoCo loaded the Panda MJCF with: {}", error);

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
    throw ConfigError(fmt::format("MuJoCo Panda MJCF needs sites named {} and {}", kFlangeSite,
                                  kTubeSite));
  }
}

PandaScene::~PandaScene() = default;

int PandaScene::nq() const { return impl_->model->nq; }

double PandaScene::timestep_s() const { return impl_->model->opt.timestep; }

double PandaScene::TotalMass() const { return mj_getTotalmass(impl_->model); }

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

const mjModel* PandaScene::model() const { return impl_->model; }

int PandaScene::ContactCount(const JointVector& q) const {
  DataPtr data = impl_->MakeData(q);
  mj_forward(impl_->model, data.get());
  return data->ncon;
}

}  // namespace sonicboom::sim
