#include "sonicboom/acoustics/shell.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <tuple>
#include <utility>

#include <fmt/format.h>

#include "sonicboom/acoustics/tdoa.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// grid lookups: a point that does not exist (off the grid, on a seam, in a hole) makes a strain
// that needs it unavailable; a fixed point (a supported end) contributes zero
constexpr int64_t kAbsent = -1;
constexpr int64_t kFixed = -2;

enum class Field { kU, kV, kW };
struct Term {
  Field field;
  int i, j;  // grid indices (u: i + 1/2, v: j + 1/2)
  double c;  // coefficient
};
using Row = std::vector<std::pair<int64_t, double>>;  // (dof, coefficient)

double ArcDistance(double radius_m, double a_rad, double b_rad) {
  return radius_m * std::abs(WrapAngle(a_rad - b_rad));
}

}  // namespace

void ShellConfig::Serialize(Archive* a) {
  a->Visit("grid_spacing_m", &grid_spacing_m, Bounds::Closed(0.0, 1.0));
  a->Visit("axial_spacing_m", &axial_spacing_m, Bounds::Closed(0.0, 1.0));
  a->Visit("ends", &ends);
  a->Visit("ideal", &ideal);
  a->Visit("seam_theta_deg", &seam_theta_deg, Bounds::Closed(-360.0, 360.0));
  a->Visit("bolt_z_m", &bolt_z_m);
  a->Visit("bolt_stiffness_n_m", &bolt_stiffness_n_m, Bounds::Closed(0.0, 1e12));
  a->Visit("bolt_stiffness_scale", &bolt_stiffness_scale, Bounds::Closed(0.0, 1e6));
  a->Visit("bolt_model", &bolt_model);
  a->Visit("bolt_tie_length_m", &bolt_tie_length_m, Bounds::Open(0.0, 1.0));
  a->Visit("hole_z_m", &hole_z_m);
  a->Visit("hole_theta_deg", &hole_theta_deg, Bounds::Closed(-360.0, 360.0));
  a->Visit("hole_diameter_m", &hole_diameter_m, Bounds::Closed(0.0, 0.1));
  a->Visit("flange_mount_stiffness_n_m2", &flange_mount_stiffness_n_m2, Bounds::Closed(0.0, 1e12));
  a->Visit("tool_mount_stiffness_n_m2", &tool_mount_stiffness_n_m2, Bounds::Closed(0.0, 1e12));
  a->Visit("attached_mass_kg", &attached_mass_kg, Bounds::Closed(0.0, 10.0));
  a->Visit("attached_mass_z_m", &attached_mass_z_m);
  a->Visit("attached_mass_theta_deg", &attached_mass_theta_deg, Bounds::Closed(-360.0, 360.0));
  a->Visit("damping", &damping);
  a->Visit("loss_exponent", &loss_exponent, Bounds{-1.0, 2.0, false, true});
  a->Visit("loss_reference_hz", &loss_reference_hz, Bounds::Open(0.0, 1e6));
  a->Visit("loss_low_hz", &loss_low_hz, Bounds::Open(0.0, 1e6));
  a->Visit("loss_high_hz", &loss_high_hz, Bounds::Open(0.0, 1e6));
  a->Visit("loss_factor_high", &loss_factor_high, Bounds::Closed(0.0, 2.0));
  a->Visit("dispersion", &dispersion);
}

double DerivedGridSpacing(const TubeConfig& tube, const MaterialConfig& material, double band_hz) {
  SONICBOOM_DEMAND(band_hz > 0.0);
  const double wavelength_m =
      FlexuralPhaseVelocity(band_hz, material, tube.wall_thickness_m) / band_hz;
  return std::min(kCoarsestDerivedSpacingM, wavelength_m / kGridPointsPerWavelength);
}

