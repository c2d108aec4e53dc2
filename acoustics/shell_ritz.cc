#include "sonicboom/acoustics/shell_ritz.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_dir.h"
#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using SpMat = Eigen::SparseMatrix<double>;

// the three factors of Poisson's ratio in the shell's stiffness
std::array<double, 3> PoissonFactors(double nu) {
  return {1.0 / (1.0 - nu), 1.0 / (1.0 + nu), 1.0};
}

// the shell of a model's structure without its springs (bolts and mounts), at Poisson's ratio nu
ShellModel SpringFree(const ShellModel& model, const MaterialConfig& material, double nu) {
  ShellConfig s = model.shell();
  s.bolt_stiffness_n_m = 0.0;
  s.flange_mount_stiffness_n_m2 = 0.0;
  s.tool_mount_stiffness_n_m2 = 0.0;
  MaterialConfig m = material;
  m.poisson_ratio = nu;
  return ShellModel(model.tube(), m, s);
}

// X (dofs x k) made M-orthogonal to the M-orthonormal columns of phi, in place
void DeflateAgainst(const Eigen::MatrixXd& phi, const Eigen::VectorXd& mass, Eigen::MatrixXd* x) {
  const Eigen::MatrixXd mx = mass.asDiagonal() * *x;  // (dofs x k)
  *x -= phi * (phi.transpose() * mx);
}

// an M-orthonormal basis of the columns of x (dofs x k); directions whose M-norm is below `drop`
// of the largest are dropped as dependent
Eigen::MatrixXd MassOrthonormal(const Eigen::MatrixXd& x, const Eigen::VectorXd& mass,
                                double drop) {
  const Eigen::MatrixXd gram = x.transpose() * mass.asDiagonal() * x;  // (k x k)
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  const Eigen::VectorXd& d = eig.eigenvalues();
  if (d.size() == 0 || !(d.maxCoeff() > 0.0)) return Eigen::MatrixXd(x.rows(), 0);
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < d.size(); ++i) {
    if (d[i] > drop * d.maxCoeff()) keep.push_back(i);
  }
  Eigen::MatrixXd out(x.rows(), static_cast<Eigen::Index>(keep.size()));
  for (size_t j = 0; j < keep.size(); ++j) {
    out.col(static_cast<Eigen::Index>(j)) =
        x * eig.eigenvectors().col(keep[j]) / std::sqrt(d[keep[j]]);
  }
  return out;
}

// Phi^T A Phi for a sparse A whose nonzero rows and columns are few (springs): only those rows
// of Phi take part
Eigen::MatrixXd ProjectSparse(const SpMat& a, const Eigen::MatrixXd& phi) {
  std::vector<Eigen::Index> rows;
  for (Eigen::Index k = 0; k < a.outerSize(); ++k) {
    if (a.col(k).nonZeros() > 0) rows.push_back(k);
  }
  const auto n = static_cast<Eigen::Index>(rows.size());
  std::vector<Eigen::Index> slot(static_cast<size_t>(a.rows()), -1);
  Eigen::MatrixXd phi_s(n, phi.cols());
  for (Eigen::Index r = 0; r < n; ++r) {
    slot[static_cast<size_t>(rows[static_cast<size_t>(r)])] = r;
    phi_s.row(r) = phi.row(rows[static_cast<size_t>(r)]);
  }
  Eigen::MatrixXd a_s = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index k = 0; k < a.outerSize(); ++k) {
    for (SpMat::InnerIterator it(a, k); it; ++it) {
      a_s(slot[static_cast<size_t>(it.row())], slot[static_cast<size_t>(it.col())]) += it.value();
    }
  }
  return phi_s.transpose() * (a_s * phi_s);
}

}  // namespace

struct ShellRitzProjector::Impl {
  const ShellModel* base{nullptr};
  Eigen::MatrixXd phi;     // (dofs x N) base shapes
  Eigen::MatrixXf phi_f;   // the same in float, for the shapes of a variant
  Eigen::VectorXd omega2;  // (N) the base modes' omega^2, 1/s^2
  int64_t enrichment{0};
  // Phi^T X_i Phi of the three parts of K_shell(nu) = X1 / (1 - nu) + X2 / (1 + nu) + X3, (N x N)
  std::array<Eigen::MatrixXd, 3> reduced_part;
};

