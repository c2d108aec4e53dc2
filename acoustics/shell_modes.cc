#include "sonicboom/acoustics/shell_modes.h"

#include <tbb/parallel_for.h>
#include <tbb/task_group.h>
#include <Eigen/Eigenvalues>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <iterator>
#include <map>
#include <memory>
#include <numbers>
#include <set>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

constexpr int64_t kMaxModes = 20000;
// modes a slice of the spectrum is planned to hold, and the most it may hold before it is split
constexpr int64_t kSliceModes = 60;
constexpr int64_t kMaxSliceModes = 90;
// the first inertia probe of a count request, and the most probes one planning round adds above
// the highest one (fixed numbers: the plan must not depend on the thread count)
constexpr double kFirstProbeHz = 1000.0;
constexpr int kProbesPerRound = 4;
// slices narrower than this (relative) are not split further (a cluster of repeated eigenvalues)
constexpr double kNarrowestSlice = 1e-6;
// Lanczos: residual tolerance relative to the Ritz value, and reruns (found modes deflated)
constexpr double kTolerance = 1e-10;
constexpr int kMaxReruns = 3;
// block width of the Lanczos method: the factor is read once per block of right-hand sides, and an
// eigenvalue repeated up to this many times is found in one run
constexpr int kBlock = 4;
// a factorization whose solves are off by more than this (about 30 times rounding) is redone at a
// shift moved a little
constexpr double kSolveError = 3e-10;
// matrices smaller than this are solved densely
constexpr Eigen::Index kSmallestSparse = 16 * kBlock;

using SpMat = Eigen::SparseMatrix<double>;
using Perm = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;
// the matrix comes already in a fill-reducing order, so the factorization keeps the natural one
using Ldlt = Eigen::SimplicialLDLT<SpMat, Eigen::Upper, Eigen::NaturalOrdering<int>>;
// Lanczos blocks and the basis are row-major: the kBlock values of a block's row are adjacent
using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, kBlock, Eigen::RowMajor>;
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

double Hz(double lambda) {
  return std::sqrt(std::max(lambda, 0.0)) / (2.0 * kPi);
}
double Lambda(double hz) {
  return std::pow(2.0 * kPi * hz, 2);
}

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  int64_t ns() const {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() -
                                                                start_)
        .count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// where the time goes, summed over threads (debug log)
struct Stats {
  std::atomic<int64_t> factorizations{0}, factor_ns{0}, vectors{0}, solve_ns{0},
      orthogonalize_ns{0};
  std::atomic<int64_t> lanczos_ns{0}, reruns{0}, ritz_checks{0};
};

double Seconds(const std::atomic<int64_t>& ns) {
  return 1e-9 * static_cast<double>(ns.load());
}

// reproducible uniform numbers in (-0.5, 0.5) (splitmix64) for the start blocks
class Random {
 public:
  explicit Random(uint64_t seed) : state_(seed) {}
  double Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53 - 0.5;
  }

 private:
  uint64_t state_;
};

// A = M^-1/2 K M^-1/2 put once in a fill-reducing (AMD) order: every shift factorizes the same
// pattern, and the eigenvectors go back to the DOF order at the end
class OrderedMatrix {
 public:
  explicit OrderedMatrix(const SpMat& a) {
    Perm inverse;
    Eigen::AMDOrdering<int>()(a, inverse);
    perm_ = inverse.inverse();
    SpMat upper(a.rows(), a.cols());
    upper.selfadjointView<Eigen::Upper>() = a.selfadjointView<Eigen::Upper>().twistedBy(perm_);
    ordered_ = upper.selfadjointView<Eigen::Upper>();
    // Gershgorin: every eigenvalue lies below the largest absolute row sum
    for (Eigen::Index j = 0; j < a.outerSize(); ++j) {
      double sum = 0.0;
      for (SpMat::InnerIterator it(a, j); it; ++it) sum += std::abs(it.value());
      bound_ = std::max(bound_, sum);
    }
  }
  Eigen::Index rows() const { return ordered_.rows(); }
  double upper_bound() const { return bound_; }
  Eigen::MatrixXd Dense() const { return Eigen::MatrixXd(ordered_); }