void ShellConfig::Validate(const TubeConfig& tube) const {
  const double half_length_m = 0.5 * tube.length_m;
  if (grid_spacing_m == 0.0) {
    throw ConfigError(
        "shell.grid_spacing_m = 0 (derived from the mode band) is resolved with the whole "
        "configuration (ResolveConfig); a shell built on its own needs a spacing");
  }
  for (const auto& [key, value] : {std::pair{"grid_spacing_m", grid_spacing_m},
                                   std::pair{"axial_spacing_m", AxialSpacing()}}) {
    if (!(value > 0.0) || value > 0.25 * tube.length_m) {
      throw ConfigError(fmt::format(
          "shell.{} = {} m must be positive and at most a quarter of tube.length_m ({} m)", key,
          value, 0.25 * tube.length_m));
    }
  }
  if (!bolt_stiffness_scale.empty() && bolt_stiffness_scale.size() != bolt_z_m.size()) {
    throw ConfigError(
        fmt::format("shell.bolt_stiffness_scale has {} entries but shell.bolt_z_m "
                    "has {}: one scale per bolt (or none)",
                    bolt_stiffness_scale.size(), bolt_z_m.size()));
  }
  for (double z : bolt_z_m) {
    if (!(std::abs(z) <= half_length_m)) {
      throw ConfigError(fmt::format("shell.bolt_z_m entry {} m lies off the tube (|z| <= {} m)", z,
                                    half_length_m));
    }
  }
  if (hole_z_m.size() != hole_theta_deg.size()) {
    throw ConfigError(fmt::format("shell.hole_z_m has {} entries but shell.hole_theta_deg has {}",
                                  hole_z_m.size(), hole_theta_deg.size()));
  }
  for (double z : hole_z_m) {
    if (!(std::abs(z) <= half_length_m)) {
      throw ConfigError(fmt::format("shell.hole_z_m entry {} m lies off the tube (|z| <= {} m)", z,
                                    half_length_m));
    }
  }
  if (attached_mass_z_m.size() != attached_mass_kg.size() ||
      attached_mass_theta_deg.size() != attached_mass_kg.size()) {
    throw ConfigError(fmt::format(
        "shell.attached_mass_kg has {} entries, shell.attached_mass_z_m {} and "
        "shell.attached_mass_theta_deg {}: one place per mass",
        attached_mass_kg.size(), attached_mass_z_m.size(), attached_mass_theta_deg.size()));
  }
  for (double z : attached_mass_z_m) {
    if (!(std::abs(z) <= half_length_m)) {
      throw ConfigError(fmt::format(
          "shell.attached_mass_z_m entry {} m lies off the tube (|z| <= {} m)", z, half_length_m));
    }
  }
  if (!(loss_high_hz > loss_low_hz)) {
    throw ConfigError(fmt::format("shell.loss_high_hz = {} must exceed shell.loss_low_hz = {}",
                                  loss_high_hz, loss_low_hz));
  }
}

namespace {

// The grid of a shell: nz intervals along the tube, nth points around it, the seams' cuts, the
// holes; the w points sit at (i, j), u at (i + 1/2, j), v at (i, j + 1/2).
struct GridLayout {
  const TubeConfig& tube;
  const ShellConfig& shell;
  double R{0.0}, dz{0.0}, dth{0.0}, ds{0.0};  // mid radius, m; spacings, m, rad, m of arc
  int nz{0}, nth{0};
  bool real{false};                    // seams, bolts, holes and mounts (not the ideal tube)
  bool supported{false};               // simply supported ends
  std::vector<int> seams{};            // the v column js of each cut
  std::vector<bool> seam_v{}, edge{};  // (nth) v on a cut; w/u column beside a cut

