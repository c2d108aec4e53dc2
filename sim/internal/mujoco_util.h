#pragma once
/// MuJoCo helpers shared by the sim .cc files (private to the sim module: includes mujoco.h).

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <memory>
#include <string>

namespace sonicboom::sim::internal {

struct DataDeleter {
  void operator()(mjData* data) const { mj_deleteData(data); }
};
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

struct ModelDeleter {
  void operator()(mjModel* model) const { mj_deleteModel(model); }
};
using ModelPtr = std::unique_ptr<mjModel, ModelDeleter>;

/// Compiles MJCF text from memory (through a MuJoCo virtual file system), installing the
/// process-wide MuJoCo error and warning hooks first (see mujoco_scene.h). Throws ConfigError
/// with MuJoCo's message, prefixed by `what`, when the model does not load.
ModelPtr CompileMjcf(const std::string& xml, const std::string& what);

/// Name of the first MuJoCo warning raised on `d` that makes a simulation untrustworthy, or
/// nullptr.
const char* RaisedWarning(const mjData* d);

/// Every value finite.
bool AllFinite(const mjtNum* values, int n);

/// A geom's name, or "geom <id>".
std::string GeomName(const mjModel* m, int geom);

/// Id of a named object; throws ConfigError naming it where the model lacks it.
int RequireId(const mjModel* m, mjtObj type, const std::string& name);

/// Shortest distance between segments [p0, p1] and [q0, q1], m.
double SegmentDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                       const Eigen::Vector3d& q0, const Eigen::Vector3d& q1);

/// Inverse of the effective mass (1/kg) that body `body` shows at world point `point` along the
/// unit direction `normal`: n^T J M^-1 J^T n, with d's kinematics and mass matrix current.
/// `scratch` holds 5 nv values.
double InverseEffectiveMass(const mjModel* m, mjData* d, int body, const mjtNum point[3],
                            const Eigen::Vector3d& normal, mjtNum* scratch);

/// Velocity (m/s) of body `body`'s point `point` (world) along the unit direction `normal`:
/// n^T J qdot. `scratch` holds 3 nv values.
double PointVelocityAlong(const mjModel* m, const mjData* d, int body, const mjtNum point[3],
                          const Eigen::Vector3d& normal, mjtNum* scratch);

}  // namespace sonicboom::sim::internal