  // L D L^T of A - sigma I from the upper triangle (the symbolic analysis of the ordered pattern is
  // cheap); a zero pivot throws
  std::shared_ptr<const Ldlt> Factor(double sigma, Stats* stats) const {
    const Stopwatch watch;
    auto ldlt = std::make_shared<Ldlt>();
    ldlt->analyzePattern(ordered_);
    ldlt->setShift(-sigma);
    ldlt->factorize(ordered_);
    if (ldlt->info() != Eigen::Success) {
      throw Error(fmt::format("shell modes: the factorization at {} Hz failed", Hz(sigma)));
    }
    ++stats->factorizations;
    stats->factor_ns += watch.ns();
    return ldlt;
  }

  // relative residual |x - (A - sigma I) y| / |x| of a solve by the factorization at sigma: a
  // little above rounding, unless its pivots grew (L D L^T of an indefinite matrix has no pivoting)
  // or sigma nearly hits an eigenvalue
  double SolveError(const Ldlt& ldlt, double sigma) const {
    Random random(0);
    Eigen::VectorXd x(rows());
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = random.Next();
    const Eigen::VectorXd y = ldlt.solve(x);
    const Eigen::VectorXd r = x - (ordered_ * y - sigma * y);
    return r.norm() / x.norm();
  }

  // a vector of the ordered matrix in the DOF order
  Eigen::VectorXd ToDofs(const Eigen::VectorXd& y) const { return perm_.transpose() * y; }

 private:
  SpMat ordered_;  // P A P^T
  Perm perm_;
  double bound_{0.0};
};

// eigenvalues below sigma (Sylvester): the negative pivots of L D L^T of A - sigma I
int64_t NegativePivots(const Ldlt& ldlt) {
  return (ldlt.vectorD().array() < 0.0).count();
}

// (A - sigma I)^-1 on a block of kBlock vectors through L D L^T: the factor is read once per block.
// Found eigenvectors (orthonormal columns Q) are projected out: P (A - sigma I)^-1 P with
// P = I - Q Q^T maps them to 0, so a rerun finds only modes not yet found.
class BlockShiftInvert {
 public:
  BlockShiftInvert(const Ldlt& ldlt, const Eigen::MatrixXd& found, Stats* stats)
      : l_(ldlt.matrixL().nestedExpression()),
        d_inv_(ldlt.vectorD().cwiseInverse()),
        q_(found),
        stats_(stats) {}
  Eigen::Index rows() const { return l_.rows(); }

  // x - Q (Q^T x)
  template <typename Block>
  void Project(Block* x) const {
    if (q_.cols() > 0) *x -= q_ * (q_.transpose() * *x);
  }

  // w = P (A - sigma I)^-1 P x
  void Apply(const RowBlock& x, RowBlock* w) const {
    const Stopwatch watch;
    *w = x;
    Project(w);
    Solve(w->data());
    Project(w);
    stats_->vectors += kBlock;
    stats_->solve_ns += watch.ns();
  }

 private:
  // L D L^T y = x in place on the row-major block
  void Solve(double* x) const {
    const int n = static_cast<int>(l_.rows());
    const int* lp = l_.outerIndexPtr();
    const int* li = l_.innerIndexPtr();
    const double* lx = l_.valuePtr();
    // L z = x by columns of L (unit diagonal, stored below it)
    for (int j = 0; j < n; ++j) {
      double xj[kBlock];
      for (int c = 0; c < kBlock; ++c) xj[c] = x[j * kBlock + c];
      for (int p = lp[j]; p < lp[j + 1]; ++p) {
        double* xi = x + static_cast<ptrdiff_t>(li[p]) * kBlock;
        const double l = lx[p];
        for (int c = 0; c < kBlock; ++c) xi[c] -= l * xj[c];
      }
    }
    // D
    for (int j = 0; j < n; ++j) {
      for (int c = 0; c < kBlock; ++c) x[j * kBlock + c] *= d_inv_[j];
    }
    // L^T y = z backwards, by the same columns
    for (int j = n - 1; j >= 0; --j) {
      double acc[kBlock];
      for (int c = 0; c < kBlock; ++c) acc[c] = x[j * kBlock + c];
      for (int p = lp[j]; p < lp[j + 1]; ++p) {
        const double* xi = x + static_cast<ptrdiff_t>(li[p]) * kBlock;
        const double l = lx[p];
        for (int c = 0; c < kBlock; ++c) acc[c] -= l * xi[c];
      }
      for (int c = 0; c < kBlock; ++c) x[j * kBlock + c] = acc[c];
    }
  }