  int Wrap(int j) const { return ((j % nth) + nth) % nth; }
  double Z(double i) const { return -0.5 * tube.length_m + i * dz; }
  bool InHole(double z_m, double theta_rad) const {
    if (!real) return false;
    for (size_t k = 0; k < shell.hole_z_m.size(); ++k) {
      const double dzh = z_m - shell.hole_z_m[k];
      const double dsh = ArcDistance(R, theta_rad, shell.hole_theta_deg[k] * kPi / 180.0);
      if (std::hypot(dzh, dsh) < 0.5 * shell.hole_diameter_m) return true;
    }
    return false;
  }
  double Fz(int i) const { return (i == 0 || i == nz) ? 0.5 : 1.0; }  // end rows carry half
  double Fth(int j) const { return edge[j] ? 0.5 : 1.0; }             // seam edges carry half
};

GridLayout LayOut(const TubeConfig& tube, const ShellConfig& shell) {
  GridLayout g{tube, shell};
  g.R = tube.mid_radius_m();
  g.nz = std::max(4, static_cast<int>(std::lround(tube.length_m / shell.AxialSpacing())));
  g.nth = std::max(8, static_cast<int>(std::lround(2.0 * kPi * g.R / shell.grid_spacing_m)));
  g.dz = tube.length_m / g.nz;
  g.dth = 2.0 * kPi / g.nth;
  g.ds = g.R * g.dth;
  g.real = !shell.ideal;
  g.supported = shell.ends == TubeEnds::kSimplySupported;
  // seams: the v point (i, js) lies on the cut at theta = (js + 1/2) dth
  if (g.real) {
    for (double deg : shell.seam_theta_deg) {
      const double theta = deg * kPi / 180.0;
      const int js = g.Wrap(static_cast<int>(std::lround(theta / g.dth - 0.5)));
      if (std::find(g.seams.begin(), g.seams.end(), js) != g.seams.end()) {
        throw ConfigError(fmt::format(
            "shell.seam_theta_deg: two seams fall on the same grid column (at {} deg); use a finer "
            "shell.grid_spacing_m",
            deg));
      }
      g.seams.push_back(js);
    }
  }
  g.seam_v.assign(static_cast<size_t>(g.nth), false);
  g.edge.assign(static_cast<size_t>(g.nth), false);
  for (int js : g.seams) {
    g.seam_v[js] = true;
    g.edge[js] = g.edge[g.Wrap(js + 1)] = true;
  }
  return g;
}

// Each field's DOF at every grid point (kAbsent, kFixed or the DOF) and every DOF's lumped mass
struct DofNumbering {
  std::vector<int64_t> w, u, v;  // (rows x nth) row-major
  Eigen::VectorXd mass_kg;       // (dofs)
};

// DOF numbering: w, u, v point by point; lumped masses from the area each point carries
DofNumbering NumberDofs(const GridLayout& g, double rho_h) {
  DofNumbering n;
  std::vector<double> mass;
  auto number = [&](std::vector<int64_t>* index, int rows, double i_offset, double j_offset,
                    auto fixed, auto area) {
    index->assign(static_cast<size_t>(rows) * g.nth, kAbsent);
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < g.nth; ++j) {
        if (g.InHole(g.Z(i + i_offset), (j + j_offset) * g.dth)) continue;
        int64_t& slot = (*index)[static_cast<size_t>(i) * g.nth + j];
        if (fixed(i, j)) {
          slot = kFixed;
          continue;
        }
        slot = static_cast<int64_t>(mass.size());
        mass.push_back(rho_h * area(i, j));
      }
    }
  };
  const int nz = g.nz;
  auto end_row = [&](int i, int) { return g.supported && (i == 0 || i == nz); };
  number(&n.w, nz + 1, 0.0, 0.0, end_row,
         [&](int i, int j) { return g.dz * g.Fz(i) * g.ds * g.Fth(j); });
  number(
      &n.u, nz, 0.5, 0.0, [](int, int) { return false; },
      [&](int, int j) { return g.dz * g.ds * g.Fth(j); });
  number(&n.v, nz + 1, 0.0, 0.5, end_row, [&](int i, int) { return g.dz * g.Fz(i) * g.ds; });
  for (int i = 0; i <= nz; ++i) {
    for (int j = 0; j < g.nth; ++j) {
      if (g.seam_v[j]) n.v[static_cast<size_t>(i) * g.nth + j] = kAbsent;
    }
  }
  // renumber after the seam removals (drop the masses of removed v points)
  std::vector<int64_t> remap(mass.size(), kAbsent);
  std::vector<bool> used(mass.size(), false);
  for (const auto* index : {&n.w, &n.u, &n.v}) {
    for (int64_t d : *index) {
      if (d >= 0) used[static_cast<size_t>(d)] = true;
    }
  }
  std::vector<double> kept;
  for (size_t d = 0; d < mass.size(); ++d) {
    if (!used[d]) continue;
    remap[d] = static_cast<int64_t>(kept.size());
    kept.push_back(mass[d]);
  }
  for (auto* index : {&n.w, &n.u, &n.v}) {
    for (int64_t& d : *index) {
      if (d >= 0) d = remap[static_cast<size_t>(d)];
    }
  }
  n.mass_kg =
      Eigen::Map<const Eigen::VectorXd>(kept.data(), static_cast<Eigen::Index>(kept.size()));
  return n;
}

// The four points of one field's grid around a fractional grid position (xf along its `rows`
// rows, yf around its nth columns) and their bilinear weights: (index entry: a DOF, kAbsent or
// kFixed; weight), rows i0 and i0 + 1 (clamped inside the grid), columns j0 and j0 + 1 (wrapped)
std::array<std::pair<int64_t, double>, 4> BilinearPoints(const std::vector<int64_t>& index,
                                                         int rows, int nth, double xf, double yf) {
  const int i0 = std::clamp(static_cast<int>(std::floor(xf)), 0, rows - 2);
  const double fx = std::clamp(xf - i0, 0.0, 1.0), fy = yf - std::floor(yf);
  const int j0 = static_cast<int>(std::floor(yf));
  std::array<std::pair<int64_t, double>, 4> points;
  for (int c = 0; c < 4; ++c) {
    const int di = c / 2, dj = c % 2;
    const int j = (((j0 + dj) % nth) + nth) % nth;
    points[c] = {index[static_cast<size_t>(i0 + di) * nth + j],
                 (di ? fx : 1.0 - fx) * (dj ? fy : 1.0 - fy)};
  }
  return points;
}

