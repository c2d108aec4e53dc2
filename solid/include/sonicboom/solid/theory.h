#pragma once
/// Closed-form checks of the reference model: flexural dispersion of a free plate of the wall's
/// thickness (Rayleigh-Lamb's lowest antisymmetric branch, exact 3-D elasticity; Mindlin's
/// thick plate; Kirchhoff's thin plate), and Richardson extrapolation of a converging sequence.

#include <vector>

#include "sonicboom/core/tube.h"

namespace sonicboom::solid {

/// Angular frequency (rad/s) of the A0 Lamb wave of wavenumber k (rad/m) in a free plate of
/// thickness h: the lowest nonzero root of the antisymmetric Rayleigh-Lamb equation.
double RayleighLambA0(const MaterialConfig& material, double thickness_m, double k_rad_m);
/// The same from Mindlin's plate (shear correction pi^2 / 12, rotary inertia): lower root.
double MindlinFlexural(const MaterialConfig& material, double thickness_m, double k_rad_m);
/// Kirchhoff's thin plate: omega = sqrt(D / (rho h)) k^2.
double KirchhoffFlexural(const MaterialConfig& material, double thickness_m, double k_rad_m);

/// Richardson extrapolation of values f_i computed at mesh sizes h_i (coarse to fine, three or
/// more): fits f = f_inf + C h^p to the last three and reports the limit, the observed order and
/// the error estimate of the finest value, |f_finest - f_inf|. Where the sequence does not
/// converge monotonically (the differences change sign or grow), the order is 0 and the error
/// estimate is the last difference |f_finest - f_previous| (the conservative bound).
struct Extrapolation {
  double limit{0.0};
  double order{0.0};
  double error{0.0};  // estimated error of the finest value, same unit as f
};
Extrapolation Richardson(const std::vector<double>& h, const std::vector<double>& f);

}  // namespace sonicboom::solid