  const SpMat& l_;
  Eigen::VectorXd d_inv_;
  const Eigen::MatrixXd& q_;  // (dofs x found)
  Stats* stats_;
};

// Two adjacent doubles (GCC / Clang vector extension, SSE2 on x86-64): the orthogonalization
// kernels work on a row of a block as kPairs of them.
using Pair = double __attribute__((vector_size(16)));
constexpr int kPairs = kBlock / 2;
static_assert(kBlock % 2 == 0);

Pair LoadPair(const double* p) {
  Pair v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
void StorePair(double* p, Pair v) {
  std::memcpy(p, &v, sizeof v);
}

// Four rows i..i+3 of a block, as pairs.
struct FourRows {
  Pair r[4][kPairs];
};
FourRows LoadFourRows(const double* wd, Eigen::Index i) {
  FourRows w;
  for (int r = 0; r < 4; ++r) {
    for (int p = 0; p < kPairs; ++p) w.r[r][p] = LoadPair(wd + (i + r) * kBlock + 2 * p);
  }
  return w;
}

// h(k, :) += sum_r V(i + r, k) w(r, :) for k < m: four rows of V (starting at v) per sweep over h
void AccumulateFourRows(const double* v, Eigen::Index ld, Eigen::Index m, const FourRows& w,
                        double* hk) {
  for (Eigen::Index k = 0; k < m; ++k) {
    Pair acc[kPairs];
    for (int p = 0; p < kPairs; ++p) acc[p] = LoadPair(hk + kBlock * k + 2 * p);
    for (int r = 0; r < 4; ++r) {
      const double x = v[r * ld + k];
      for (int p = 0; p < kPairs; ++p) acc[p] += x * w.r[r][p];
    }
    for (int p = 0; p < kPairs; ++p) StorePair(hk + kBlock * k + 2 * p, acc[p]);
  }
}

// h(k, :) += V(i, k) w(i, :) for k < m: one remaining row
void AccumulateRow(const double* v, Eigen::Index m, const double* wi, double* hk) {
  for (Eigen::Index k = 0; k < m; ++k) {
    for (int p = 0; p < kPairs; ++p) {
      StorePair(hk + kBlock * k + 2 * p,
                LoadPair(hk + kBlock * k + 2 * p) + v[k] * LoadPair(wi + 2 * p));
    }
  }
}

// h = V^T w over the first m columns of the basis V, four rows of V per sweep over h
void Coefficients(const RowMatrix& basis, Eigen::Index m, const RowBlock& w, RowBlock* h) {
  h->setZero(m, kBlock);
  double* hk = h->data();
  const double* wd = w.data();
  const Eigen::Index n = w.rows(), ld = basis.cols();
  Eigen::Index i = 0;
  for (; i + 4 <= n; i += 4)
    AccumulateFourRows(basis.data() + i * ld, ld, m, LoadFourRows(wd, i), hk);
  for (; i < n; ++i) AccumulateRow(basis.data() + i * ld, m, wd + i * kBlock, hk);
}

// w -= V h; with next, also next = V^T w of the updated w (one sweep over V for both)
void Subtract(const RowMatrix& basis, Eigen::Index m, const RowBlock& h, RowBlock* w,
              RowBlock* next) {
  if (next != nullptr) next->setZero(m, kBlock);
  const double* hk = h.data();
  double* nk = next != nullptr ? next->data() : nullptr;
  double* wd = w->data();
  const Eigen::Index n = w->rows(), ld = basis.cols();
  Eigen::Index i = 0;
  for (; i + 4 <= n; i += 4) {
    const double* v = basis.data() + i * ld;
    FourRows wr = LoadFourRows(wd, i);
    for (Eigen::Index k = 0; k < m; ++k) {
      Pair hp[kPairs];
      for (int p = 0; p < kPairs; ++p) hp[p] = LoadPair(hk + kBlock * k + 2 * p);
      for (int r = 0; r < 4; ++r) {
        const double x = v[r * ld + k];
        for (int p = 0; p < kPairs; ++p) wr.r[r][p] -= x * hp[p];
      }
    }
    for (int r = 0; r < 4; ++r) {
      for (int p = 0; p < kPairs; ++p) StorePair(wd + (i + r) * kBlock + 2 * p, wr.r[r][p]);
    }
    if (nk != nullptr) AccumulateFourRows(v, ld, m, wr, nk);
  }
  for (; i < n; ++i) {
    const double* v = basis.data() + i * ld;
    Pair wr[kPairs];
    for (int p = 0; p < kPairs; ++p) wr[p] = LoadPair(wd + i * kBlock + 2 * p);
    for (Eigen::Index k = 0; k < m; ++k) {
      for (int p = 0; p < kPairs; ++p) wr[p] -= v[k] * LoadPair(hk + kBlock * k + 2 * p);
    }
    for (int p = 0; p < kPairs; ++p) StorePair(wd + i * kBlock + 2 * p, wr[p]);
    if (nk != nullptr) AccumulateRow(v, m, wd + i * kBlock, nk);
  }
}

// Orthonormalizes the block w (already orthogonal to the basis) in place: w_in = w_out r with r
// upper triangular. A column that vanishes (the Krylov space holds an invariant subspace) gets
// r(c, c) = 0 and is replaced by a random direction orthogonal to everything before.
Eigen::MatrixXd OrthonormalizeBlock(const BlockShiftInvert& op, const RowMatrix& basis,
                                    Eigen::Index m, const Eigen::VectorXd& scale, Random* random,
                                    RowBlock* w) {
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(kBlock, kBlock);
  for (Eigen::Index c = 0; c < kBlock; ++c) {
    auto col = w->col(c);
    for (int pass = 0; pass < 2; ++pass) {
      for (Eigen::Index k = 0; k < c; ++k) {
        const double s = w->col(k).dot(col);
        r(k, c) += s;
        col -= s * w->col(k);
      }
    }
    const double norm = col.norm();
    if (norm > 1e-10 * scale[c]) {
      r(c, c) = norm;
      col /= norm;
      continue;
    }
    Eigen::VectorXd fresh(w->rows());
    for (Eigen::Index i = 0; i < fresh.size(); ++i) fresh[i] = random->Next();
    for (int pass = 0; pass < 2; ++pass) {
      op.Project(&fresh);
      fresh -= basis.leftCols(m) * (basis.leftCols(m).transpose() * fresh);
      for (Eigen::Index k = 0; k < c; ++k) fresh -= w->col(k).dot(fresh) * w->col(k);
    }
    col = fresh / fresh.norm();
  }
  return r;
}

// [lo, hi) in omega^2 holding `count` eigenvalues by inertia, solved at the shift sigma
struct Slice {
  double lo{0.0}, hi{0.0};
  int64_t count{0};
  double sigma{0.0};
};

struct SliceModes {
  std::vector<double> lambdas;
  Eigen::MatrixXd vectors;  // (dofs x found), ordered matrix
};

// Block Lanczos on (A - sigma I)^-1 with full reorthogonalization and no restart: the Krylov space
// grows until `wanted` converged Ritz values lie in the slice, or to its largest size (`size` times
// the usual for the slice; then the converged ones are kept, with their vectors, and the caller
// reruns with them deflated and a larger size).
void BlockLanczos(const BlockShiftInvert& op, const Slice& slice, int64_t wanted, int size,
                  bool with_vectors, SliceModes* out, Stats* stats) {
  const Stopwatch watch;
  const Eigen::Index n = op.rows(), b = kBlock;
  const Eigen::Index max_dim =
      std::min<Eigen::Index>((n / b) * b, ((4 * slice.count + 64) * size / b) * b);
  RowMatrix basis(n, max_dim);
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(max_dim, max_dim);  // block tridiagonal V^T op V
  Random random(static_cast<uint64_t>(size));
  // the start block: random, without the found directions
  RowBlock w(n, b);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index c = 0; c < b; ++c) w(i, c) = random.Next();
  }
  op.Project(&w);
  OrthonormalizeBlock(op, basis, 0, Eigen::VectorXd::Constant(b, w.norm()), &random, &w);
  basis.leftCols(b) = w;
  RowBlock block = w, previous, h, h2;  // the newest block of the basis and the one before
  Eigen::Index next_check = wanted + wanted / 2;  // about two converge per block step
  for (Eigen::Index m = b;; m += b) {
    // the operator on the newest block, less its three-term recurrence terms
    op.Apply(block, &w);
    const Stopwatch orthogonalize;
    const Eigen::VectorXd scale = w.colwise().norm().transpose();
    if (m > b) w -= previous * t.block(m - b, m - 2 * b, b, b).transpose();
    Eigen::MatrixXd diagonal = block.transpose() * w;
    w -= block * diagonal;
    // then against the whole basis (rounding makes the recurrence lose orthogonality), once more
    // where one pass left more than rounding
    Coefficients(basis, m, w, &h);
    Subtract(basis, m, h, &w, &h2);
    const Eigen::VectorXd norms = w.colwise().norm().transpose();
    bool again = false;
    for (Eigen::Index c = 0; c < b; ++c)
      again = again || h2.col(c).cwiseAbs().maxCoeff() > 1e-14 * norms[c];
    if (again) {
      Subtract(basis, m, h2, &w, nullptr);
      h += h2;
    }
    diagonal += h.bottomRows(b);
    t.block(m - b, m - b, b, b) = 0.5 * (diagonal + diagonal.transpose());
    const Eigen::MatrixXd r = OrthonormalizeBlock(op, basis, m, scale, &random, &w);
    stats->orthogonalize_ns += orthogonalize.ns();
    // Ritz pairs: theta of T with residual |r s_last|, eigenvalue sigma + 1 / theta; checked less
    // often while many are still missing
    const bool last = m + b > max_dim;
    if (m >= next_check || last) {
      ++stats->ritz_checks;
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(t.topLeftCorner(m, m));
      const Eigen::VectorXd& theta = eig.eigenvalues();
      const Eigen::MatrixXd residual = r * eig.eigenvectors().bottomRows(b);
      std::vector<Eigen::Index> inside;
      for (Eigen::Index k = 0; k < m; ++k) {
        const double lambda = slice.sigma + 1.0 / theta[k];
        if (lambda >= slice.lo && lambda < slice.hi &&
            residual.col(k).norm() < kTolerance * std::abs(theta[k])) {
          inside.push_back(k);
        }
      }
      const bool complete = static_cast<int64_t>(inside.size()) >= wanted;
      if (complete || last) {
        // Ritz vectors of the converged ones, V s, where the shapes are wanted or a rerun deflates
        // them
        const Eigen::Index have = out->vectors.cols(),
                           count = static_cast<Eigen::Index>(inside.size());
        Eigen::MatrixXd s(m, count);
        for (Eigen::Index c = 0; c < count; ++c) {
          const Eigen::Index k = inside[static_cast<size_t>(c)];
          out->lambdas.push_back(slice.sigma + 1.0 / theta[k]);
          s.col(c) = eig.eigenvectors().col(k);
        }
        if (with_vectors || !complete) {
          out->vectors.conservativeResize(n, have + count);
          out->vectors.rightCols(count).noalias() = basis.leftCols(m) * s;
        }
        stats->lanczos_ns += watch.ns();
        spdlog::trace(
            "shell modes: [{:.1f}, {:.1f}) Hz: {} of {} modes in a {}-vector Krylov space",
            Hz(slice.lo), Hz(slice.hi), count, wanted, m);
        return;
      }
      next_check = m + b * std::max<Eigen::Index>(
                               1, (wanted - static_cast<int64_t>(inside.size())) / (2 * b));
    }
    t.block(m, m - b, b, b) = r;
    t.block(m - b, m, b, b) = r.transpose();
    basis.middleCols(m, b) = w;
    previous.swap(block);
    block.swap(w);
  }
}

