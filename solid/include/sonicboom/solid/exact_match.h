#pragma once
/// A model's modes of the ideal simply supported tube against the exact list (ss_exact.h): each
/// mode shape labelled with its (m, n) by projection on the separable fields, then matched to the
/// exact roots family by family (m, n, branch), or by rank alone.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "sonicboom/core/tube.h"
#include "sonicboom/solid/solid_modes.h"
#include "sonicboom/solid/solid_tube.h"
#include "sonicboom/solid/ss_exact.h"

namespace sonicboom::solid {

/// One displacement component of a mode sampled on a tensor grid of the tube's surface.
struct SurfaceComponent {
  std::vector<double> z_m;        // (Z) tube frame, z in [-L/2, L/2]
  std::vector<double> theta_rad;  // (T)
  Eigen::MatrixXd values;         // (Z x T), m per unit modal coordinate
};

/// The (m, n) a mode shape is, and how clearly.
struct ModeLabel {
  int64_t m{-1}, n{-1};
  double purity{0.0};  // the share of the sampled energy the (m, n) fields hold, 0 to 1
};

/// The (m, n), m <= max_m and n <= max_n, whose fields hold the most of the shape's sampled
/// energy: u_r on sin(m pi s) {cos, sin}(n th), u_th on sin(m pi s) {sin, cos}(n th), u_z on
/// cos(m pi s) {cos, sin}(n th), s = z / L + 1/2, each projection weighted by its own norm on the
/// grid. components: radial (outward), arc, axial.
ModeLabel LabelSimplySupportedMode(const TubeConfig& tube,
                                   const std::array<SurfaceComponent, 3>& components,
                                   int64_t max_m, int64_t max_n);

/// A model's mode with its label.
struct LabelledMode {
  double frequency_hz{0.0};
  ModeLabel label;
};

/// Where the reference solid's modes are labelled: a grid of the outer surface, midpoints along
/// z, evenly around, and the read-out rows of its points (row-major over (z, theta), each
/// point's radial, arc and axial rows in turn: SolidModeRequest::projection_rows).
struct SolidLabelGrid {
  std::vector<double> z_m, theta_rad;
  Eigen::SparseMatrix<double, Eigen::RowMajor> rows;  // (3 z_m.size() theta_rad.size() x dofs)
};
/// The grid of rows x columns points; it resolves m < rows and n < columns / 2.
SolidLabelGrid MakeSolidLabelGrid(const SolidTubeModel& model, int rows = 64, int columns = 96);

/// Every mode of `modes` labelled (m <= 40, n <= 30), from its projections on grid.rows when
/// they are there, else from its shapes.
std::vector<LabelledMode> LabelSolidModes(const SolidTubeModel& model, const SolidLabelGrid& grid,
                                          const SolidModes& modes);

/// A model's modes against the exact ones below a band.
struct ExactComparison {
  int64_t exact_count{0};  // exact modes below the band, a pair counted twice
  int64_t model_count{0};  // the model's modes below the band
  int64_t matched{0};      // exact modes below the band given a model mode
  std::vector<double> relative_error;  // (matched) f_model / f_exact - 1, in the exact order
  double median_abs{0.0}, max_abs{0.0}, signed_median{0.0};
  std::vector<ExactMode> unmatched;  // exact modes below the band left without a model mode
  // by family: the matched exact modes of the largest |error|, largest first (at most 5)
  std::vector<std::pair<ExactMode, double>> worst;
};

/// By (m, n, branch): within each (m, n) the model's modes (all of `model`, past the band too,
/// ascending) take the exact roots of the family in order, a pair's two modes in turn; an exact
/// mode whose family has run out of model modes stays unmatched.
ExactComparison CompareByFamily(const ExactModeList& exact, const std::vector<LabelledMode>& model,
                                double band_hz);

/// By rank: the i-th model mode against the i-th exact one (pairs listed twice), below the band
/// of the exact list; model_count is counted alone.
ExactComparison CompareByRank(const ExactModeList& exact, std::vector<double> model_hz,
                              double band_hz);

}  // namespace sonicboom::solid
