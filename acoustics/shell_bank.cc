#include "sonicboom/acoustics/shell_bank.h"

#include "sonicboom/acoustics/dispersion.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <complex>
#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

constexpr int64_t kBlock = 256;  // samples between checks of the live mode count
constexpr int kMaxMics = 16;

// One sample of `live` modes: y_c += sum_n g_c[n] Im z_n (before the step), then
// z_n <- p_n z_n + h_n u_n (h = p^(1/2): the impulse lands mid-sample). Modes vectorized; six
// mics (the SonicBoom array) get one fused pass with six independent sums.
void StepModes(int64_t live, int mics, const float* const* gain, const float* pr, const float* pim,
               const float* ir, const float* ii, const float* u, float* zr, float* zi, float* y) {
  if (mics == 6) {
    const float *g0 = gain[0], *g1 = gain[1], *g2 = gain[2], *g3 = gain[3], *g4 = gain[4],
                *g5 = gain[5];
    float a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0;
#pragma omp simd reduction(+ : a0, a1, a2, a3, a4, a5)
    for (int64_t q = 0; q < live; ++q) {
      const float r = zr[q], i = zi[q];
      a0 += g0[q] * i;
      a1 += g1[q] * i;
      a2 += g2[q] * i;
      a3 += g3[q] * i;
      a4 += g4[q] * i;
      a5 += g5[q] * i;
      zr[q] = pr[q] * r - pim[q] * i + ir[q] * u[q];
      zi[q] = pim[q] * r + pr[q] * i + ii[q] * u[q];
    }
    y[0] = a0, y[1] = a1, y[2] = a2, y[3] = a3, y[4] = a4, y[5] = a5;
    return;
  }
  for (int c = 0; c < mics; ++c) {
    const float* g = gain[c];
    float sum = 0.0f;
#pragma omp simd reduction(+ : sum)
    for (int64_t q = 0; q < live; ++q) sum += g[q] * zi[q];
    y[c] = sum;
  }
#pragma omp simd
  for (int64_t q = 0; q < live; ++q) {
    const float r = zr[q], i = zi[q];
    zr[q] = pr[q] * r - pim[q] * i + ir[q] * u[q];
    zi[q] = pim[q] * r + pr[q] * i + ii[q] * u[q];
  }
}

// Flush-to-zero and denormals-are-zero for the scope (x86 SSE control register; a no-op elsewhere)
struct FlushSubnormals {
#if defined(__SSE2__)
  unsigned int saved = _mm_getcsr();
  FlushSubnormals() {
    _mm_setcsr(saved | 0x8040u);
  }
  ~FlushSubnormals() {
    _mm_setcsr(saved);
  }
#endif
};

// every DOF a disc of the array moved by up to the margin (and grown by twice it) can read,
// ascending: those of a disc grown by the margin and two grid steps on every side
std::vector<int64_t> PlacementDofs(const ShellModel& model, const MicArrayConfig& mics,
                                   double margin_m) {
  std::vector<int64_t> dofs;
  const double step = std::max(model.dz_m(), model.dtheta_rad() * model.tube().outer_radius_m);
  for (int c = 0; c < mics.count(); ++c) {
    const double d = mics.disc_diameter_m + 2.0 * margin_m + 2.0 * step;
    for (const int64_t dof :
         model.SensorDofs(mics.z_m[static_cast<size_t>(c)],
                          mics.theta_deg[static_cast<size_t>(c)] * M_PI / 180.0, d)) {
      dofs.push_back(dof);
    }
  }
  std::sort(dofs.begin(), dofs.end());
  dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
  return dofs;
}

// the w DOFs a radial point force spreads over, and their weights
struct PointWeights {
  std::vector<int64_t> dof;
  std::vector<double> weight;
};