namespace {

// the parts X_i of the spring-free shell's stiffness from its assemblies at three ratios:
// K(nu_j) = sum_i f_i(nu_j) X_i
std::array<SpMat, 3> StiffnessParts(const ShellModel& base) {
  const double nu0 = base.material().poisson_ratio;
  const std::array<double, 3> nus{nu0, nu0 > 0.3 ? nu0 - 0.15 : nu0 + 0.15,
                                  nu0 > 0.3 ? nu0 - 0.3 : nu0 + 0.3};
  Eigen::Matrix3d f;  // f(i, j) = f_i(nu_j)
  std::array<SpMat, 3> k;
  for (size_t j = 0; j < 3; ++j) {
    const std::array<double, 3> fj = PoissonFactors(nus[j]);
    for (size_t i = 0; i < 3; ++i)
      f(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = fj[i];
    k[j] = SpringFree(base, base.material(), nus[j]).stiffness();
  }
  // X_i = sum_j (f^-1)_{j i} K(nu_j)
  const Eigen::Matrix3d inv = f.inverse();
  std::array<SpMat, 3> x;
  const double tiny = 1e-12 * k[0].coeffs().cwiseAbs().maxCoeff();
  for (size_t i = 0; i < 3; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    x[i] = inv(0, ii) * k[0] + inv(1, ii) * k[1] + inv(2, ii) * k[2];
    x[i].prune(tiny, 1.0);
  }
  return x;
}

}  // namespace

ShellRitzProjector::ShellRitzProjector(const ShellModel& base, const ShellModes& base_modes,
                                       int64_t enrichment)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (base_modes.shapes.cols() != base_modes.omega_rad_s.size() ||
      base_modes.shapes.rows() != base.dofs()) {
    throw Error("a Ritz projector needs the base modes with their shapes");
  }
  m.base = &base;
  m.phi = base_modes.shapes;
  m.phi_f = m.phi.cast<float>();
  m.omega2 = base_modes.omega_rad_s.cwiseAbs2();
  m.enrichment = std::min<int64_t>(enrichment, m.phi.cols());
  // X3 (free edges) has few rows: projected directly. Phi^T K_base Phi = Lambda gives
  // X1 / (1 - nu0) + X2 / (1 + nu0) = Lambda - Phi^T (X3 + springs) Phi, so one projection (X2)
  // is computed in full and X1's follows
  const std::array<SpMat, 3> x = StiffnessParts(base);
  const double nu0 = base.material().poisson_ratio;
  const double tiny = 1e-12 * base.stiffness().coeffs().cwiseAbs().maxCoeff();
  SpMat springs = base.stiffness() - SpringFree(base, base.material(), nu0).stiffness();
  springs.prune(tiny, 1.0);
  m.reduced_part[2] = ProjectSparse(x[2], m.phi);
  m.reduced_part[1] = m.phi.transpose() * (x[1] * m.phi);
  const Eigen::MatrixXd lambda = base_modes.omega_rad_s.cwiseAbs2().asDiagonal();
  m.reduced_part[0] = (1.0 - nu0) * (lambda - ProjectSparse(springs, m.phi) - m.reduced_part[2] -
                                     m.reduced_part[1] / (1.0 + nu0));
}

ShellRitzProjector::~ShellRitzProjector() = default;

// the reduced solution of a variant: kept eigenvalues and coefficients on [Phi, X]
struct RitzSolution {
  Eigen::VectorXd omega_rad_s;  // (kept)
  Eigen::MatrixXd y;            // (N + e, kept)
  Eigen::MatrixXd x;            // (dofs, e) the static corrections
  int64_t rigid_body_modes{0};
};

RitzSolution SolveRitz(const ShellRitzProjector::Impl& m, const ShellModel& varied,
                       double max_frequency_hz);

ShellModes ShellRitzProjector::Project(const ShellModel& varied, double max_frequency_hz) const {
  const RitzSolution r = SolveRitz(*impl_, varied, max_frequency_hz);
  const Eigen::Index n = impl_->phi.cols(), e = r.x.cols();
  ShellModes out;
  out.omega_rad_s = r.omega_rad_s;
  out.rigid_body_modes = r.rigid_body_modes;
  out.shapes = impl_->phi * r.y.topRows(n);
  if (e > 0) out.shapes += r.x * r.y.bottomRows(e);
  return out;
}

