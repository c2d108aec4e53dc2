#include "sonicboom/solid/solid_modes.h"

#include <tbb/parallel_for.h>

#include <Spectra/SymEigsShiftSolver.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;
using Ldlt = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>>;

double Lambda(double f_hz) {
  return std::pow(2.0 * std::numbers::pi * f_hz, 2);
}

// A - sigma I (A holds its whole diagonal)
SparseMatrix Shifted(const SparseMatrix& a, double sigma) {
  SparseMatrix s = a;
  for (int k = 0; k < s.outerSize(); ++k) {
    for (SparseMatrix::InnerIterator it(s, k); it; ++it) {
      if (it.row() == it.col()) it.valueRef() -= sigma;
    }
  }
  return s;
}

// Spectra's shift-solve operation y = (A - sigma I)^-1 x by a sparse LDL^T
class ShiftSolve {
 public:
  using Scalar = double;
  explicit ShiftSolve(const SparseMatrix& a) : a_(a) {}
  Eigen::Index rows() const { return a_.rows(); }
  Eigen::Index cols() const { return a_.cols(); }
  void set_shift(double sigma) {
    ldlt_.compute(Shifted(a_, sigma));
    if (ldlt_.info() != Eigen::Success) {
      throw NumericalError(
          fmt::format("reference modes: the LDL^T factorization at shift {:.6g} Hz failed",
                      std::sqrt(std::abs(sigma)) / (2.0 * std::numbers::pi)));
    }
  }
  void perform_op(const double* x, double* y) const {
    Eigen::Map<const Eigen::VectorXd> xv(x, a_.rows());
    Eigen::Map<Eigen::VectorXd> yv(y, a_.rows());
    yv = ldlt_.solve(xv);
  }

 private:
  const SparseMatrix& a_;
  Ldlt ldlt_;
};

// negative pivots of A - sigma I = eigenvalues of A below sigma
int64_t Inertia(const SparseMatrix& a, double sigma) {
  Ldlt ldlt(Shifted(a, sigma));
  if (ldlt.info() != Eigen::Success) {
    throw NumericalError(
        fmt::format("reference modes: the inertia count at {:.6g} 1/s^2 failed", sigma));
  }
  return (ldlt.vectorD().array() < 0.0).count();
}

struct Slice {
  double lo, hi;  // eigenvalue interval (lo, hi], 1/s^2
  int64_t count;  // modes in it, by inertia
};

// the eigenpairs of A in (lo, hi], exactly `count` of them
void SolveSlice(const SparseMatrix& a, const Slice& slice, bool with_vectors,
                Eigen::VectorXd* values, Eigen::MatrixXd* vectors) {
  const Eigen::Index n = a.rows();
  const double sigma = 0.5 * (slice.lo + slice.hi);
  int64_t nev = slice.count + std::max<int64_t>(8, slice.count / 4);
  for (int attempt = 0; attempt < 4; ++attempt) {
    nev = std::min<int64_t>(nev, n - 2);
    const int64_t ncv = std::min<int64_t>(n, std::max(2 * nev + 1, nev + 40));
    ShiftSolve op(a);
    Spectra::SymEigsShiftSolver<ShiftSolve> eigs(op, nev, ncv, sigma);
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10, Spectra::SortRule::SmallestAlge);
    if (eigs.info() == Spectra::CompInfo::Successful) {
      const Eigen::VectorXd all = eigs.eigenvalues();
      std::vector<Eigen::Index> keep;
      for (Eigen::Index i = 0; i < all.size(); ++i) {
        if (all(i) > slice.lo && all(i) <= slice.hi) keep.push_back(i);
      }
      if (static_cast<int64_t>(keep.size()) == slice.count) {
        values->resize(slice.count);
        for (size_t i = 0; i < keep.size(); ++i) (*values)(i) = all(keep[i]);
        if (with_vectors) {
          const Eigen::MatrixXd v = eigs.eigenvectors();
          vectors->resize(n, slice.count);
          for (size_t i = 0; i < keep.size(); ++i) vectors->col(i) = v.col(keep[i]);
        }
        return;
      }
    }
    nev = nev * 3 / 2 + 8;  // the interval's modes were not all nearest the shift: widen
  }
  throw NumericalError(fmt::format(
      "reference modes: the slice ({:.6g}, {:.6g}] Hz holds {} modes by inertia but the Lanczos "
      "solver did not find them all",
      std::sqrt(std::max(slice.lo, 0.0)) / (2.0 * std::numbers::pi),
      std::sqrt(slice.hi) / (2.0 * std::numbers::pi), slice.count));
}

}  // namespace

int64_t CountSolidModesBelow(const SolidTubeModel& model, double f_hz) {
  return Inertia(model.MassScaledStiffness(), Lambda(f_hz));
}