// The attached masses lumped onto the grid: each mass shared bilinearly among the four points
// of every field around it (w at nodes, u half a row up, v half a column over), the share of a
// point in a hole given to the others, the share of a fixed point dropped (it does not move).
// Throws ConfigError naming the entry when the mass sits in a hole (half its w share absent).
void AddAttachedMasses(const GridLayout& g, DofNumbering* n) {
  const ShellConfig& s = g.shell;
  for (size_t k = 0; k < s.attached_mass_kg.size(); ++k) {
    const double x = (s.attached_mass_z_m[k] + 0.5 * g.tube.length_m) / g.dz;
    const double y = WrapAngle(s.attached_mass_theta_deg[k] * kDeg) / g.dth;
    // the mass shared among one field's four points; returns the absent share
    const auto share = [&](const std::vector<int64_t>& index, int rows, double i_offset,
                           double j_offset) {
      const auto points = BilinearPoints(index, rows, g.nth, x - i_offset, y - j_offset);
      double absent = 0.0;
      for (const auto& [d, wgt] : points) {
        if (d == kAbsent) absent += wgt;
      }
      for (const auto& [d, wgt] : points) {
        if (d >= 0) n->mass_kg[d] += s.attached_mass_kg[k] * wgt / (1.0 - absent);
      }
      return absent;
    };
    if (share(n->w, g.nz + 1, 0.0, 0.0) > 0.5) {
      throw ConfigError(fmt::format(
          "shell.attached_mass entry {} (z = {} m, theta = {} deg) lies in a hole of the shell", k,
          s.attached_mass_z_m[k], s.attached_mass_theta_deg[k]));
    }
    share(n->u, g.nz, 0.5, 0.0);
    share(n->v, g.nz + 1, 0.0, 0.5);
  }
}

// Strain samples of the energy: each row b_r with weight w_r adds w_r (b_r q)^2 / 2, so that
// K = B^T W B
class StrainRows {
 public:
  StrainRows(const GridLayout& g, const DofNumbering& n) : g_(g), n_(n) {}

  // a linear form of grid values, or false when a point is absent
  bool Form(std::initializer_list<Term> terms, Row* row) const {
    row->clear();
    for (const Term& t : terms) {
      const int64_t d = Lookup(t.field, t.i, t.j);
      if (d == kAbsent) return false;
      if (d >= 0) row->push_back({d, t.c});
    }
    return true;
  }
  void Add(const Row& a, double ca, const Row& b, double cb, double weight) {
    if (weight == 0.0) return;
    const int64_t r = static_cast<int64_t>(weights_.size());
    for (const auto& [d, c] : a) triplets_.emplace_back(r, d, ca * c);
    for (const auto& [d, c] : b) triplets_.emplace_back(r, d, cb * c);
    weights_.push_back(weight);
  }
  // the pair energy s (x^2 + y^2 + 2 nu x y) of two strains, or s (1 - nu^2) x^2 with y free
  void PairEnergy(bool has_x, const Row& x, bool has_y, const Row& y, double s, double nu,
                  double area) {
    const Row none;
    if (has_x && has_y) {
      Add(x, 1.0, y, 1.0, area * s * 0.5 * (1.0 + nu));
      Add(x, 1.0, y, -1.0, area * s * 0.5 * (1.0 - nu));
    } else if (has_x) {
      Add(x, 1.0, none, 0.0, area * s * (1.0 - nu * nu));
    } else if (has_y) {
      Add(y, 1.0, none, 0.0, area * s * (1.0 - nu * nu));
    }
  }
  // K = B^T W B, (dofs x dofs), N/m
  Eigen::SparseMatrix<double> Stiffness() const {
    const Eigen::Index n = n_.mass_kg.size();
    Eigen::SparseMatrix<double> B(static_cast<Eigen::Index>(weights_.size()), n);
    B.setFromTriplets(triplets_.begin(), triplets_.end());
    const Eigen::Map<const Eigen::VectorXd> w(weights_.data(),
                                              static_cast<Eigen::Index>(weights_.size()));
    const Eigen::SparseMatrix<double> WB = w.asDiagonal() * B;
    Eigen::SparseMatrix<double> k(B.transpose() * WB);
    k.makeCompressed();
    return k;
  }

 private:
  int64_t Lookup(Field f, int i, int j) const {
    const int rows = f == Field::kU ? g_.nz : g_.nz + 1;
    if (i < 0 || i >= rows) return kAbsent;
    const auto& index = f == Field::kU ? n_.u : (f == Field::kV ? n_.v : n_.w);
    return index[static_cast<size_t>(i) * g_.nth + g_.Wrap(j)];
  }

  const GridLayout& g_;
  const DofNumbering& n_;
  std::vector<Eigen::Triplet<double>> triplets_;
  std::vector<double> weights_;
};