ModeRows ShellRitzProjector::Project(const ShellModel& varied, double max_frequency_hz,
                                     const std::vector<int64_t>& rows) const {
  const RitzSolution r = SolveRitz(*impl_, varied, max_frequency_hz);
  const Eigen::Index n = impl_->phi.cols(), e = r.x.cols();
  const auto count = static_cast<Eigen::Index>(rows.size());
  // the rows asked for, in single precision (the modal bank keeps its shapes in float)
  Eigen::MatrixXf phi_rows(count, n), x_rows(count, e);
  for (Eigen::Index i = 0; i < count; ++i) {
    phi_rows.row(i) = impl_->phi_f.row(rows[static_cast<size_t>(i)]);
    if (e > 0) x_rows.row(i) = r.x.row(rows[static_cast<size_t>(i)]).cast<float>();
  }
  Eigen::MatrixXf part = phi_rows * r.y.topRows(n).cast<float>();
  if (e > 0) part += x_rows * r.y.bottomRows(e).cast<float>();
  ModeRows out;
  out.omega_rad_s = r.omega_rad_s;
  out.rigid_body_modes = r.rigid_body_modes;
  out.dofs = rows;
  out.shapes = part.cast<double>();
  return out;
}

namespace {

// Refuses a variant the base's projections do not hold: another grid, or another wall (the
// reduced stiffness parts were made for the base's geometry, modulus and density)
void CheckRitzVariant(const ShellModel& base, const ShellModel& varied) {
  const TubeConfig &bt = base.tube(), &vt = varied.tube();
  const MaterialConfig &bm = base.material(), &vm = varied.material();
  const ShellConfig &bs = base.shell(), &vs = varied.shell();
  const bool same_layout = bs.grid_spacing_m == vs.grid_spacing_m &&
                           bs.AxialSpacing() == vs.AxialSpacing() && bs.ends == vs.ends &&
                           bs.ideal == vs.ideal && bs.seam_theta_deg == vs.seam_theta_deg &&
                           bs.hole_z_m == vs.hole_z_m && bs.hole_theta_deg == vs.hole_theta_deg &&
                           bs.hole_diameter_m == vs.hole_diameter_m;
  if (!same_layout || varied.dofs() != base.dofs() || bt.outer_radius_m != vt.outer_radius_m ||
      bt.wall_thickness_m != vt.wall_thickness_m || bt.length_m != vt.length_m ||
      bm.youngs_modulus_pa != vm.youngs_modulus_pa || bm.density_kg_m3 != vm.density_kg_m3) {
    throw ConfigError(fmt::format(
        "a Ritz structure variant must keep the base grid and wall ({} DOFs against {}): "
        "holes, seams, grid spacing, the tube's size, its modulus, density and wall thickness "
        "need a full mode solve",
        varied.dofs(), base.dofs()));
  }
}

// Q_s^T diag(d_s) Q_s over the rows s where d is nonzero (attached masses: a few DOFs), with
// Q = [phi, x], (k x k)
Eigen::MatrixXd ProjectDiagonal(const Eigen::VectorXd& d, const Eigen::MatrixXd& phi,
                                const Eigen::MatrixXd& x) {
  std::vector<Eigen::Index> rows;
  for (Eigen::Index r = 0; r < d.size(); ++r) {
    if (d[r] != 0.0) rows.push_back(r);
  }
  const auto n = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd q_s(n, phi.cols() + x.cols());
  Eigen::VectorXd d_s(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index r = rows[static_cast<size_t>(i)];
    q_s.row(i).head(phi.cols()) = phi.row(r);
    q_s.row(i).tail(x.cols()) = x.row(r);
    d_s[i] = d[r];
  }
  return q_s.transpose() * d_s.asDiagonal() * q_s;
}

// Static corrections K_v^-1 r_k of the lowest base modes to the variant's residual
// r_k = (dK - omega_k^2 dM) phi_k, M-orthonormal and M-orthogonal to Phi (base mass); none when
// nothing changed or K_v cannot be factored
Eigen::MatrixXd StaticCorrections(const ShellRitzProjector::Impl& m, const SpMat& kv,
                                  const SpMat& dk, const Eigen::VectorXd& dm) {
  const bool stiffer = dk.norm() > 0.0, heavier = !dm.isZero(0.0);
  if (m.enrichment <= 0 || (!stiffer && !heavier)) return {};
  const Eigen::SimplicialLDLT<SpMat> ldlt(kv);
  if (ldlt.info() != Eigen::Success) return {};
  const auto phi = m.phi.leftCols(m.enrichment);  // (dofs x e), a view
  Eigen::MatrixXd residual = dk * phi;
  if (heavier) {
    residual -= dm.asDiagonal() * (phi * m.omega2.head(m.enrichment).asDiagonal());
  }
  Eigen::MatrixXd x = ldlt.solve(residual);
  // twice, for round-off: orthogonal to the base modes, then orthonormal among themselves
  const Eigen::VectorXd& mass = m.base->mass_kg();
  for (int pass = 0; pass < 2; ++pass) {
    DeflateAgainst(m.phi, mass, &x);
    x = MassOrthonormal(x, mass, 1e-10);
  }
  return x;
}

}  // namespace

