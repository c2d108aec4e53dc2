#include "sonicboom/acoustics/dispersion.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// k from the grid's quotient q = (2 sin(k d / 2) / d)^2 (step d, m); beyond the grid's highest
// wave (q >= 4 / d^2) the Nyquist wavenumber pi / d
double InvertQuotient(double q_1_m2, double step_m) {
  const double s = std::sqrt(std::max(q_1_m2, 0.0)) * step_m / 2.0;
  return s >= 1.0 ? kPi / step_m : 2.0 / step_m * std::asin(s);
}

}  // namespace

double MindlinFrequencyRatio(double k_rad_m, double wall_thickness_m, double poisson_ratio) {
  if (k_rad_m <= 0.0) return 1.0;
  // per unit E and rho (the ratio depends on k h and nu only): shear stiffness A = kappa^2 G h,
  // bending D, mass per area m, rotary inertia I
  const double h = wall_thickness_m, nu = poisson_ratio;
  const double A = kPi * kPi / 12.0 * h / (2.0 * (1.0 + nu));
  const double D = h * h * h / (12.0 * (1.0 - nu * nu));
  const double m = h, I = h * h * h / 12.0;
  const double k2 = k_rad_m * k_rad_m, k4 = k2 * k2;
  // m I x^2 - (A I k^2 + m D k^2 + m A) x + A D k^4 = 0, x = omega^2; the lower root, written
  // without the cancellation of b - sqrt(b^2 - 4ac) at small k
  const double b = A * I * k2 + m * D * k2 + m * A;
  const double x = 2.0 * A * D * k4 / (b + std::sqrt(b * b - 4.0 * m * I * A * D * k4));
  return std::sqrt(x / (D * k4 / m));
}

namespace {

// (axial_points x circumferential_points) the row of `modes` that holds node (i, j)'s w, -1 for
// a fixed or absent node
std::vector<int64_t> NodeRows(const ShellModel& model, const ModeRows& modes) {
  const int rows = model.axial_points(), nth = model.circumferential_points();
  std::vector<int64_t> node_row(static_cast<size_t>(rows) * nth, -1);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < nth; ++j) {
      const int64_t d = model.WIndex(i, j);
      if (d < 0) continue;
      const auto it = std::lower_bound(modes.dofs.begin(), modes.dofs.end(), d);
      if (it == modes.dofs.end() || *it != d) {
        throw Error(fmt::format("thick-plate dispersion: the mode rows lack w DOF {}", d));
      }
      node_row[static_cast<size_t>(i) * nth + j] = it - modes.dofs.begin();
    }
  }
  return node_row;
}

ModeWavenumbers Estimate(const ShellModel& model, const ModeRows& modes,
                         const std::vector<int64_t>& node_row, Eigen::Index mode) {
  const int rows = model.axial_points(), nth = model.circumferential_points();
  const auto shape = modes.shapes.col(mode);
  // w at node (i, j), and whether it is a free DOF
  const auto w = [&](int i, int j, double* value) {
    const int64_t r = node_row[static_cast<size_t>(i) * nth + j];
    if (r < 0) return false;
    *value = shape[static_cast<Eigen::Index>(r)];
    return true;
  };
  // mean squares per node and per joined pair, so that edges and holes do not bias the quotient
  double sum_w2 = 0.0, sum_dz2 = 0.0, sum_dth2 = 0.0;
  int64_t nodes = 0, pairs_z = 0, pairs_th = 0;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < nth; ++j) {
      double a = 0.0, b = 0.0;
      if (!w(i, j, &a)) continue;
      sum_w2 += a * a;
      ++nodes;
      if (i + 1 < rows && w(i + 1, j, &b)) {
        sum_dz2 += (b - a) * (b - a);
        ++pairs_z;
      }
      if (model.ArcLinked(i, j) && w(i, (j + 1) % nth, &b)) {
        sum_dth2 += (b - a) * (b - a);
        ++pairs_th;
      }
    }
  }
  ModeWavenumbers k;
  if (nodes == 0 || sum_w2 <= 0.0) return k;
  const double mean_w2 = sum_w2 / static_cast<double>(nodes);
  const double dz = model.dz_m(), ds = model.radius_m() * model.dtheta_rad();
  if (pairs_z > 0) k.q_axial_1_m2 = sum_dz2 / static_cast<double>(pairs_z) / mean_w2 / (dz * dz);
  if (pairs_th > 0) k.q_arc_1_m2 = sum_dth2 / static_cast<double>(pairs_th) / mean_w2 / (ds * ds);
  k.k_axial_rad_m = InvertQuotient(k.q_axial_1_m2, dz);
  k.k_arc_rad_m = InvertQuotient(k.q_arc_1_m2, ds);
  return k;
}

}  // namespace