// Sanders' membrane and bending energy of every node (i, j) and corner (i + 1/2, j + 1/2)
void AddShellEnergy(const GridLayout& g, const MaterialConfig& material, double h,
                    StrainRows* rows) {
  const double E = material.youngs_modulus_pa, nu = material.poisson_ratio;
  const double C = E * h / (1.0 - nu * nu);                   // membrane stiffness, N/m
  const double D = E * h * h * h / (12.0 * (1.0 - nu * nu));  // bending stiffness, N m
  const double R = g.R, dz = g.dz, dth = g.dth, ds = g.ds;
  const Row none;
  Row ex, et, kx, kt, gm, tw;
  for (int i = 0; i <= g.nz; ++i) {
    for (int j = 0; j < g.nth; ++j) {
      if (g.InHole(g.Z(i), j * dth)) continue;
      const double area = dz * g.Fz(i) * ds * g.Fth(j);
      // node (i, j): eps_x = u_x, eps_th = (v_th + w) / R, kappa_x = -w_xx,
      // kappa_th = (v_th - w_thth) / R^2
      const bool has_ex =
          rows->Form({{Field::kU, i, j, 1.0 / dz}, {Field::kU, i - 1, j, -1.0 / dz}}, &ex);
      const bool has_et = rows->Form({{Field::kV, i, j, 1.0 / (R * dth)},
                                      {Field::kV, i, j - 1, -1.0 / (R * dth)},
                                      {Field::kW, i, j, 1.0 / R}},
                                     &et);
      const bool has_kx = rows->Form({{Field::kW, i + 1, j, -1.0 / (dz * dz)},
                                      {Field::kW, i, j, 2.0 / (dz * dz)},
                                      {Field::kW, i - 1, j, -1.0 / (dz * dz)}},
                                     &kx);
      const bool has_kt = rows->Form({{Field::kV, i, j, 1.0 / (R * R * dth)},
                                      {Field::kV, i, j - 1, -1.0 / (R * R * dth)},
                                      {Field::kW, i, j + 1, -1.0 / (R * R * dth * dth)},
                                      {Field::kW, i, j, 2.0 / (R * R * dth * dth)},
                                      {Field::kW, i, j - 1, -1.0 / (R * R * dth * dth)}},
                                     &kt);
      rows->PairEnergy(has_ex, ex, has_et, et, C, nu, area);
      rows->PairEnergy(has_kx, kx, has_kt, kt, D, nu, area);
      // corner (i + 1/2, j + 1/2): shear gamma = v_x + u_th / R and Sanders' twist
      // tau = (-w_xth + 3/4 v_x - u_th / (4 R)) / R
      if (i == g.nz || g.InHole(g.Z(i + 0.5), (j + 0.5) * dth)) continue;
      if (rows->Form({{Field::kV, i + 1, j, 1.0 / dz},
                      {Field::kV, i, j, -1.0 / dz},
                      {Field::kU, i, j + 1, 1.0 / (R * dth)},
                      {Field::kU, i, j, -1.0 / (R * dth)}},
                     &gm)) {
        rows->Add(gm, 1.0, none, 0.0, dz * ds * C * 0.5 * (1.0 - nu));
      }
      const double cw = -1.0 / (R * dz * dth);
      if (rows->Form({{Field::kW, i + 1, j + 1, cw},
                      {Field::kW, i + 1, j, -cw},
                      {Field::kW, i, j + 1, -cw},
                      {Field::kW, i, j, cw},
                      {Field::kV, i + 1, j, 0.75 / (R * dz)},
                      {Field::kV, i, j, -0.75 / (R * dz)},
                      {Field::kU, i, j + 1, -0.25 / (R * R * dth)},
                      {Field::kU, i, j, 0.25 / (R * R * dth)}},
                     &tw)) {
        rows->Add(tw, 1.0, none, 0.0, dz * ds * 2.0 * D * (1.0 - nu));
      }
    }
  }
}

// Springs: bolts across every seam (axial, arc and radial), mounts to ground at the end rims
void AddSprings(const GridLayout& g, StrainRows* rows) {
  if (!g.real) return;
  const ShellConfig& shell = g.shell;
  const double length = g.tube.length_m;
  const int nz = g.nz;
  const Row none;
  Row a, b;
  auto spring = [&](Field f, int ia, int ja, Field g2, int ib, int jb, double k) {
    if (k <= 0.0) return;
    const bool has_a = rows->Form({{f, ia, ja, 1.0}}, &a);
    const bool has_b = rows->Form({{g2, ib, jb, -1.0}}, &b);
    if (has_a && has_b) rows->Add(a, 1.0, b, 1.0, k);
  };
  // one bolt at z: three springs of stiffness k across the cut at row (ib, iu)
  auto bolt_springs = [&](int js, double z, double k) {
    const int ib = std::clamp(static_cast<int>(std::lround((z + 0.5 * length) / g.dz)), 0, nz);
    const int iu = std::clamp(static_cast<int>(std::floor((z + 0.5 * length) / g.dz)), 0, nz - 1);
    spring(Field::kW, ib, js, Field::kW, ib, js + 1, k);
    spring(Field::kU, iu, js, Field::kU, iu, js + 1, k);
    spring(Field::kV, ib, js - 1, Field::kV, ib, js + 1, k);
  };
  for (int js : g.seams) {
    for (size_t bolt = 0; bolt < shell.bolt_z_m.size(); ++bolt) {
      const double z = shell.bolt_z_m[bolt];
      const double k =
          shell.bolt_stiffness_n_m *
          (shell.bolt_stiffness_scale.empty() ? 1.0 : shell.bolt_stiffness_scale[bolt]);
      if (shell.bolt_model == BoltModel::kPoint) {
        bolt_springs(js, z, k);
        continue;
      }
      // a tie: the same total stiffness over the rows within the tie length (at least one)
      const int tie_rows =
          std::max(1, static_cast<int>(std::lround(shell.bolt_tie_length_m / g.dz)));
      for (int r = 0; r < tie_rows; ++r) {
        bolt_springs(js, z + (r - 0.5 * (tie_rows - 1)) * g.dz, k / tie_rows);
      }
    }
  }
  for (const auto& [i, iu, k_per_m] : {std::tuple{0, 0, shell.flange_mount_stiffness_n_m2},
                                       std::tuple{nz, nz - 1, shell.tool_mount_stiffness_n_m2}}) {
    if (k_per_m <= 0.0) continue;
    for (int j = 0; j < g.nth; ++j) {
      const double k = k_per_m * g.ds * g.Fth(j);
      for (const auto& [f, ii] :
           {std::pair{Field::kW, i}, std::pair{Field::kU, iu}, std::pair{Field::kV, i}}) {
        if (rows->Form({{f, ii, j, 1.0}}, &a)) rows->Add(a, 1.0, none, 0.0, k);
      }
    }
  }
}