RitzSolution SolveRitz(const ShellRitzProjector::Impl& m, const ShellModel& varied,
                       double max_frequency_hz) {
  const ShellModel& base = *m.base;
  CheckRitzVariant(base, varied);
  const SpMat& kv = varied.stiffness();
  const double nu = varied.material().poisson_ratio;
  // (dofs) the variant's added mass (attached masses), kg
  const Eigen::VectorXd dm = varied.mass_kg() - base.mass_kg();

  // Phi^T K_v Phi: the shell at nu from its three parts, plus the variant's springs
  const std::array<double, 3> f = PoissonFactors(nu);
  Eigen::MatrixXd k_pp =
      f[0] * m.reduced_part[0] + f[1] * m.reduced_part[1] + f[2] * m.reduced_part[2];
  // (the difference of two assemblies: round-off below 1e-12 of the largest entry is dropped)
  const double tiny = 1e-12 * kv.coeffs().cwiseAbs().maxCoeff();
  SpMat springs = kv - SpringFree(varied, varied.material(), nu).stiffness();
  springs.prune(tiny, 1.0);
  k_pp += ProjectSparse(springs, m.phi);

  // static corrections of the lowest base modes to the stiffness and mass change
  SpMat dk = kv - base.stiffness();
  dk.prune(tiny, 1.0);
  Eigen::MatrixXd x = StaticCorrections(m, kv, dk, dm);
  const Eigen::Index n = m.phi.cols(), e = x.cols();

  // the reduced problem on Q = [Phi, X] (M-orthonormal): [K_pp, K_px; K_xp, K_xx]
  Eigen::MatrixXd reduced(n + e, n + e);
  reduced.topLeftCorner(n, n) = k_pp;
  if (e > 0) {
    const Eigen::MatrixXd kx = kv * x;  // (dofs x e)
    reduced.topRightCorner(n, e) = m.phi.transpose() * kx;
    reduced.bottomLeftCorner(e, n) = reduced.topRightCorner(n, e).transpose();
    reduced.bottomRightCorner(e, e) = x.transpose() * kx;
  }
  reduced = 0.5 * (reduced + reduced.transpose()).eval();
  // the reduced mass is I, or I + Q^T dM Q with attached masses: a generalized problem whose
  // eigenvectors come out normalized to it (shapes Q y mass-normalized for the variant)
  Eigen::VectorXd lambda;
  Eigen::MatrixXd vectors;
  const auto take = [&](const auto& eig) {
    if (eig.info() != Eigen::Success) {
      throw NumericalError("the Ritz eigenproblem of a structure variant did not converge");
    }
    lambda = eig.eigenvalues();
    vectors = eig.eigenvectors();
  };
  if (dm.isZero(0.0)) {
    take(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(reduced));
  } else {
    Eigen::MatrixXd reduced_mass = ProjectDiagonal(dm, m.phi, x);
    reduced_mass.diagonal().array() += 1.0;
    reduced_mass = 0.5 * (reduced_mass + reduced_mass.transpose()).eval();
    take(Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd>(reduced, reduced_mass));
  }

  // the elastic modes of the band
  const double lo = std::pow(2.0 * std::numbers::pi * kRigidBodyHz, 2);
  const double hi = std::pow(2.0 * std::numbers::pi * max_frequency_hz, 2);
  std::vector<Eigen::Index> keep;
  RitzSolution out;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    if (lambda[i] < lo) {
      ++out.rigid_body_modes;
    } else if (lambda[i] <= hi) {
      keep.push_back(i);
    }
  }
  const auto kept = static_cast<Eigen::Index>(keep.size());
  out.y.resize(n + e, kept);
  out.omega_rad_s.resize(kept);
  for (Eigen::Index j = 0; j < kept; ++j) {
    out.y.col(j) = vectors.col(keep[static_cast<size_t>(j)]);
    out.omega_rad_s[j] = std::sqrt(lambda[keep[static_cast<size_t>(j)]]);
  }
  out.x = std::move(x);
  return out;
}