// rows (of the radial-DOF tables) and weights of a radial point force at (z, theta)
PointWeights SparseWeights(const ShellModel& model, const std::vector<int64_t>& w_row, double z_m,
                           double theta_rad) {
  const Eigen::VectorXd w = model.RadialForceWeights(z_m, theta_rad);
  PointWeights p;
  for (Eigen::Index d = 0; d < w.size(); ++d) {
    if (w[d] != 0.0) {
      SONICBOOM_DEMAND(w_row[static_cast<size_t>(d)] >= 0);
      p.dof.push_back(w_row[static_cast<size_t>(d)]);
      p.weight.push_back(w[d]);
    }
  }
  return p;
}

// the recursion tables of one structure: the bank's own, or a varied one per render
struct RecursionTables {
  Eigen::ArrayXf pole_re, pole_im;  // (modes) p = exp((-sigma + i omega_d) T)
  Eigen::ArrayXf in_re, in_im;      // (modes) p^(1/2): an impulse mid-sample
  Eigen::ArrayXd decay_per_sample;  // (modes) sigma T
  Eigen::ArrayXd decay_tail_min;    // (modes) min of sigma T over this mode and every above
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> sensor_gain;
  // (mics x modes) S phi_n / omega_d, rows contiguous
  double shape_scale{1.0};   // mass-normalized shapes: 1 / sqrt(rho' / rho)
  double static_scale{1.0};  // residual flexibility: E / E'

  // poles of modes at omega (rad/s) with damping ratios zeta (each < 1) at the audio period T
  void SetPoles(const Eigen::VectorXd& omega, const Eigen::VectorXd& zeta, double T);
};

void RecursionTables::SetPoles(const Eigen::VectorXd& omega, const Eigen::VectorXd& zeta,
                               double T) {
  const Eigen::Index n = omega.size();
  pole_re.resize(n);
  pole_im.resize(n);
  in_re.resize(n);
  in_im.resize(n);
  decay_per_sample.resize(n);
  decay_tail_min.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double sigma = zeta[k] * omega[k], wd = omega[k] * std::sqrt(1 - zeta[k] * zeta[k]);
    const std::complex<double> p = std::exp(std::complex<double>(-sigma * T, wd * T));
    const std::complex<double> half =
        std::exp(std::complex<double>(-0.5 * sigma * T, 0.5 * wd * T));
    pole_re[k] = static_cast<float>(p.real());
    pole_im[k] = static_cast<float>(p.imag());
    in_re[k] = static_cast<float>(half.real());
    in_im[k] = static_cast<float>(half.imag());
    decay_per_sample[k] = sigma * T;
  }
  for (Eigen::Index k = n - 1; k >= 0; --k) {
    decay_tail_min[k] =
        k + 1 < n ? std::min(decay_per_sample[k], decay_tail_min[k + 1]) : decay_per_sample[k];
  }
}

}  // namespace

struct ShellModalBank::Impl {
  const ShellModel* model{nullptr};
  double fs{0.0};
  int64_t n_modes{0};
  Eigen::VectorXd frequency_hz;   // (modes) ascending
  Eigen::VectorXd omega, zeta;    // (modes) rad/s, damping ratio
  RecursionTables base;           // the structure as solved
  Eigen::MatrixXd sensor_shape;   // (mics x modes) S phi_n
  Eigen::MatrixXd sensor_static;  // (mics x modes) S phi_n / omega_n^2
  std::vector<int64_t> w_row;     // (dofs) row of a radial DOF in the tables below, or -1
  Eigen::MatrixXf shapes;         // (radial DOFs x modes) mass-normalized shapes, 1/sqrt(kg)
  Eigen::MatrixXd flexibility;    // (radial DOFs x mics) rows of K^-1 S^T, or empty
  double floor_ln{0.0};           // ln of the decay floor ratio
  // microphone placement: the configured array, and the shapes of every DOF around the discs
  MicArrayConfig mics;
  std::vector<int64_t> placement_row;  // (dofs) row of a DOF in placement_shapes, or -1
  Eigen::MatrixXf placement_shapes;    // (DOFs around the discs x modes)