struct RayleighFit {
  double alpha_1_s{0.0}, beta_s{0.0};
  bool loss_law{true};
};

// Rayleigh damping through (f_low, eta) and (f_high, eta_high): zeta = alpha/(2 w) + beta w / 2;
// under the loss law, through the law's own values there. Throws ConfigError naming the keys when
// no fit has non-negative coefficients.
RayleighFit FitRayleigh(const MaterialConfig& material, const ShellConfig& shell) {
  RayleighFit fit;
  fit.loss_law = shell.damping == DampingModel::kLaw;
  auto law = [&](double f_hz) {
    return material.loss_factor * std::pow(f_hz / shell.loss_reference_hz, shell.loss_exponent);
  };
  const double eta_low = fit.loss_law ? law(shell.loss_low_hz) : material.loss_factor;
  const double eta_high = fit.loss_law                   ? law(shell.loss_high_hz)
                          : shell.loss_factor_high > 0.0 ? shell.loss_factor_high
                                                         : eta_low;
  const double w1 = 2.0 * kPi * shell.loss_low_hz, w2 = 2.0 * kPi * shell.loss_high_hz;
  const double z1 = 0.5 * eta_low, z2 = 0.5 * eta_high;
  const double beta = 2.0 * (z2 * w2 - z1 * w1) / (w2 * w2 - w1 * w1);
  const double alpha = 2.0 * w1 * z1 - beta * w1 * w1;
  if ((alpha < 0.0 || beta < 0.0) && fit.loss_law) {
    throw ConfigError(fmt::format(
        "shell.loss_exponent = {}: the FD rung's Rayleigh curve through the loss law at {} and {} "
        "Hz needs a negative coefficient (alpha = {:.4g}, beta = {:.4g}); the law's ratio between "
        "them must stay within [f_low / f_high, f_high / f_low]",
        shell.loss_exponent, shell.loss_low_hz, shell.loss_high_hz, alpha, beta));
  }
  if (alpha < 0.0 || beta < 0.0) {
    throw ConfigError(fmt::format(
        "shell.loss_factor_high = {} with material.loss_factor = {} between {} and {} Hz has no "
        "Rayleigh fit with non-negative coefficients (alpha = {:.4g}, beta = {:.4g}); keep "
        "eta_high / eta_low within [f_low / f_high, f_high / f_low]",
        eta_high, eta_low, shell.loss_low_hz, shell.loss_high_hz, alpha, beta));
  }
  fit.alpha_1_s = alpha;
  fit.beta_s = beta;
  return fit;
}

// The mode cache's key of a structure on an nz x nth grid.
std::string CacheKey(TubeConfig tube, MaterialConfig material, ShellConfig shell, int nz, int nth) {
  // The key is the serialized sections, so that a field added to any of them enters it without
  // anyone remembering to: only the fields known to set no mode are reset to their defaults
  // first (the tube's mount offset and contact region, the loss factor and the damping keys).
  const TubeConfig tube_defaults;
  tube.center_from_flange_m = tube_defaults.center_from_flange_m;
  tube.contact_z_min_m = tube_defaults.contact_z_min_m;
  tube.contact_z_max_m = tube_defaults.contact_z_max_m;
  material.loss_factor = MaterialConfig{}.loss_factor;
  const ShellConfig shell_defaults;
  shell.damping = shell_defaults.damping;
  shell.loss_exponent = shell_defaults.loss_exponent;
  shell.loss_reference_hz = shell_defaults.loss_reference_hz;
  shell.loss_low_hz = shell_defaults.loss_low_hz;
  shell.loss_high_hz = shell_defaults.loss_high_hz;
  shell.loss_factor_high = shell_defaults.loss_factor_high;
  shell.dispersion = shell_defaults.dispersion;  // applied to the solved modes, not in them
  return fmt::format("shell-v2 nz={} nth={}\ntube:\n{}material:\n{}shell:\n{}", nz, nth,
                     ToYaml(tube), ToYaml(material), ToYaml(shell));
}

}  // namespace