namespace {

constexpr char kRitzMagic[8] = {'S', 'B', 'R', 'I', 'T', 'Z', '0', '2'};

// file layout (sonicboom/core/cache_file.h): header {modes, rows}, omega (modes), shapes at the
// rows (rows x modes, float), checksum
bool ReadRitz(const std::string& path, const std::string& key, const std::vector<int64_t>& rows,
              ModeRows* out) {
  internal::CacheFileReader in;
  int64_t header[2];
  if (!in.Open(path, kRitzMagic, key, header, 2)) return false;
  const bool sized =
      header[0] >= 0 && header[0] < (1 << 24) && header[1] == static_cast<int64_t>(rows.size());
  Eigen::MatrixXf part;
  if (sized) {
    out->rigid_body_modes = 0;
    out->omega_rad_s.resize(header[0]);
    part.resize(header[1], header[0]);
    in.Read(out->omega_rad_s.data(), sizeof(double) * out->omega_rad_s.size());
    in.Read(part.data(), sizeof(float) * part.size());
  }
  if (!in.Finish() || !sized) return false;
  out->dofs = rows;
  out->shapes = part.cast<double>();
  return true;
}

void WriteRitz(const std::string& cache_dir, const std::string& path, const std::string& key,
               const ModeRows& modes) {
  const Eigen::MatrixXf part = modes.shapes.cast<float>();
  internal::WriteCacheFile(cache_dir, path, kRitzMagic, key,
                           {modes.omega_rad_s.size(), part.rows()},
                           {{modes.omega_rad_s.data(), sizeof(double) * modes.omega_rad_s.size()},
                            {part.data(), sizeof(float) * part.size()}});
}

}  // namespace

ModeRows CachedRitzModes(const std::function<const ShellRitzProjector&()>& projector,
                         const ShellModel& base, const ShellModel& varied, double max_frequency_hz,
                         const std::vector<int64_t>& rows, const std::string& cache_dir,
                         bool* hit) {
  if (hit != nullptr) *hit = false;
  if (cache_dir.empty()) return projector().Project(varied, max_frequency_hz, rows);
  std::string row_text;
  for (const int64_t r : rows) row_text += fmt::format("{},", r);
  const std::string key = fmt::format(
      "ritz-v1 | base: {} | variant: {} | band={:.17g} "
      "enrichment={} rows={}:{:016x}",
      base.key(), varied.key(), max_frequency_hz, kRitzEnrichment, rows.size(),
      CacheKeyHash(row_text));
  const std::string path =
      (std::filesystem::path(cache_dir) / fmt::format("ritz-{:016x}.bin", CacheKeyHash(key)))
          .string();
  // a variant's use is its base's too: the base's modes (the costliest entry, which every pool
  // reads first) stay more recently used than the pool's variants while these are read and
  // written, so that a budget smaller than the pool prunes variants, not the base
  const std::string base_path = ShellModesCachePath(base, max_frequency_hz, 0, true, cache_dir);
  internal::TouchCacheEntry(base_path);
  ModeRows modes;
  if (ReadRitz(path, key, rows, &modes)) {
    if (hit != nullptr) *hit = true;
    return modes;
  }
  modes = projector().Project(varied, max_frequency_hz, rows);
  internal::TouchCacheEntry(base_path);
  WriteRitz(cache_dir, path, key, modes);
  return modes;
}

ShellModes RitzShellModes(const ShellModel& base, const ShellModes& base_modes,
                          const ShellModel& varied, double max_frequency_hz, int64_t enrichment) {
  return ShellRitzProjector(base, base_modes, enrichment).Project(varied, max_frequency_hz);
}

}  // namespace sonicboom::acoustics
