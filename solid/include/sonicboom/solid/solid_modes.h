#pragma once
/// Natural modes of the reference solid (solid_tube.h): K phi = omega^2 M phi, solved on
/// A = M^-1/2 K M^-1/2 by Spectra's implicitly restarted shift-invert Lanczos, sliced over
/// frequency. Sylvester's inertia (the negative pivots of an LDL^T factorization of A - s I count
/// the modes below s) sizes the slices and checks that each slice found every mode it holds.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include "sonicboom/solid/solid_tube.h"

namespace sonicboom::solid {

/// Modes below this frequency are rigid-body motion of a free tube (0 in the continuum) and are
/// counted, not listed.
inline constexpr double kSolidRigidBodyHz = 20.0;

struct SolidModeRequest {
  double max_frequency_hz{20000.0};  // every elastic mode up to here
  bool with_shapes{true};            // false: frequencies only
  // with_shapes: the DOFs whose rows of the shapes are kept, ascending (empty: all)
  std::vector<int64_t> shape_dofs;
  int64_t modes_per_slice{120};  // target size of one Lanczos slice
  // (rows x dofs) linear read-outs (sensor rows, force weights, surface points) to apply to every
  // shape; no rows: none. Cheaper in memory than the shapes themselves for large meshes.
  Eigen::SparseMatrix<double, Eigen::RowMajor> projection_rows;
};

struct SolidModes {
  Eigen::VectorXd omega_rad_s;  // (modes) elastic modes, ascending, rad/s
  Eigen::MatrixXd shapes;  // (dofs x modes) mass-normalized (phi^T M phi = 1); empty if not asked
  int64_t rigid_body_modes{0};  // modes below kSolidRigidBodyHz, not listed
  Eigen::MatrixXd projections;  // (rows x modes) projection_rows * shapes; empty if not asked
};

/// Every elastic mode with frequency <= request.max_frequency_hz. Slices run concurrently
/// (oneTBB); the slice plan depends on inertia counts only, so the result does not depend on the
/// thread count. Throws NumericalError when a slice cannot find the modes its inertia promises.
SolidModes SolveSolidModes(const SolidTubeModel& model, const SolidModeRequest& request);

/// The number of modes (rigid-body ones included) below f_hz, by inertia.
int64_t CountSolidModesBelow(const SolidTubeModel& model, double f_hz);

}  // namespace sonicboom::solid