ShellModel::ShellModel(const TubeConfig& tube, const MaterialConfig& material,
                       const ShellConfig& shell)
    : tube_(tube), material_(material), shell_(shell) {
  tube.Validate();
  shell.Validate(tube);
  // the grid and its DOFs
  const GridLayout grid = LayOut(tube, shell);
  radius_m_ = grid.R;
  nz_ = grid.nz;
  nth_ = grid.nth;
  dz_m_ = grid.dz;
  dth_rad_ = grid.dth;
  DofNumbering dofs = NumberDofs(grid, material.density_kg_m3 * tube.wall_thickness_m);
  AddAttachedMasses(grid, &dofs);
  // K from the shell's energy and the springs
  StrainRows rows(grid, dofs);
  AddShellEnergy(grid, material, tube.wall_thickness_m, &rows);
  AddSprings(grid, &rows);
  stiffness_ = rows.Stiffness();
  w_index_ = std::move(dofs.w);
  u_index_ = std::move(dofs.u);
  v_index_ = std::move(dofs.v);
  mass_kg_ = std::move(dofs.mass_kg);
  // the FD rung's damping, and the mode cache's key
  const RayleighFit fit = FitRayleigh(material, shell);
  alpha_ = fit.alpha_1_s;
  beta_ = fit.beta_s;
  loss_law_ = fit.loss_law;
  key_ = CacheKey(tube, material, shell, nz_, nth_);
}

Eigen::SparseMatrix<double> ShellModel::MassScaledStiffness() const {
  const Eigen::VectorXd s = mass_kg_.cwiseSqrt().cwiseInverse();
  Eigen::SparseMatrix<double> a = s.asDiagonal() * stiffness_ * s.asDiagonal();
  a.makeCompressed();
  return a;
}

double ShellModel::DampingRatio(double omega_rad_s) const {
  if (!loss_law_) return RayleighDampingRatio(omega_rad_s);
  const double f_hz = omega_rad_s / (2.0 * kPi);
  return 0.5 * material_.loss_factor *
         std::pow(f_hz / shell_.loss_reference_hz, shell_.loss_exponent);
}

double ShellModel::RayleighDampingRatio(double omega_rad_s) const {
  return alpha_ / (2.0 * omega_rad_s) + 0.5 * beta_ * omega_rad_s;
}

int64_t ShellModel::WIndex(int i, int j) const {
  if (i < 0 || i > nz_ || j < 0 || j >= nth_) return -1;
  const int64_t d = w_index_[static_cast<size_t>(i) * nth_ + j];
  return d >= 0 ? d : -1;
}

int64_t ShellModel::UIndex(int i, int j) const {
  if (i < 0 || i >= nz_ || j < 0 || j >= nth_) return -1;
  const int64_t d = u_index_[static_cast<size_t>(i) * nth_ + j];
  return d >= 0 ? d : -1;
}

int64_t ShellModel::VIndex(int i, int j) const {
  if (i < 0 || i > nz_ || j < 0 || j >= nth_) return -1;
  const int64_t d = v_index_[static_cast<size_t>(i) * nth_ + j];
  return d >= 0 ? d : -1;
}

bool ShellModel::ArcLinked(int i, int j) const {
  if (WIndex(i, j) < 0 || WIndex(i, (j + 1) % nth_) < 0) return false;
  return v_index_[static_cast<size_t>(i) * nth_ + j] != kAbsent;
}

bool ShellModel::AcceptsForce(double z_m, double theta_rad) const {
  double absent = 0.0;
  PointWeights(z_m, theta_rad, &absent);
  return absent <= 0.5;
}

Eigen::VectorXd ShellModel::RadialForceWeights(double z_m, double theta_rad) const {
  double absent = 0.0;
  const Eigen::VectorXd out = PointWeights(z_m, theta_rad, &absent);
  if (absent > 0.5) {
    throw ConfigError(fmt::format("contact at z = {} m, theta = {} rad lies in a hole of the shell",
                                  z_m, theta_rad));
  }
  return out / (1.0 - absent);
}

Eigen::VectorXd ShellModel::PointWeights(double z_m, double theta_rad, double* absent) const {
  const double x = (z_m + 0.5 * tube_.length_m) / dz_m_;
  if (!(x >= -1e-9 && x <= nz_ + 1e-9)) {
    throw ConfigError(
        fmt::format("contact z = {} m lies off the tube (|z| <= {} m)", z_m, 0.5 * tube_.length_m));
  }
  double y = WrapAngle(theta_rad) / dth_rad_;
  if (y < 0.0) y += nth_;
  Eigen::VectorXd out = Eigen::VectorXd::Zero(dofs());
  *absent = 0.0;
  for (const auto& [d, wgt] : BilinearPoints(w_index_, nz_ + 1, nth_, x, y)) {
    if (d >= 0) out[d] += wgt;
    if (d == kAbsent) *absent += wgt;
  }
  return out;
}