SolidModes SolveSolidModes(const SolidTubeModel& model, const SolidModeRequest& request) {
  if (!(request.max_frequency_hz > kSolidRigidBodyHz)) {
    throw ConfigError(fmt::format("reference modes: max_frequency_hz = {} must exceed {} Hz",
                                  request.max_frequency_hz, kSolidRigidBodyHz));
  }
  const SparseMatrix a = model.MassScaledStiffness();
  // slice boundaries: a negative start (below the rigid-body modes), then equal steps in
  // frequency, halved where a slice holds too many modes
  const double start = -Lambda(50.0);
  const int64_t total = Inertia(a, Lambda(request.max_frequency_hz));
  const int64_t target = std::max<int64_t>(10, request.modes_per_slice);
  const int64_t steps = std::max<int64_t>(1, (total + target - 1) / target);
  std::vector<double> bounds_hz;
  for (int64_t s = 1; s <= steps; ++s) bounds_hz.push_back(request.max_frequency_hz * s / steps);
  std::vector<int64_t> counts(bounds_hz.size());
  tbb::parallel_for(size_t{0}, bounds_hz.size(), [&](size_t i) {
    counts[i] = i + 1 == bounds_hz.size() ? total : Inertia(a, Lambda(bounds_hz[i]));
  });
  std::vector<Slice> slices;
  for (size_t i = 0; i < bounds_hz.size(); ++i) {
    const double lo = i == 0 ? start : Lambda(bounds_hz[i - 1]);
    const int64_t below = i == 0 ? 0 : counts[i - 1];
    slices.push_back({lo, Lambda(bounds_hz[i]), counts[i] - below});
  }
  for (bool split = true; split;) {
    split = false;
    for (size_t i = 0; i < slices.size(); ++i) {
      if (slices[i].count <= target * 3 / 2) continue;
      const double lo_hz = std::sqrt(std::max(slices[i].lo, 0.0)) / (2.0 * std::numbers::pi);
      const double hi_hz = std::sqrt(slices[i].hi) / (2.0 * std::numbers::pi);
      const double mid = Lambda(0.5 * (lo_hz + hi_hz));
      // the slices run contiguously from the start, below which no mode lies
      int64_t below_lo = 0;
      for (size_t j = 0; j < i; ++j) below_lo += slices[j].count;
      const int64_t in_lower = Inertia(a, mid) - below_lo;
      const Slice upper{mid, slices[i].hi, slices[i].count - in_lower};
      slices[i] = {slices[i].lo, mid, in_lower};
      slices.insert(slices.begin() + i + 1, upper);
      split = true;
      break;
    }
  }

  std::vector<Eigen::VectorXd> values(slices.size());
  std::vector<Eigen::MatrixXd> vectors(slices.size());
  const bool project = request.projection_rows.rows() > 0;
  SONICBOOM_DEMAND(!project || request.projection_rows.cols() == model.dofs());
  const Eigen::VectorXd inv_sqrt_mass = model.mass_kg().cwiseSqrt().cwiseInverse();
  std::vector<Eigen::MatrixXd> projected(slices.size());
  tbb::parallel_for(size_t{0}, slices.size(), [&](size_t i) {
    if (slices[i].count == 0) return;
    SolveSlice(a, slices[i], request.with_shapes || project, &values[i], &vectors[i]);
    if (vectors[i].size() == 0) return;
    // the mass-normalized shapes phi = M^-1/2 y, their read-outs, and the rows asked for
    vectors[i] = inv_sqrt_mass.asDiagonal() * vectors[i];
    if (project) projected[i] = request.projection_rows * vectors[i];
    if (!request.with_shapes) {
      vectors[i] = Eigen::MatrixXd();
    } else if (!request.shape_dofs.empty()) {
      Eigen::MatrixXd kept(request.shape_dofs.size(), vectors[i].cols());
      for (size_t r = 0; r < request.shape_dofs.size(); ++r) {
        kept.row(r) = vectors[i].row(request.shape_dofs[r]);
      }
      vectors[i] = std::move(kept);
    }
  });

  // gather ascending; rigid-body modes counted, elastic ones listed
  SolidModes modes;
  const double rigid = Lambda(kSolidRigidBodyHz);
  std::vector<std::pair<double, Eigen::Index>> order;  // (eigenvalue, index into where)
  std::vector<std::pair<size_t, Eigen::Index>> where;
  for (size_t s = 0; s < slices.size(); ++s) {
    for (Eigen::Index i = 0; i < values[s].size(); ++i) {
      if (values[s](i) < rigid) {
        ++modes.rigid_body_modes;
        continue;
      }
      order.emplace_back(values[s](i), static_cast<Eigen::Index>(where.size()));
      where.emplace_back(s, i);
    }
  }
  std::sort(order.begin(), order.end());
  const Eigen::Index m = static_cast<Eigen::Index>(order.size());
  modes.omega_rad_s.resize(m);
  if (request.with_shapes) {
    modes.shapes.resize(request.shape_dofs.empty() ? model.dofs() : request.shape_dofs.size(), m);
  }
  if (project) modes.projections.resize(request.projection_rows.rows(), m);
  for (Eigen::Index k = 0; k < m; ++k) {
    modes.omega_rad_s(k) = std::sqrt(order[k].first);
    const auto& [s, i] = where[order[k].second];
    if (request.with_shapes) modes.shapes.col(k) = vectors[s].col(i);
    if (project) modes.projections.col(k) = projected[s].col(i);
  }
  return modes;
}

}  // namespace sonicboom::solid