// The eigenpairs of one slice by block Lanczos on the shift-invert at its shift (its centre, where
// its eigenvalues are exactly the `count` nearest ones, or its lower end when nothing but
// rigid-body modes lies below), rerun with the found ones deflated until the inertia count is met
SliceModes SolveSlice(const OrderedMatrix& a, const Slice& slice, std::shared_ptr<const Ldlt> ldlt,
                      bool with_vectors, Stats* stats) {
  SliceModes out;
  if (a.rows() < kSmallestSparse) {
    // a tiny matrix: all eigenpairs at once
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a.Dense());
    for (Eigen::Index k = 0; k < a.rows(); ++k) {
      const double lambda = eig.eigenvalues()[k];
      if (lambda < slice.lo || lambda >= slice.hi) continue;
      out.lambdas.push_back(lambda);
      out.vectors.conservativeResize(a.rows(), out.vectors.cols() + 1);
      out.vectors.rightCols(1) = eig.eigenvectors().col(k);
    }
    return out;
  }
  // an inner shift whose solves are off (element growth) is moved a little, if that helps
  Slice at = slice;
  if (ldlt == nullptr) ldlt = a.Factor(at.sigma, stats);
  if (const double error = slice.sigma == slice.lo ? 0.0 : a.SolveError(*ldlt, at.sigma);
      error > kSolveError) {
    Slice moved = slice;
    moved.sigma = slice.sigma + 0.01 * (slice.hi - slice.lo);
    std::shared_ptr<const Ldlt> other = a.Factor(moved.sigma, stats);
    const double moved_error = a.SolveError(*other, moved.sigma);
    spdlog::debug("shell modes: solves at {:.2f} Hz are off by {:.1e}, at {:.2f} Hz by {:.1e}",
                  Hz(at.sigma), error, Hz(moved.sigma), moved_error);
    if (moved_error < error) {
      at = moved;
      ldlt = std::move(other);
    }
  }
  out.vectors.resize(a.rows(), 0);
  for (int attempt = 0;; ++attempt) {
    const int64_t missing = slice.count - static_cast<int64_t>(out.lambdas.size());
    if (missing == 0) break;
    if (missing < 0 || attempt > kMaxReruns) {
      throw Error(fmt::format(
          "shell modes: {} modes found in [{:.2f}, {:.2f}) Hz but the inertia count is {}",
          out.lambdas.size(), Hz(slice.lo), Hz(slice.hi), slice.count));
    }
    if (attempt > 0) ++stats->reruns;
    const BlockShiftInvert op(*ldlt, out.vectors, stats);
    BlockLanczos(op, at, missing, attempt + 1, with_vectors, &out, stats);
  }
  return out;
}

