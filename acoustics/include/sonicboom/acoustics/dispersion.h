#pragma once
/// The thick-wall correction of the modal rung (shell.dispersion = thick-plate, docs/shell.md,
/// "Dispersion"). The discretized thin shell errs in two ways a localizer feels as timing: its
/// second differences soften short waves (a wave of wavenumber k on a grid of step d bends as
/// (2 sin(k d / 2) / d)^2, not k^2), and thin-plate theory leaves out transverse shear and rotary
/// inertia, which slow the flexural wave of a 3 mm wall by several per cent at 10 kHz. Both depend
/// on a mode's wavenumbers, which its shape tells: the mean squared first difference of w along z
/// and around the tube over its mean square is the grid's own (2 sin(k d / 2) / d)^2, so it gives
/// back k exactly for one sinusoid and an energy-weighted mean for a mix. Each mode's frequency is
/// then carried by its two parts of omega^2 (Rayleigh's quotient): with g = (k_z^2 + k_th^2) /
/// (q_z + q_th) the continuum's over the grid's squared wavenumber and M = omega_Mindlin(k) /
/// omega_Kirchhoff(k) the thick plate's over the thin plate's at k = |(k_z, k_th)|,
///   omega'^2 = omega^2 [s (M g)^2 + (1 - s) g],
/// bending (second differences, k^4) in the first term, membrane stretching (first differences,
/// k^2) in the second, s = min(1, D (q_z + q_th)^2 / (rho h omega^2)) the share a flat plate's
/// bending gives the shape. Shapes stay as solved.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// omega_Mindlin(k) / omega_Kirchhoff(k) of a flat plate of the wall's thickness and material at
/// wavenumber k (rad/m): the lower root of Mindlin's flexural dispersion with shear coefficient
/// pi^2 / 12, over sqrt(D / (rho h)) k^2. 1 at k = 0, below 1 above.
double MindlinFrequencyRatio(double k_rad_m, double wall_thickness_m, double poisson_ratio);

/// The wavenumbers a mode shape carries: k_z, k_th (rad/m, arc along the mid-surface) inverted
/// from the grid's quotients q_z, q_th (1/m^2). `rows` must hold every w DOF (RowsRead does).
struct ModeWavenumbers {
  double k_axial_rad_m{0.0}, k_arc_rad_m{0.0};
  double q_axial_1_m2{0.0}, q_arc_1_m2{0.0};
};
ModeWavenumbers EstimateWavenumbers(const ShellModel& model, const ModeRows& rows,
                                    Eigen::Index mode);

/// What a correction carries: the grid's error alone (M = 1), or the grid's and the thick wall's.
enum class DispersionParts { kGridOnly, kGridAndThickWall };

/// (modes) omega' / omega above for every mode of `rows`.
Eigen::VectorXd ThickPlateFrequencyFactors(
    const ShellModel& model, const ModeRows& rows,
    DispersionParts parts = DispersionParts::kGridAndThickWall);

/// `rows` with every frequency scaled by its factor and the modes re-sorted ascending (a scaled
/// mode may pass its neighbour); *solved_omega (optional, modes) gets the solved frequencies in
/// the new order (rad/s).
ModeRows ThickPlateCorrected(const ShellModel& model, const ModeRows& rows,
                             Eigen::VectorXd* solved_omega = nullptr);

}  // namespace sonicboom::acoustics