  // the tables of the structure under a variation, for the lowest n modes
  RecursionTables Varied(const StructureDraw& v, int64_t n) const;
  // (mics x n) S phi_n of the discs where the variation puts them
  Eigen::MatrixXd PlacedSensorShape(const StructureDraw& v, int64_t n) const;
  // damping ratio of bank mode k at the varied angular frequency omega
  double VariedDamping(const StructureDraw& v, double omega_rad_s) const;
};

double ShellModalBank::Impl::VariedDamping(const StructureDraw& v, double omega_rad_s) const {
  const double zeta = v.loss_factor > 0.0 ? v.DampingRatio(omega_rad_s / (2 * M_PI))
                                          : model->DampingRatio(omega_rad_s);
  if (!(zeta < 1.0)) {
    throw NumericalError(
        fmt::format("a mode at {:.1f} Hz of the randomized structure has damping "
                    "ratio {:.3f} >= 1 (overdamped)",
                    omega_rad_s / (2 * M_PI), zeta));
  }
  return zeta;
}

RecursionTables ShellModalBank::Impl::Varied(const StructureDraw& v, int64_t n) const {
  RecursionTables t;
  const double s = v.frequency_scale();
  const Eigen::VectorXd w = omega.head(n) * s;
  Eigen::VectorXd z(n), out_scale(n);
  for (int64_t k = 0; k < n; ++k) {
    z[k] = VariedDamping(v, w[k]);
    out_scale[k] = 1.0 / (w[k] * std::sqrt(1 - z[k] * z[k]));
  }
  t.SetPoles(w, z, 1.0 / fs);
  t.shape_scale = 1.0 / std::sqrt(v.density_scale);
  t.static_scale = 1.0 / v.youngs_modulus_scale;
  const Eigen::MatrixXd shape = v.placed() ? PlacedSensorShape(v, n) : sensor_shape.leftCols(n);
  t.sensor_gain = (shape * (t.shape_scale * out_scale).asDiagonal()).cast<float>();
  return t;
}

Eigen::MatrixXd ShellModalBank::Impl::PlacedSensorShape(const StructureDraw& v, int64_t n) const {
  if (placement_shapes.size() == 0) {
    throw ConfigError(
        "randomize: microphone placement ranges need a modal bank built with a "
        "placement margin (acoustics.model = modal)");
  }
  const int count = mics.count();
  Eigen::MatrixXd shape = Eigen::MatrixXd::Zero(count, n);
  for (int c = 0; c < count; ++c) {
    const auto at = [c](const std::vector<double>& x) {
      return x.empty() ? 0.0 : x[static_cast<size_t>(c)];
    };
    const double z = mics.z_m[static_cast<size_t>(c)] + at(v.mic_z_offset_m);
    const double theta =
        (mics.theta_deg[static_cast<size_t>(c)] + at(v.mic_theta_offset_deg)) * M_PI / 180.0;
    const double d = v.disc_diameter_m.empty() ? mics.disc_diameter_m : at(v.disc_diameter_m);
    for (const auto& [dof, coefficient] : model->SensorTerms(z, theta, d)) {
      const int64_t r = placement_row[static_cast<size_t>(dof)];
      SONICBOOM_DEMAND(r >= 0);  // the margin covers every placement the config can draw
      shape.row(c) += coefficient * placement_shapes.row(r).head(n).cast<double>();
    }
  }
  return shape;
}

ModeRows ModeRows::Of(const ShellModes& modes, std::vector<int64_t> dofs) {
  SONICBOOM_DEMAND(modes.shapes.cols() == modes.omega_rad_s.size());
  ModeRows out;
  out.omega_rad_s = modes.omega_rad_s;
  out.rigid_body_modes = modes.rigid_body_modes;
  out.shapes.resize(static_cast<Eigen::Index>(dofs.size()), modes.shapes.cols());
  for (size_t r = 0; r < dofs.size(); ++r) {
    out.shapes.row(static_cast<Eigen::Index>(r)) = modes.shapes.row(dofs[r]);
  }
  out.dofs = std::move(dofs);
  return out;
}