// Plans the slices from inertia counts alone (never from the eigenvalues found), so the plan and
// every slice's result are the same for any number of threads. counts_: omega^2 -> eigenvalues
// below it.
class Planner {
 public:
  Planner(const OrderedMatrix& a, double rigid_lambda, double cut_lambda, int64_t max_count,
          Stats* stats)
      : a_(a), rigid_(rigid_lambda), cut_(cut_lambda), max_count_(max_count), stats_(stats) {
    counts_[-rigid_lambda] = 0;  // below every eigenvalue of the PSD A
  }

  // inertia counts at these points, factorized concurrently (the one at the rigid-body limit is
  // kept for the first slice); returns how many were new
  size_t Probe(std::vector<double> points) {
    std::sort(points.begin(), points.end());
    points.erase(std::unique(points.begin(), points.end()), points.end());
    std::erase_if(points, [&](double p) { return counts_.contains(p); });
    std::vector<int64_t> found(points.size());
    tbb::parallel_for(size_t{0}, points.size(), [&](size_t k) {
      std::shared_ptr<const Ldlt> ldlt = a_.Factor(points[k], stats_);
      found[k] = NegativePivots(*ldlt);
      if (points[k] == rigid_) rigid_factor_ = std::move(ldlt);
    });
    for (size_t k = 0; k < points.size(); ++k) counts_[points[k]] = found[k];
    ++rounds_;
    return points.size();
  }

