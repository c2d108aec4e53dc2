#pragma once
/// Exact 3-D linear elasticity of the ideal simply supported (shear-diaphragm) isotropic tube
/// (docs/reference_model.md, "Against exact 3-D elasticity"). With the tube along z in [0, L],
///   u_r = U(r) cos(n th) sin(k z),  u_th = V(r) sin(n th) sin(k z),  u_z = W(r) cos(n th) cos(k z)
/// satisfy the end conditions u_r = u_th = 0, sigma_zz = 0 at z = 0 and L for k = m pi / L and
/// separate Navier's equations exactly: what is left is a 1-D eigenproblem through the wall per
/// (m, n). It is solved by Rayleigh-Ritz on one Lagrange element of degree p through the wall
/// (traction-free faces are natural), which converges spectrally in p. m = 0 keeps only u_z =
/// W(r) cos(n th) (the axially uniform shear modes; u_r and u_th vanish with sin(0)).
/// Each (m, n >= 1) root is a degenerate pair (the same shape turned by pi / (2 n)); n = 0 holds
/// the torsional (V alone) and the axisymmetric (U, W) families.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sonicboom/core/tube.h"

namespace sonicboom::solid {

/// Which fields of the cross-section problem are solved.
enum class WallFields { kAll, kAxialOnly };

/// The radial degrees a cross-section problem accepts (one GLL element through the wall).
inline constexpr int kMinRadialDegree = 2;
inline constexpr int kMaxRadialDegree = 14;

/// (roots) omega, rad/s, ascending, of the cross-section problem of axial wavenumber k (rad/m)
/// and circumferential order n: every root of the discretized problem, 3 (p + 1) of them (p + 1
/// for kAxialOnly). k need not be m pi / L: k = 0 with kAll is the plane-strain ring together with
/// the anti-plane (W) family. Throws ConfigError for a degree outside [kMinRadialDegree,
/// kMaxRadialDegree] or a negative n or k.
Eigen::VectorXd WallSpectrum(const TubeConfig& tube, const MaterialConfig& material,
                             double k_rad_m, int64_t n, int radial_degree, WallFields fields);

/// One (m, n) root of the simply supported tube.
struct ExactMode {
  int64_t m{0};       // axial half-waves
  int64_t n{0};       // circumferential waves
  int64_t branch{0};  // rank of the root within its (m, n), 0 = lowest
  double frequency_hz{0.0};
  int multiplicity{1};  // 2 for n >= 1 (a degenerate pair), 1 for n = 0
};

struct ExactModeRequest {
  double max_frequency_hz{20000.0};  // every root up to here
  int radial_degree{12};
};

struct ExactModeList {
  std::vector<ExactMode> modes;  // ascending in frequency
  int64_t rigid_body_modes{0};   // the axial slide (m = 0, n = 0, W constant): omega = 0, below kSolidRigidBodyHz
  /// Modes below f_hz with their multiplicity (rigid-body ones not counted).
  int64_t CountBelow(double f_hz) const;
  /// Every mode's frequency, a degenerate pair twice, ascending, Hz.
  std::vector<double> ExpandedFrequenciesHz() const;
};

/// Every root of the simply supported tube up to request.max_frequency_hz. Families are scanned
/// over m for each n until three successive m and then three successive n hold no root below
/// the limit (the lowest root of a family rises with m once past its minimum, and with n).
ExactModeList ExactSimplySupportedModes(const TubeConfig& tube, const MaterialConfig& material,
                                        const ExactModeRequest& request);

/// Closed forms the cross-section solver is checked against (Bessel functions of the first and
/// second kind; roots by sign changes on a fine scan, then bisection to machine precision).
/// Torsion (n = 0, V alone): omega^2 = c_s^2 (k^2 + beta^2), beta = 0 (V = r: omega = c_s k) or
/// a root of J2(beta a) Y2(beta b) - J2(beta b) Y2(beta a). The lowest `count`, rad/s.
std::vector<double> TorsionOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                  double k_rad_m, int count);
/// The anti-plane family (k = 0, W(r) cos(n th)): omega = c_s beta, J_n'(beta a) Y_n'(beta b) =
/// J_n'(beta b) Y_n'(beta a); for n = 0 the rigid slide (0) first. The lowest `count`, rad/s.
std::vector<double> AntiPlaneOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                    int64_t n, int count);
/// The breathing ring in plane strain (k = 0, n = 0, U alone): omega = c_p alpha with
/// sigma_rr((lambda + 2 mu) alpha X0(alpha r) - 2 mu X1(alpha r) / r) = 0 on both faces. The
/// lowest `count`, rad/s.
std::vector<double> BreathingOmegas(const TubeConfig& tube, const MaterialConfig& material,
                                    int count);

}  // namespace sonicboom::solid
