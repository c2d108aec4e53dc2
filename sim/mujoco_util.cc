#include "internal/mujoco_util.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <utility>

#include "sonicboom/core/errors.h"

namespace sonicboom::sim::internal {
namespace {

constexpr const char* kVfsFileName = "sonicboom_scene.xml";

// MuJoCo's contract: mju_user_error must not return. We log and abort rather than throw, since an
// exception must not unwind through MuJoCo's C frames. Load errors never get here: mj_loadXML
// reports them through its error buffer, which CompileMjcf turns into ConfigError.
[[noreturn]] void MujocoErrorHandler(const char* message) {
  spdlog::critical("MuJoCo error: {}", message);
  std::abort();
}

void MujocoWarningHandler(const char* message) {
  spdlog::warn("MuJoCo warning: {}", message);
}

// Process-global MuJoCo hooks, installed once; handlers someone else installed are kept
void InstallMujocoHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (mju_user_error == nullptr) mju_user_error = MujocoErrorHandler;
    if (mju_user_warning == nullptr) mju_user_warning = MujocoWarningHandler;
  });
}

// Owns a heap mjVFS (it is ~2 MB) and the file buffers MuJoCo allocated in it
struct VfsDeleter {
  void operator()(mjVFS* vfs) const {
    mj_deleteVFS(vfs);
    delete vfs;
  }
};

}  // namespace

ModelPtr CompileMjcf(const std::string& xml, const std::string& what) {
  InstallMujocoHandlers();
  // hand the text to MuJoCo as an in-memory file
  std::unique_ptr<mjVFS, VfsDeleter> vfs(new mjVFS);
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), kVfsFileName, static_cast<int>(xml.size())) != 0) {
    throw ConfigError(fmt::format("{}: cannot create the in-memory MJCF file", what));
  }
  const int file = mj_findFileVFS(vfs.get(), kVfsFileName);
  SONICBOOM_DEMAND(file >= 0);
  std::memcpy(vfs->filedata[file], xml.data(), xml.size());

  char error[1024] = "";
  ModelPtr model(mj_loadXML(kVfsFileName, vfs.get(), error, sizeof(error)));
  if (model == nullptr) throw ConfigError(fmt::format("MuJoCo could not load {}: {}", what, error));
  if (error[0] != '\0') spdlog::warn("MuJoCo loaded {} with: {}", what, error);
  return model;
}

const char* RaisedWarning(const mjData* d) {
  static constexpr std::array<std::pair<int, const char*>, 6> kWarnings = {{
      {mjWARN_BADQACC, "mjWARN_BADQACC (bad acceleration)"},
      {mjWARN_BADQPOS, "mjWARN_BADQPOS (bad position)"},
      {mjWARN_BADQVEL, "mjWARN_BADQVEL (bad velocity)"},
      {mjWARN_CONTACTFULL, "mjWARN_CONTACTFULL (contact buffer full)"},
      {mjWARN_CNSTRFULL, "mjWARN_CNSTRFULL (constraint buffer full)"},
      {mjWARN_INERTIA, "mjWARN_INERTIA (singular inertia)"},
  }};
  for (const auto& [index, name] : kWarnings) {
    if (d->warning[index].number > 0) return name;
  }
  return nullptr;
}

bool AllFinite(const mjtNum* values, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(values[i])) return false;
  }
  return true;
}

std::string GeomName(const mjModel* m, int geom) {
  const char* name = mj_id2name(m, mjOBJ_GEOM, geom);
  return name != nullptr ? name : fmt::format("geom {}", geom);
}

int RequireId(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw ConfigError(fmt::format("the MuJoCo scene has no {}", name));
  return id;
}

// Ericson, Real-Time Collision Detection, 5.1.9
double SegmentDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                       const Eigen::Vector3d& q0, const Eigen::Vector3d& q1) {
  constexpr double kTiny = 1e-18;
  const Eigen::Vector3d d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= kTiny && e <= kTiny) return r.norm();
  if (a <= kTiny) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= kTiny) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > kTiny ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p0 + s * d1 - (q0 + t * d2)).norm();
}

double InverseEffectiveMass(const mjModel* m, mjData* d, int body, const mjtNum point[3],
                            const Eigen::Vector3d& normal, mjtNum* scratch) {
  // scratch: jacp (3 nv), J^T n (nv), M^-1 J^T n (nv)
  const int nv = m->nv;
  mjtNum* jacp = scratch;
  mjtNum* jt_n = scratch + 3 * nv;
  mjtNum* minv_jt_n = scratch + 4 * nv;
  mj_jac(m, d, jacp, nullptr, point, body);
  for (int k = 0; k < nv; ++k) {
    jt_n[k] = normal.x() * jacp[k] + normal.y() * jacp[nv + k] + normal.z() * jacp[2 * nv + k];
  }
  mj_solveM(m, d, minv_jt_n, jt_n, 1);
  double inverse_mass = 0.0;
  for (int k = 0; k < nv; ++k) inverse_mass += jt_n[k] * minv_jt_n[k];
  return inverse_mass;
}

double PointVelocityAlong(const mjModel* m, const mjData* d, int body, const mjtNum point[3],
                          const Eigen::Vector3d& normal, mjtNum* scratch) {
  const int nv = m->nv;
  mj_jac(m, d, scratch, nullptr, point, body);
  double speed = 0.0;
  for (int k = 0; k < nv; ++k) {
    speed += (normal.x() * scratch[k] + normal.y() * scratch[nv + k] +
              normal.z() * scratch[2 * nv + k]) *
             d->qvel[k];
  }
  return speed;
}

}  // namespace sonicboom::sim::internal