ShellModalBank::ShellModalBank(const ShellModel& model, const ShellModes& modes,
                               const MicArrayConfig& mics, double sample_rate_hz,
                               double decay_floor_db, bool residual, double placement_margin_m)
    : ShellModalBank(model, ModeRows::Of(modes, RowsRead(model, mics, placement_margin_m)), mics,
                     sample_rate_hz, decay_floor_db, residual, placement_margin_m) {}

ShellModalBank::ShellModalBank(const ShellModel& model, const ModeRows& solved,
                               const MicArrayConfig& mics, double sample_rate_hz,
                               double decay_floor_db, bool residual, double placement_margin_m)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  // the modes as rendered: as solved, or carried to the thick wall's dispersion (the residual
  // keeps the solved frequencies: it restores the solved structure's left-out modes)
  const bool thick_wall = model.shell().dispersion == Dispersion::kThickPlate;
  Eigen::VectorXd solved_omega = solved.omega_rad_s;
  const ModeRows thick =
      thick_wall ? ThickPlateCorrected(model, solved, &solved_omega) : ModeRows{};
  const ModeRows& modes = thick_wall ? thick : solved;
  m.mics = mics;
  SONICBOOM_DEMAND(modes.shapes.rows() == static_cast<Eigen::Index>(modes.dofs.size()) &&
                   modes.shapes.cols() == modes.omega_rad_s.size());
  // a DOF's row in modes.shapes (-1: not given)
  std::vector<int64_t> row_of(static_cast<size_t>(model.dofs()), -1);
  for (size_t r = 0; r < modes.dofs.size(); ++r)
    row_of[static_cast<size_t>(modes.dofs[r])] = static_cast<int64_t>(r);
  const auto shape_row = [&](int64_t dof) {
    const int64_t r = row_of[static_cast<size_t>(dof)];
    if (r < 0) throw Error(fmt::format("modal bank: the mode shapes lack DOF {}", dof));
    return modes.shapes.row(r);
  };
  m.model = &model;
  m.fs = sample_rate_hz;
  const double T = 1.0 / sample_rate_hz;
  const double nyquist_rad_s = M_PI * sample_rate_hz;
  // keep the modes below Nyquist: above it a recursion aliases
  m.n_modes = 0;
  while (m.n_modes < modes.omega_rad_s.size() &&
         modes.omega_rad_s[m.n_modes] < 0.95 * nyquist_rad_s) {
    ++m.n_modes;
  }
  const int64_t n = m.n_modes;
  m.omega = modes.omega_rad_s.head(n);
  m.frequency_hz = m.omega / (2 * M_PI);
  m.zeta.resize(n);
  Eigen::VectorXd out_scale(n);  // 1 / omega_d: modal displacement per unit impulse amplitude
  for (int64_t k = 0; k < n; ++k) {
    const double w = m.omega[k];
    const double zeta = model.DampingRatio(w);
    if (!(zeta < 1.0)) {
      throw ConfigError(
          fmt::format("mode at {:.1f} Hz has damping ratio {:.3f} >= 1 (overdamped); "
                      "lower shell.loss_factor_high or material.loss_factor",
                      m.frequency_hz[k], zeta));
    }
    m.zeta[k] = zeta;
    out_scale[k] = 1.0 / (w * std::sqrt(1 - zeta * zeta));
  }
  m.base.SetPoles(m.omega, m.zeta, T);
  // Rayleigh decay grows with frequency, so the live modes stay a prefix; check it, and stop
  // modes by their own decay (a varied loss law may not grow: its tables use the tail minimum)
  for (int64_t k = 1; k < n; ++k) {
    SONICBOOM_DEMAND(m.base.decay_per_sample[k] >= m.base.decay_per_sample[k - 1] * (1 - 1e-9));
  }
  m.base.decay_tail_min = m.base.decay_per_sample;
  // forces act on radial DOFs only: keep those rows of the shapes
  m.w_row.assign(static_cast<size_t>(model.dofs()), -1);
  std::vector<int64_t> w_dofs;
  for (int i = 0; i < model.axial_points(); ++i) {
    for (int j = 0; j < model.circumferential_points(); ++j) {
      const int64_t d = model.WIndex(i, j);
      if (d < 0) continue;
      m.w_row[static_cast<size_t>(d)] = static_cast<int64_t>(w_dofs.size());
      w_dofs.push_back(d);
    }
  }
  m.shapes.resize(static_cast<Eigen::Index>(w_dofs.size()), n);
  for (size_t r = 0; r < w_dofs.size(); ++r) {
    m.shapes.row(static_cast<Eigen::Index>(r)) = shape_row(w_dofs[r]).head(n).cast<float>();
  }
  const Eigen::MatrixXd rows = model.SensorRows(mics);      // (mics x dofs)
  m.sensor_shape = Eigen::MatrixXd::Zero(mics.count(), n);  // (mics x modes)
  for (int c = 0; c < mics.count(); ++c) {
    for (Eigen::Index d = 0; d < rows.cols(); ++d) {
      if (rows(c, d) != 0.0) m.sensor_shape.row(c) += rows(c, d) * shape_row(d).head(n);
    }
  }
  const Eigen::MatrixXd& gain = m.sensor_shape;
  m.base.sensor_gain = (gain * out_scale.asDiagonal()).cast<float>();
  if (mics.count() > kMaxMics) {
    throw ConfigError(fmt::format("mics: {} microphones; the modal bank renders at most {}",
                                  mics.count(), kMaxMics));
  }
  m.sensor_static = gain * solved_omega.head(n).cwiseAbs2().cwiseInverse().asDiagonal();
  // every DOF a disc moved by up to the margin (and grown by twice it) can read
  if (placement_margin_m > 0.0) {
    m.placement_row.assign(static_cast<size_t>(model.dofs()), -1);
    const std::vector<int64_t> dofs = PlacementDofs(model, mics, placement_margin_m);
    for (size_t r = 0; r < dofs.size(); ++r) {
      m.placement_row[static_cast<size_t>(dofs[r])] = static_cast<int64_t>(r);
    }
    m.placement_shapes.resize(static_cast<Eigen::Index>(dofs.size()), n);
    for (size_t r = 0; r < dofs.size(); ++r) {
      m.placement_shapes.row(static_cast<Eigen::Index>(r)) =
          shape_row(dofs[r]).head(n).cast<float>();
    }
  }
  m.floor_ln = std::abs(decay_floor_db) / 20.0 * std::log(10.0);
  // static flexibility at the sensors for the residual: K^-1 S^T (symmetric K)
  if (residual && modes.rigid_body_modes == 0) {
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(model.stiffness());
    SONICBOOM_DEMAND(ldlt.info() == Eigen::Success);
    const Eigen::MatrixXd flex = ldlt.solve(rows.transpose());  // (dofs x mics)
    m.flexibility.resize(static_cast<Eigen::Index>(w_dofs.size()), flex.cols());
    for (size_t r = 0; r < w_dofs.size(); ++r)
      m.flexibility.row(static_cast<Eigen::Index>(r)) = flex.row(w_dofs[r]);
  }
}

