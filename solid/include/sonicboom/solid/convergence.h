#pragma once
/// One mesh of the reference solid's convergence study (`sonicboom reference`,
/// docs/reference_model.md): its elastic frequencies and the first arrivals at the discs of a
/// force pulse struck at a few probe points. A solved level can be kept in a cache directory
/// (checksummed, keyed by every input), so that a study resumes where it stopped and so that
/// levels solved elsewhere (apps/reference_levels, which needs no libtorch) are read back.

#include <cstdint>
#include <string>
#include <utility>
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
  // outer-surface points (SignaturePoints) whose displacement identifies each mode from one mesh
  // to the next (MatchModesByShape); 0: none
  int64_t signature_points{768};
};

struct ConvergenceLevel {
  double h_m{0.0};  // the mesh's element length
  int64_t dofs{0};
  double build_s{0.0}, solve_s{0.0};     // as solved (a cached level keeps its first timing)
  std::vector<double> f_hz;              // elastic modes, ascending, Hz
  std::vector<std::vector<double>> t_s;  // (probe) x (disc) first arrival, s
  // (3 signature points x modes) each mass-normalized shape's displacement (normal, arc, axis)
  // at the request's signature points, m per unit modal coordinate
  Eigen::MatrixXd signature;
  bool from_cache{false};
};

/// `count` points (z, theta) (m, rad) spread evenly over the outer surface, away from the ends
/// (|z| <= 0.45 length): a golden-angle lattice, the same for every mesh of a tube.
std::vector<std::pair<double, double>> SignaturePoints(const TubeConfig& tube, int64_t count);

/// Which mode of one mesh a mode of another is.
struct ModeMatch {
  int64_t from{-1};  // index into the `from` modes; -1: none within the window
  double mac{0.0};   // modal assurance criterion of the pair, 0 to 1
};

/// For each mode of `to` (frequencies f_to_hz, signature columns `to`), the mode of `from` with
/// the same shape: every pair within `window` relative frequency of each other is ranked by its
/// modal assurance criterion, the squared cosine between the `to` signature and the span of the
/// `from` mode (with the modes degenerate with it, within 1e-4 in frequency, since a mesh returns
/// any basis of a degenerate set; alone, (a.b)^2 / (|a|^2 |b|^2)), and pairs are taken from the
/// highest, each mode at most once. Rank matching mixes modes whose order changes between meshes;
/// this does not. (to modes)
std::vector<ModeMatch> MatchModesByShape(const std::vector<double>& f_from_hz,
                                         const Eigen::MatrixXd& from,
                                         const std::vector<double>& f_to_hz,
                                         const Eigen::MatrixXd& to, double window);

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