  int64_t CountAt(double lambda) const { return counts_.at(lambda); }
  int rounds() const { return rounds_; }

  // eigenvalues wanted: those below the cut, and the lowest max_count above the rigid-body ones
  int64_t Wanted() const {
    int64_t wanted = a_.rows();
    if (cut_ > 0.0) wanted = std::min(wanted, counts_.at(cut_));
    if (max_count_ > 0) wanted = std::min(wanted, counts_.at(rigid_) + max_count_);
    return wanted;
  }

  // the points to probe next: above the highest while too few eigenvalues lie below it, and inside
  // slices to split; none when the plan is complete
  std::vector<double> NextPoints() const {
    const int64_t wanted = Wanted();
    std::vector<double> points;
    const auto top = std::prev(counts_.end());
    if (top->second < wanted) {
      // probes a slice apart, at the density of the eigenvalues below the top
      auto low = top;
      while (low != counts_.begin() && (low == top || top->second - low->second < kSliceModes / 2))
        --low;
      const int64_t below = top->second - low->second;
      const double f_top = Hz(top->first), f_max = Hz(1.001 * a_.upper_bound());
      const int64_t steps = std::min<int64_t>(
          kProbesPerRound, (wanted - top->second + kSliceModes - 1) / kSliceModes);
      for (int64_t k = 1; k <= steps; ++k) {
        const double f = below > 0
                             ? f_top + static_cast<double>(k * kSliceModes) *
                                           (f_top - Hz(low->first)) / static_cast<double>(below)
                             : f_top * std::pow(2.0, static_cast<double>(k));
        points.push_back(Lambda(std::min(f, f_max)));
        if (f >= f_max) break;
      }
    }
    for (auto lo = counts_.lower_bound(rigid_);
         lo != counts_.end() && std::next(lo) != counts_.end(); ++lo) {
      const auto hi = std::next(lo);
      if (lo->second >= wanted) break;
      if (!NeedsSplit(lo, wanted)) continue;
      // the part still useful (up to the wanted count and a margin), in pieces evenly in frequency
      // (the density of shell modes changes slowly with it)
      const int64_t count = hi->second - lo->second;
      const int64_t useful = std::min(count, wanted - lo->second + kSliceModes / 4);
      const int64_t pieces = (useful + kSliceModes - 1) / kSliceModes;
      const double f_lo = Hz(lo->first), f_hi = Hz(hi->first);
      const double f_useful =
          f_lo + (f_hi - f_lo) * static_cast<double>(useful) / static_cast<double>(count);
      for (int64_t k = 1; k < pieces; ++k) {
        points.push_back(Lambda(f_lo + (f_useful - f_lo) * static_cast<double>(k) /
                                           static_cast<double>(pieces)));
      }
      if (useful < count) points.push_back(Lambda(f_useful));
    }
    return points;
  }