ModeWavenumbers EstimateWavenumbers(const ShellModel& model, const ModeRows& modes,
                                    Eigen::Index mode) {
  return Estimate(model, modes, NodeRows(model, modes), mode);
}

Eigen::VectorXd ThickPlateFrequencyFactors(const ShellModel& model, const ModeRows& rows,
                                           DispersionParts parts) {
  const Eigen::Index modes = rows.omega_rad_s.size();
  Eigen::VectorXd factor = Eigen::VectorXd::Ones(modes);
  const MaterialConfig& mat = model.material();
  const double h = model.tube().wall_thickness_m, nu = mat.poisson_ratio;
  // omega^2 of plate bending per (q_z + q_th)^2: D / (rho h), m^4/s^2
  const double bending =
      mat.youngs_modulus_pa * h * h / (12.0 * (1.0 - nu * nu) * mat.density_kg_m3);
  const std::vector<int64_t> node_row = NodeRows(model, rows);
  for (Eigen::Index n = 0; n < modes; ++n) {
    const ModeWavenumbers k = Estimate(model, rows, node_row, n);
    const double q = k.q_axial_1_m2 + k.q_arc_1_m2;
    const double omega2 = rows.omega_rad_s[n] * rows.omega_rad_s[n];
    if (!(q > 0.0) || !(omega2 > 0.0)) continue;
    const double k2 = k.k_axial_rad_m * k.k_axial_rad_m + k.k_arc_rad_m * k.k_arc_rad_m;
    const double grid = k2 / q;  // continuum over grid, per power of the wavenumber squared
    const double thick = parts == DispersionParts::kGridAndThickWall
                             ? MindlinFrequencyRatio(std::sqrt(k2), h, nu)
                             : 1.0;
    // the bending part of omega^2 goes as k^4 (and the thick wall's ratio), the membrane part as
    // k^2
    const double share = std::min(1.0, bending * q * q / omega2);
    factor[n] = std::sqrt(share * (thick * grid) * (thick * grid) + (1.0 - share) * grid);
  }
  return factor;
}

ModeRows ThickPlateCorrected(const ShellModel& model, const ModeRows& rows,
                             Eigen::VectorXd* solved_omega) {
  const Eigen::VectorXd factor = ThickPlateFrequencyFactors(model, rows);
  const Eigen::VectorXd scaled = rows.omega_rad_s.cwiseProduct(factor);
  std::vector<Eigen::Index> order(static_cast<size_t>(scaled.size()));
  for (size_t n = 0; n < order.size(); ++n) order[n] = static_cast<Eigen::Index>(n);
  std::stable_sort(order.begin(), order.end(),
                   [&](Eigen::Index a, Eigen::Index b) { return scaled[a] < scaled[b]; });
  ModeRows out;
  out.rigid_body_modes = rows.rigid_body_modes;
  out.dofs = rows.dofs;
  out.omega_rad_s.resize(scaled.size());
  out.shapes.resize(rows.shapes.rows(), rows.shapes.cols());
  if (solved_omega != nullptr) solved_omega->resize(scaled.size());
  for (size_t n = 0; n < order.size(); ++n) {
    const auto to = static_cast<Eigen::Index>(n);
    out.omega_rad_s[to] = scaled[order[n]];
    out.shapes.col(to) = rows.shapes.col(order[n]);
    if (solved_omega != nullptr) (*solved_omega)[to] = rows.omega_rad_s[order[n]];
  }
  return out;
}

}  // namespace sonicboom::acoustics