int ShellModel::VisitSensorTerms(double z_m, double theta_rad, double diameter_m,
                                 const std::function<void(int64_t, double)>& term) const {
  const double R = radius_m_, h = tube_.wall_thickness_m;
  const double dz = dz_m_, dth = dth_rad_;
  auto at = [&](int i, int j, auto field) -> int64_t {
    if (i < 0) return kAbsent;
    j = ((j % nth_) + nth_) % nth_;
    if (field == 0) return i <= nz_ ? w_index_[static_cast<size_t>(i) * nth_ + j] : kAbsent;
    if (field == 1) return i < nz_ ? u_index_[static_cast<size_t>(i) * nth_ + j] : kAbsent;
    return i <= nz_ ? v_index_[static_cast<size_t>(i) * nth_ + j] : kAbsent;
  };
  // outer-surface strain at node (i, j): eps_x + eps_th + h/2 (kappa_x + kappa_th)
  auto node_row = [&](int i, int j) {
    const std::initializer_list<std::tuple<int, int, int, double>> terms = {
        {1, i, j, 1.0 / dz},
        {1, i - 1, j, -1.0 / dz},
        {2, i, j, 1.0 / (R * dth) + 0.5 * h / (R * R * dth)},
        {2, i, j - 1, -1.0 / (R * dth) - 0.5 * h / (R * R * dth)},
        {0, i, j, 1.0 / R + 0.5 * h * (2.0 / (dz * dz) + 2.0 / (R * R * dth * dth))},
        {0, i + 1, j, -0.5 * h / (dz * dz)},
        {0, i - 1, j, -0.5 * h / (dz * dz)},
        {0, i, j + 1, -0.5 * h / (R * R * dth * dth)},
        {0, i, j - 1, -0.5 * h / (R * R * dth * dth)}};
    for (const auto& [f, ii, jj, c] : terms) {
      if (at(ii, jj, f) == kAbsent) return false;
    }
    for (const auto& [f, ii, jj, c] : terms) {
      const int64_t d = at(ii, jj, f);
      if (d >= 0) term(d, c);
    }
    return true;
  };
  const int ic = static_cast<int>(std::lround((z_m + 0.5 * tube_.length_m) / dz));
  double y = WrapAngle(theta_rad) / dth;
  const int jc = static_cast<int>(std::lround(y));
  const int reach_i = static_cast<int>(std::ceil(0.5 * diameter_m / dz)) + 1;
  const int reach_j = static_cast<int>(std::ceil(0.5 * diameter_m / (R * dth))) + 1;
  int count = 0;
  for (int i = ic - reach_i; i <= ic + reach_i; ++i) {
    for (int j = jc - reach_j; j <= jc + reach_j; ++j) {
      const double dzn = NodeZ(i) - z_m, dsn = R * (j * dth - y * dth);
      if (std::hypot(dzn, dsn) > 0.5 * diameter_m) continue;
      if (node_row(i, j)) ++count;
    }
  }
  if (count == 0 && node_row(ic, jc)) count = 1;  // disc smaller than the grid
  if (count == 0) {
    throw ConfigError(
        fmt::format("microphone at z = {} m, theta = {} rad has no complete grid node "
                    "under it (seam, hole or end)",
                    z_m, theta_rad));
  }
  return count;
}

Eigen::VectorXd ShellModel::SensorRow(double z_m, double theta_rad, double diameter_m) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(dofs());
  const int count =
      VisitSensorTerms(z_m, theta_rad, diameter_m, [&out](int64_t d, double c) { out[d] += c; });
  return out / count;
}

std::vector<std::pair<int64_t, double>> ShellModel::SensorTerms(double z_m, double theta_rad,
                                                                double diameter_m) const {
  std::vector<std::pair<int64_t, double>> terms;
  const int count = VisitSensorTerms(z_m, theta_rad, diameter_m,
                                     [&terms](int64_t d, double c) { terms.emplace_back(d, c); });
  for (auto& t : terms) t.second /= count;
  return terms;
}

std::vector<int64_t> ShellModel::SensorDofs(double z_m, double theta_rad, double diameter_m) const {
  std::vector<int64_t> dofs;
  VisitSensorTerms(z_m, theta_rad, diameter_m, [&dofs](int64_t d, double) { dofs.push_back(d); });
  std::sort(dofs.begin(), dofs.end());
  dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
  return dofs;
}

Eigen::MatrixXd ShellModel::SensorRows(const MicArrayConfig& mics) const {
  Eigen::MatrixXd rows(mics.count(), dofs());
  for (int m = 0; m < mics.count(); ++m) {
    rows.row(m) =
        SensorRow(mics.z_m[m], mics.theta_deg[m] * kPi / 180.0, mics.disc_diameter_m).transpose();
  }
  return rows;
}

double ShellModel::StrainEnergy(const Eigen::VectorXd& q_m) const {
  return 0.5 * q_m.dot(stiffness_ * q_m);
}

}  // namespace sonicboom::acoustics
