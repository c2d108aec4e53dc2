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

}  // namespace sonicboom::sim::internal

#include <Eigen/Geometry>
#include <vector>

#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/rollout.h"

namespace sonicboom::sim::internal {

/// Velocity (m/s) of body `body`'s point `point` (world) along the unit direction `normal`:
/// n^T J qdot. `scratch` holds 3 nv values.
double PointVelocityAlong(const mjModel* m, const mjData* d, int body, const mjtNum point[3],
                          const Eigen::Vector3d& normal, mjtNum* scratch);

/// The deepest of d's contacts listed in `contacts` (indices into d->contact; not empty).
const mjContact& DeepestContact(const mjData* d, const std::vector<int>& contacts);

/// A tube contact record at touch from MuJoCo contact `c`: time, raw point (world and tube
/// frame), outward (tube to object) normal in the tube frame, z and theta from the raw point.
/// `tube_pose`: tube frame in the world; `normal_world` receives the outward normal, world.
ContactRecord TouchRecord(const mjContact& c, int tube_geom, const Eigen::Isometry3d& tube_pose,
                          double t_s, Eigen::Vector3d* normal_world);

/// Why a touch is not a trustworthy contact, or "": a raw point more than 1 mm off the tube
/// surface, or a first contact outside the contact region (never clamped).
std::string TouchProblem(const ContactRecord& rec, const TubeConfig& tube, bool first);

/// Adds one step's normal force (N) of d's listed contacts to rec's impulse and peak force.
void AccumulateForce(const mjModel* m, const mjData* d, const std::vector<int>& contacts,
                     double dt_s, ContactRecord* rec);

/// Kinds of a simulation's contact episodes, decided at release: the first hard contact is the
/// impact; a later one lasting longer than 20 ms a press; one that touched within 50 ms of the
/// previous release a bounce; any other an impact.
class EpisodeClassifier {
 public:
  /// Time since the previous release, for an episode touching at touch_s (s; huge if none).
  double SinceRelease(double touch_s) const {
    return any_release_ ? touch_s - last_release_s_ : 1e9;
  }
  /// Kind of an episode released at release_s, and the release noted.
  ContactEpisode::Kind Release(double since_release_s, double duration_s, bool first_hard,
                               double release_s) {
    any_release_ = true;
    last_release_s_ = release_s;
    if (first_hard) return ContactEpisode::Kind::kImpact;
    if (duration_s > kPressDurationS) return ContactEpisode::Kind::kPress;
    if (since_release_s <= kBounceWindowS) return ContactEpisode::Kind::kBounce;
    return ContactEpisode::Kind::kImpact;
  }

  static constexpr double kPressDurationS = 0.02;
  static constexpr double kBounceWindowS = 0.05;

 private:
  bool any_release_{false};
  double last_release_s_{0.0};
};

}  // namespace sonicboom::sim::internal