  // the slices the plan has fixed for good and not handed out yet: above the rigid-body band,
  // holding wanted eigenvalues, not to be split (all of them once the plan is complete)
  std::vector<Slice> TakeSlices(bool complete) {
    const int64_t wanted = Wanted();
    std::vector<Slice> slices;
    for (auto lo = counts_.lower_bound(rigid_);
         lo != counts_.end() && std::next(lo) != counts_.end(); ++lo) {
      const auto hi = std::next(lo);
      if (lo->second >= wanted) break;
      const int64_t count = hi->second - lo->second;
      if (count == 0 || (!complete && NeedsSplit(lo, wanted)) || !taken_.insert(lo->first).second)
        continue;
      // the first slice is solved at the rigid-body limit (nothing but rigid-body modes below it)
      const double sigma = lo->first == rigid_ ? rigid_ : 0.5 * (lo->first + hi->first);
      slices.push_back(Slice{lo->first, hi->first, count, sigma});
    }
    return slices;
  }

  // the factorization at a slice's shift when the planner has it (once)
  std::shared_ptr<const Ldlt> TakeFactor(const Slice& slice) {
    return slice.sigma == rigid_ ? std::move(rigid_factor_) : nullptr;
  }

 private:
  // a slice holds too many modes, or many more than still wanted, and can still be split
  bool NeedsSplit(std::map<double, int64_t>::const_iterator lo, int64_t wanted) const {
    const auto hi = std::next(lo);
    const int64_t count = hi->second - lo->second;
    if (hi->first - lo->first <= kNarrowestSlice * hi->first) return false;
    return count > kMaxSliceModes || count - (wanted - lo->second) > kSliceModes / 2;
  }

  const OrderedMatrix& a_;
  double rigid_, cut_;
  int64_t max_count_;
  Stats* stats_;
  std::map<double, int64_t> counts_;
  std::set<double> taken_;  // lower ends of the slices handed out
  std::shared_ptr<const Ldlt> rigid_factor_;
  int rounds_{0};
};

}  // namespace

int64_t CountModesBelow(const ShellModel& model, double f_hz) {
  Stats stats;
  return NegativePivots(*OrderedMatrix(model.MassScaledStiffness()).Factor(Lambda(f_hz), &stats));
}

