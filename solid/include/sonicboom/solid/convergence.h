#pragma once
/// One mesh of the reference solid's convergence study (`sonicboom reference`,
/// docs/reference_model.md): its elastic frequencies and the first arrivals at the discs of a
/// force pulse struck at a few probe points. A solved level can be kept in a cache directory
/// (checksummed, keyed by every input), so that a study resumes where it stopped and so that
/// levels solved elsewhere (apps/reference_levels, which needs no libtorch) are read back.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sonicboom/core/tube.h"
#include "sonicboom/solid/reference_tube.h"

namespace sonicboom::solid {

/// A probe strike: where the pulse is applied on the outer surface.
struct ConvergenceProbe {
  double z_m{0.0};
  double theta_deg{0.0};
};

/// The probes every convergence study strikes: inside the contact region, between and in front
/// of discs.
std::vector<ConvergenceProbe> DefaultConvergenceProbes();

struct ConvergenceRequest {
  // the tube, material (its loss_factor damps the probe pulse's response), discs, structure and
  // mesh, every elastic mode up to its max_frequency_hz; its cache_dir keeps the level ("" =
  // solve, keep nothing)
  ReferenceTubeConfig solid;
  std::vector<ConvergenceProbe> probes = DefaultConvergenceProbes();
};

struct ConvergenceLevel {
  double h_m{0.0};  // the mesh's element length
  int64_t dofs{0};
  double build_s{0.0}, solve_s{0.0};     // as solved (a cached level keeps its first timing)
  std::vector<double> f_hz;              // elastic modes, ascending, Hz
  std::vector<std::vector<double>> t_s;  // (probe) x (disc) first arrival, s
  bool from_cache{false};
};

/// The level of `request`: read from request.cache_dir when a file of the same key is there,
/// else solved (and written there when cache_dir is set).
ConvergenceLevel SolveConvergenceLevel(const ConvergenceRequest& request);

/// The text a level's file is keyed by: every input of the solve and of the arrivals.
std::string ConvergenceLevelKey(const ConvergenceRequest& request);

/// The first arrival at each sensor of the probe pulse (solid_response.h, 20 % of each sensor's
/// own peak) through a model's modes: omega (modes) rad/s, sensor_modal (sensors x modes) each
/// sensor's read-out of each shape, probe_modal (probes x modes) each probe's drive of each shape.
/// (probe) x (sensor), s. The one measurement every rung of the study gets.
std::vector<std::vector<double>> ProbeArrivals(const Eigen::VectorXd& omega_rad_s,
                                               const Eigen::MatrixXd& sensor_modal,
                                               const Eigen::MatrixXd& probe_modal,
                                               double loss_factor);

}  // namespace sonicboom::solid