ShellModalBank::~ShellModalBank() = default;

std::vector<int64_t> ShellModalBank::RowsRead(const ShellModel& model, const MicArrayConfig& mics,
                                              double placement_margin_m) {
  std::vector<int64_t> rows;
  for (int i = 0; i < model.axial_points(); ++i) {
    for (int j = 0; j < model.circumferential_points(); ++j) {
      if (model.WIndex(i, j) >= 0) rows.push_back(model.WIndex(i, j));
    }
  }
  for (int c = 0; c < mics.count(); ++c) {
    for (const int64_t d : model.SensorDofs(mics.z_m[static_cast<size_t>(c)],
                                            mics.theta_deg[static_cast<size_t>(c)] * M_PI / 180.0,
                                            mics.disc_diameter_m)) {
      rows.push_back(d);
    }
  }
  if (placement_margin_m > 0.0) {
    for (const int64_t d : PlacementDofs(model, mics, placement_margin_m)) rows.push_back(d);
  }
  std::sort(rows.begin(), rows.end());
  rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
  return rows;
}

int64_t ShellModalBank::modes() const {
  return impl_->n_modes;
}

double ShellModalBank::max_frequency_hz() const {
  return impl_->n_modes > 0 ? impl_->frequency_hz[impl_->n_modes - 1] : 0.0;
}