ShellModes SolveShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                           bool with_shapes) {
  if (!(max_frequency_hz > 0.0) && max_count <= 0) {
    throw ConfigError("shell modes need a frequency limit or a mode count");
  }
  if (max_count > kMaxModes) {
    throw ConfigError(
        fmt::format("shell modes: {} modes requested, at most {}", max_count, kMaxModes));
  }
  const Stopwatch total;
  Stats stats;
  const OrderedMatrix a(model.MassScaledStiffness());
  const Eigen::Index n = a.rows();
  const double rigid_lambda = Lambda(kRigidBodyHz);
  const double cut_lambda = max_frequency_hz > 0.0 ? Lambda(max_frequency_hz) : 0.0;

  // plan by inertia counts: the rigid-body limit and the cut or a first probe, then rounds of
  // probes; every slice the plan fixes is solved at once, concurrently with the planning
  Planner planner(a, rigid_lambda, cut_lambda, max_count, &stats);
  std::deque<std::pair<Slice, SliceModes>> solved;  // stable references for the tasks
  tbb::task_group group;
  try {
    std::vector<double> points = {rigid_lambda};
    if (cut_lambda > 0.0) points.push_back(cut_lambda);
    if (max_count > 0 && (cut_lambda <= 0.0 || Lambda(kFirstProbeHz) < cut_lambda)) {
      points.push_back(Lambda(kFirstProbeHz));
    }
    planner.Probe(points);
    if (cut_lambda > 0.0 && planner.CountAt(cut_lambda) - 12 > kMaxModes) {
      throw ConfigError(
          fmt::format("shell modes: {} modes lie below {} Hz, at most {}; lower the band or "
                      "coarsen shell.grid_spacing_m",
                      planner.CountAt(cut_lambda), max_frequency_hz, kMaxModes));
    }
    // (complete also where no new point can be placed, as at the top of the spectrum)
    for (bool complete = false;;) {
      for (const Slice& slice : planner.TakeSlices(complete)) {
        auto& entry = solved.emplace_back(slice, SliceModes{});
        group.run([&a, &entry, &stats, with_shapes, ldlt = planner.TakeFactor(slice)] {
          entry.second = SolveSlice(a, entry.first, ldlt, with_shapes, &stats);
          if (!with_shapes) entry.second.vectors.resize(0, 0);
        });
      }
      if (complete) break;
      points = planner.NextPoints();
      complete = points.empty() || planner.Probe(points) == 0;
    }
  } catch (...) {
    group.cancel();
    try {
      group.wait();
    } catch (...) {
    }
    throw;
  }
  group.wait();

  // ascending (slices are disjoint; in order of their lower ends the sort is deterministic)
  std::sort(solved.begin(), solved.end(),
            [](const auto& x, const auto& y) { return x.first.lo < y.first.lo; });
  struct Found {
    double lambda;
    const SliceModes* slice;
    Eigen::Index column;
  };
  std::vector<Found> found;
  for (const auto& [slice, modes] : solved) {
    for (size_t c = 0; c < modes.lambdas.size(); ++c) {
      found.push_back(Found{modes.lambdas[c], &modes, static_cast<Eigen::Index>(c)});
    }
  }
  std::stable_sort(found.begin(), found.end(),
                   [](const Found& x, const Found& y) { return x.lambda < y.lambda; });
  if (cut_lambda > 0.0) std::erase_if(found, [&](const Found& f) { return f.lambda > cut_lambda; });
  if (max_count > 0 && static_cast<int64_t>(found.size()) > max_count)
    found.resize(static_cast<size_t>(max_count));

  ShellModes out;
  out.rigid_body_modes = planner.CountAt(rigid_lambda);
  out.omega_rad_s.resize(static_cast<Eigen::Index>(found.size()));
  if (with_shapes) out.shapes.resize(n, static_cast<Eigen::Index>(found.size()));
  const Eigen::VectorXd inv_sqrt_mass = model.mass_kg().cwiseSqrt().cwiseInverse();
  for (size_t c = 0; c < found.size(); ++c) {
    out.omega_rad_s[static_cast<Eigen::Index>(c)] = std::sqrt(std::max(found[c].lambda, 0.0));
    if (with_shapes) {
      out.shapes.col(static_cast<Eigen::Index>(c)) =
          inv_sqrt_mass.cwiseProduct(a.ToDofs(found[c].slice->vectors.col(found[c].column)));
    }
  }
  spdlog::debug(
      "shell modes: {} modes in {} slices ({} reruns), {} planning rounds; {} factorizations "
      "{:.2f} s, "
      "{} Lanczos vectors: solves {:.2f} s, orthogonalization {:.2f} s, all Lanczos {:.2f} s ({} "
      "Ritz checks); "
      "{:.2f} s in all",
      found.size(), solved.size(), stats.reruns.load(), planner.rounds(),
      stats.factorizations.load(), Seconds(stats.factor_ns), stats.vectors.load(),
      Seconds(stats.solve_ns), Seconds(stats.orthogonalize_ns), Seconds(stats.lanczos_ns),
      stats.ritz_checks.load(), 1e-9 * static_cast<double>(total.ns()));
  return out;
}

}  // namespace sonicboom::acoustics
