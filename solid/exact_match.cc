// Mode shapes labelled by their (m, n) on the simply supported tube, and matched to the exact
// roots by family or by rank.
#include "sonicboom/solid/exact_match.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <utility>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/statistics.h"

namespace sonicboom::solid {
namespace {

enum class Axial { kSin, kCos };

// (orders x points) sin(m pi s) or cos(m pi s) for m = 0..max_m, s = z / L + 1/2
Eigen::MatrixXd AxialBasis(const std::vector<double>& z_m, double length_m, int64_t max_m,
                           Axial kind) {
  Eigen::MatrixXd b(max_m + 1, static_cast<Eigen::Index>(z_m.size()));
  for (int64_t m = 0; m <= max_m; ++m) {
    for (size_t i = 0; i < z_m.size(); ++i) {
      const double x = kPi * static_cast<double>(m) * (z_m[i] / length_m + 0.5);
      b(m, static_cast<Eigen::Index>(i)) = kind == Axial::kSin ? std::sin(x) : std::cos(x);
    }
  }
  return b;
}

// (points x orders) cos(n th) or sin(n th), n = 0..max_n
Eigen::MatrixXd ArcBasis(const std::vector<double>& theta, int64_t max_n, bool sine) {
  Eigen::MatrixXd b(static_cast<Eigen::Index>(theta.size()), max_n + 1);
  for (size_t j = 0; j < theta.size(); ++j) {
    for (int64_t n = 0; n <= max_n; ++n) {
      const double x = static_cast<double>(n) * theta[j];
      b(static_cast<Eigen::Index>(j), n) = sine ? std::sin(x) : std::cos(x);
    }
  }
  return b;
}

// ((max_m + 1) x (max_n + 1)) the energy of one component on every (m, n): each projection
// squared over its basis function's own squared norm on the grid, both orientations summed
Eigen::MatrixXd ComponentEnergy(const SurfaceComponent& c, double length_m, int64_t max_m,
                                int64_t max_n, Axial axial) {
  Eigen::MatrixXd energy = Eigen::MatrixXd::Zero(max_m + 1, max_n + 1);
  if (c.values.size() == 0) return energy;
  SONICBOOM_DEMAND(c.values.rows() == static_cast<Eigen::Index>(c.z_m.size()) &&
                   c.values.cols() == static_cast<Eigen::Index>(c.theta_rad.size()));
  const Eigen::MatrixXd za = AxialBasis(c.z_m, length_m, max_m, axial);
  const Eigen::VectorXd za_norm = za.rowwise().squaredNorm();
  for (bool sine : {false, true}) {
    const Eigen::MatrixXd ta = ArcBasis(c.theta_rad, max_n, sine);
    const Eigen::RowVectorXd ta_norm = ta.colwise().squaredNorm();
    const Eigen::MatrixXd proj = za * c.values * ta;  // (m x n)
    for (int64_t m = 0; m <= max_m; ++m) {
      for (int64_t n = 0; n <= max_n; ++n) {
        const double norm = za_norm(m) * ta_norm(n);
        if (norm > 1e-12 * static_cast<double>(c.values.size()))
          energy(m, n) += proj(m, n) * proj(m, n) / norm;
      }
    }
  }
  return energy;
}

// median, max and signed median of the errors
void Summarize(ExactComparison* c) {
  std::vector<double> abs;
  for (double e : c->relative_error) abs.push_back(std::abs(e));
  c->matched = static_cast<int64_t>(c->relative_error.size());
  if (abs.empty()) return;
  c->median_abs = Median(abs);
  c->max_abs = *std::max_element(abs.begin(), abs.end());
  c->signed_median = Median(c->relative_error);
}

}  // namespace

ModeLabel LabelSimplySupportedMode(const TubeConfig& tube,
                                   const std::array<SurfaceComponent, 3>& components,
                                   int64_t max_m, int64_t max_n) {
  const double length = tube.length_m;
  // u_r and u_th carry sin(m pi s), u_z cos(m pi s); the arc orientations are summed
  const Eigen::MatrixXd energy = ComponentEnergy(components[0], length, max_m, max_n, Axial::kSin) +
                                 ComponentEnergy(components[1], length, max_m, max_n, Axial::kSin) +
                                 ComponentEnergy(components[2], length, max_m, max_n, Axial::kCos);
  double total = 0.0;
  for (const SurfaceComponent& c : components) total += c.values.squaredNorm();
  ModeLabel label;
  Eigen::Index m = 0, n = 0;
  const double best = energy.maxCoeff(&m, &n);
  label.m = m;
  label.n = n;
  label.purity = total > 0.0 ? std::min(1.0, best / total) : 0.0;
  return label;
}

SolidLabelGrid MakeSolidLabelGrid(const SolidTubeModel& model, int rows, int columns) {
  SolidLabelGrid g;
  const double length = model.tube().length_m;
  for (int i = 0; i < rows; ++i) g.z_m.push_back(length * ((i + 0.5) / rows - 0.5));
  for (int j = 0; j < columns; ++j) g.theta_rad.push_back(2 * kPi * j / columns);
  std::vector<std::pair<double, double>> points;
  for (double z : g.z_m)
    for (double t : g.theta_rad) points.emplace_back(z, t);
  g.rows = model.SurfacePointRows(points);
  return g;
}

std::vector<LabelledMode> LabelSolidModes(const SolidTubeModel& model, const SolidLabelGrid& grid,
                                          const SolidModes& modes) {
  const Eigen::MatrixXd read =
      modes.projections.size() > 0 ? modes.projections : Eigen::MatrixXd(grid.rows * modes.shapes);
  SONICBOOM_DEMAND(read.rows() == grid.rows.rows() && read.cols() == modes.omega_rad_s.size());
  const auto rows = static_cast<Eigen::Index>(grid.z_m.size());
  const auto columns = static_cast<Eigen::Index>(grid.theta_rad.size());
  std::vector<LabelledMode> out;
  for (Eigen::Index k = 0; k < read.cols(); ++k) {
    std::array<SurfaceComponent, 3> c;
    for (int comp = 0; comp < 3; ++comp) {
      c[comp].z_m = grid.z_m;
      c[comp].theta_rad = grid.theta_rad;
      c[comp].values.resize(rows, columns);
      for (Eigen::Index i = 0; i < rows; ++i)
        for (Eigen::Index j = 0; j < columns; ++j)
          c[comp].values(i, j) = read(3 * (i * columns + j) + comp, k);
    }
    out.push_back({modes.omega_rad_s(k) / (2 * kPi),
                   LabelSimplySupportedMode(model.tube(), c, 40, 30)});
  }
  return out;
}

ExactComparison CompareByFamily(const ExactModeList& exact, const std::vector<LabelledMode>& model,
                                double band_hz) {
  // each family's model frequencies, ascending
  std::map<std::pair<int64_t, int64_t>, std::vector<double>> families;
  ExactComparison c;
  for (const LabelledMode& mode : model) {
    families[{mode.label.m, mode.label.n}].push_back(mode.frequency_hz);
    c.model_count += mode.frequency_hz < band_hz ? 1 : 0;
  }
  for (auto& [key, f] : families) std::sort(f.begin(), f.end());
  // the exact modes of each family in order: root `branch` takes the family's entries
  // multiplicity * branch .. (the lower branches' modes come first)
  std::map<std::pair<int64_t, int64_t>, size_t> taken;
  std::vector<ExactMode> by_family = exact.modes;
  std::sort(by_family.begin(), by_family.end(), [](const ExactMode& x, const ExactMode& y) {
    return std::tie(x.m, x.n, x.branch) < std::tie(y.m, y.n, y.branch);
  });
  std::vector<std::pair<ExactMode, double>> errors;  // every matched exact mode, its error
  for (const ExactMode& e : by_family) {
    const auto key = std::make_pair(e.m, e.n);
    size_t& next = taken[key];
    const auto it = families.find(key);
    for (int copy = 0; copy < e.multiplicity; ++copy, ++next) {
      if (e.frequency_hz >= band_hz) continue;
      if (it == families.end() || next >= it->second.size()) {
        c.unmatched.push_back(e);
        continue;
      }
      errors.emplace_back(e, it->second[next] / e.frequency_hz - 1.0);
    }
  }
  c.exact_count = exact.CountBelow(band_hz);
  std::stable_sort(errors.begin(), errors.end(), [](const auto& x, const auto& y) {
    return x.first.frequency_hz < y.first.frequency_hz;
  });
  for (const auto& [e, err] : errors) c.relative_error.push_back(err);
  Summarize(&c);
  std::stable_sort(errors.begin(), errors.end(), [](const auto& x, const auto& y) {
    return std::abs(x.second) > std::abs(y.second);
  });
  errors.resize(std::min<size_t>(errors.size(), 5));
  c.worst = errors;
  return c;
}

ExactComparison CompareByRank(const ExactModeList& exact, std::vector<double> model_hz,
                              double band_hz) {
  std::sort(model_hz.begin(), model_hz.end());
  const std::vector<double> fe = exact.ExpandedFrequenciesHz();
  ExactComparison c;
  c.exact_count = exact.CountBelow(band_hz);
  c.model_count = std::count_if(model_hz.begin(), model_hz.end(),
                                [band_hz](double f) { return f < band_hz; });
  for (size_t i = 0; i < fe.size() && i < model_hz.size() && fe[i] < band_hz; ++i)
    c.relative_error.push_back(model_hz[i] / fe[i] - 1.0);
  Summarize(&c);
  return c;
}

}  // namespace sonicboom::solid