const Eigen::VectorXd& ShellModalBank::frequencies_hz() const {
  return impl_->frequency_hz;
}

int64_t ShellModalBank::ModesBelow(double band_hz) const {
  const Eigen::VectorXd& f = impl_->frequency_hz;
  return std::upper_bound(f.data(), f.data() + f.size(), band_hz) - f.data();
}

int64_t ShellModalBank::ModesBelow(double band_hz, const StructureDraw& structure) const {
  return ModesBelow(structure.Nominal() ? band_hz : band_hz / structure.frequency_scale());
}

DrivingPoint ShellModalBank::WallAt(double z_m, double theta_rad, double band_hz,
                                    const StructureDraw& structure) const {
  const Impl& m = *impl_;
  const PointWeights p = SparseWeights(*m.model, m.w_row, z_m, theta_rad);
  const int64_t n = ModesBelow(band_hz, structure);
  DrivingPoint wall;
  wall.omega_rad_s = m.omega.head(n);
  wall.zeta = m.zeta.head(n);
  wall.phi = Eigen::VectorXd::Zero(n);
  for (size_t i = 0; i < p.dof.size(); ++i) {
    wall.phi += p.weight[i] * m.shapes.row(p.dof[i]).head(n).transpose().cast<double>();
  }
  // the varied structure: frequencies and shapes scaled, damping by its law
  if (!structure.Nominal()) {
    wall.omega_rad_s *= structure.frequency_scale();
    for (int64_t k = 0; k < n; ++k) wall.zeta[k] = m.VariedDamping(structure, wall.omega_rad_s[k]);
    wall.phi /= std::sqrt(structure.density_scale);
  }
  return wall;
}

Eigen::MatrixXd ShellModalBank::Render(std::span<const ForceInput> forces, int64_t mode_count,
                                       int64_t samples, const StructureDraw& structure) const {
  const Impl& m = *impl_;
  int64_t n = std::clamp<int64_t>(mode_count, 0, m.n_modes);
  const double T = 1.0 / m.fs;
  const int mics = static_cast<int>(m.sensor_shape.rows());
  Eigen::MatrixXd strain = Eigen::MatrixXd::Zero(mics, samples);
  // the recursion tables: the bank's own, or the varied structure's
  RecursionTables varied;
  const bool nominal = structure.Nominal();
  if (!nominal) {
    // a stiffer varied structure lifts the top modes: keep them below 0.95 Nyquist
    n = std::min(n, ModesBelow(0.475 * m.fs, structure));
    varied = m.Varied(structure, n);
  }
  const RecursionTables& tab = nominal ? m.base : varied;

  // each force's modal input b = phi^T w (modes), its static sensor part, and its span
  std::vector<Eigen::ArrayXf> input(forces.size());
  int64_t force_end = 0;
  for (size_t e = 0; e < forces.size(); ++e) {
    const ForceInput& f = forces[e];
    const PointWeights p = SparseWeights(*m.model, m.w_row, f.z_m, f.theta_rad);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
    Eigen::VectorXd stat = Eigen::VectorXd::Zero(mics);
    // a positive force pushes the wall inward: against the outward weights
    for (size_t i = 0; i < p.dof.size(); ++i) {
      b -= p.weight[i] * m.shapes.row(p.dof[i]).head(n).transpose().cast<double>();
      if (m.flexibility.size() > 0) stat -= p.weight[i] * m.flexibility.row(p.dof[i]).transpose();
    }
    // impulse per newton of sample force; drives 120 dB below the strongest are dropped (a mode
    // with a nodal line through the point would otherwise decay into subnormal floats)
    const double drive_floor = n > 0 ? 1e-6 * b.cwiseAbs().maxCoeff() : 0.0;
    input[e] = (b.array().abs() < drive_floor)
                   .select(0.0, b.array() * (T * tab.shape_scale))
                   .cast<float>();
    force_end =
        std::max<int64_t>(force_end, f.first_sample + static_cast<int64_t>(f.force_n.size()));
    // residual flexibility of the modes left out: (S K^-1 w - sum_n S phi_n b_n / omega_n^2) F
    if (m.flexibility.size() > 0) {
      stat -= m.sensor_static.leftCols(n) * b;
      stat *= tab.static_scale;
      for (size_t j = 0; j < f.force_n.size(); ++j) {
        const int64_t k = f.first_sample + static_cast<int64_t>(j);
        if (k >= 0 && k < samples) strain.col(k) += stat * f.force_n[j];
      }
    }
  }
  if (n == 0) return strain;

  // mode recursions in float (their error stays far below the 16-bit output's step), modes in
  // the inner loop so it vectorizes; the live modes shrink to a prefix as they decay
  const float* pr = tab.pole_re.data();
  const float* pim = tab.pole_im.data();
  const float* ir = tab.in_re.data();
  const float* ii = tab.in_im.data();
  std::vector<float> zr(static_cast<size_t>(n), 0.0f), zi(static_cast<size_t>(n), 0.0f);
  std::vector<float> u(static_cast<size_t>(n), 0.0f);
  std::vector<const float*> gain(static_cast<size_t>(mics));
  for (int c = 0; c < mics; ++c) gain[static_cast<size_t>(c)] = tab.sensor_gain.row(c).data();
  float* zr_p = zr.data();
  float* zi_p = zi.data();
  float* u_p = u.data();
  const FlushSubnormals ftz;  // decayed states must not fall into slow subnormal arithmetic
  int64_t live = n;
  int64_t force_start = samples;  // the modes rest until the first force
  for (const ForceInput& f : forces)
    force_start = std::min(force_start, std::max<int64_t>(f.first_sample, 0));
  for (int64_t k = force_start; k < samples && live > 0; ++k) {
    // modal impulses of this sample from every force acting in it
    bool driven = false;
    for (size_t e = 0; e < forces.size(); ++e) {
      const int64_t s = k - forces[e].first_sample;
      if (s < 0 || s >= static_cast<int64_t>(forces[e].force_n.size())) continue;
      const float f = static_cast<float>(forces[e].force_n[static_cast<size_t>(s)]);
      const float* b = input[e].data();
      if (!driven) {
        for (int64_t q = 0; q < live; ++q) u_p[q] = b[q] * f;
      } else {
        for (int64_t q = 0; q < live; ++q) u_p[q] += b[q] * f;
      }
      driven = true;
    }
    if (!driven) std::fill(u_p, u_p + live, 0.0f);
    // outputs from the state before this sample's impulse, then one recursion step
    float y[kMaxMics] = {};
    StepModes(live, mics, gain.data(), pr, pim, ir, ii, u_p, zr_p, zi_p, y);
    for (int c = 0; c < mics; ++c) strain(c, k) += y[c];
    // modes that decayed past the floor since the last force stop (checked once a block)
    const double t_free = static_cast<double>(k + 1 - force_end);
    if (t_free > 0 && (k % kBlock) == 0) {
      while (live > 0 && tab.decay_tail_min[live - 1] * t_free > m.floor_ln) --live;
    }
  }
  return strain;
}

}  // namespace sonicboom::acoustics
