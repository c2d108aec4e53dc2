#pragma once
/// The tube as a discretized thin cylindrical shell (docs/physics.md, "The discretized shell"),
/// shared by the finite-difference time-domain solver and the numerical modal model: both use the
/// same stiffness K, lumped mass M and Rayleigh damping C = alpha M + beta K, so their signals
/// differ only by time integration and mode truncation.
///
/// Theory: Sanders' thin-shell strains (membrane u_x, (v_th + w)/R, v_x + u_th/R; bending -w_xx,
/// (v_th - w_thth)/R^2 and Sanders' twist), w radial outward. Grid: a staggered (z, theta) grid,
/// w at nodes (i dz, j dth), u at (i + 1/2, j), v at (i, j + 1/2); strains sampled at nodes and
/// cell corners, so the discrete strain energy is U = 1/2 sum_r w_r (b_r q)^2 and K = B^T W B is
/// symmetric positive semi-definite by construction. Second order in dz and dth in the interior.
///
/// Structure: the tube is sawn lengthwise along seam lines; each seam leaves two free edges (the
/// v point on the seam is removed, a kerf of one arc step) coupled by translational springs at the
/// bolts. Holes remove the grid points inside them. Flange and tool ends are free or simply
/// supported (shear diaphragm: v = w = 0), with distributed mount springs to ground. An ideal
/// tube has no seam, holes, bolts or mounts. Where a strain cannot be formed (free edge, hole) the
/// point keeps the energy of the strain it has, with the missing one at its free (stress-free)
/// value.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

enum class BoltModel { kPoint, kTie };
inline constexpr EnumName<BoltModel> kBoltModelNames[] = {{BoltModel::kPoint, "point"},
                                                          {BoltModel::kTie, "tie"}};
inline std::span<const EnumName<BoltModel>> EnumNames(BoltModel) {
  return kBoltModelNames;
}

enum class DampingModel { kLaw, kRayleigh };
inline constexpr EnumName<DampingModel> kDampingModelNames[] = {
    {DampingModel::kLaw, "law"}, {DampingModel::kRayleigh, "rayleigh"}};
inline std::span<const EnumName<DampingModel>> EnumNames(DampingModel) {
  return kDampingModelNames;
}

// thin: the modal rung keeps the frequencies of the discretized thin shell as solved.
// thick-plate: each mode's frequency is carried from the grid's thin-plate dispersion to a thick
// wall's (Mindlin: transverse shear and rotary inertia) at the mode's own axial and
// circumferential wavenumbers, estimated from its shape (acoustics/dispersion.h). The FD rung
// integrates K itself and is never corrected.
enum class Dispersion { kThin, kThickPlate };
inline constexpr EnumName<Dispersion> kDispersionNames[] = {
    {Dispersion::kThin, "thin"}, {Dispersion::kThickPlate, "thick-plate"}};
inline std::span<const EnumName<Dispersion>> EnumNames(Dispersion) {
  return kDispersionNames;
}

/// Grid points per flexural wavelength at the top of the solved mode band that a derived grid
/// keeps (shell.grid_spacing_m = 0): the default 2.5 mm grid holds 8.4 at 20 kHz on the default
/// tube; docs/fidelity.md measures what that costs and gets wrong at each band.
inline constexpr double kGridPointsPerWavelength = 8.0;
/// The coarsest derived spacing, m: the discs, holes and bolt rows stay resolved.
inline constexpr double kCoarsestDerivedSpacingM = 0.02;

/// The arc spacing a scene needs for modes up to band_hz, m: the thin-plate flexural wavelength
/// of the wall at band_hz over kGridPointsPerWavelength, at most kCoarsestDerivedSpacingM.
double DerivedGridSpacing(const TubeConfig& tube, const MaterialConfig& material, double band_hz);

/// Keys under "shell": the discretized tube structure.
struct ShellConfig {
  double grid_spacing_m{0.0025};  // target arc spacing of the grid; 0 = derived (DerivedGridSpacing)
  double axial_spacing_m{0.0025};  // target axial spacing; 0 = grid_spacing_m
  TubeEnds ends{TubeEnds::kFree};
  bool ideal{false};                                // uniform tube: no seam, holes, bolts or mounts
  std::vector<double> seam_theta_deg{90.0, 270.0};  // saw cuts (the tube is split in halves)
  std::vector<double> bolt_z_m{-0.1, 0.0, 0.1};     // bolts along every seam, tube frame
  double bolt_stiffness_n_m{2.0e6};                 // per bolt and direction (axial, arc, radial)
  std::vector<double> bolt_stiffness_scale;  // per bolt_z_m entry: x bolt_stiffness_n_m; [] = 1
  // point: each bolt is three springs at one grid row; tie: its stiffness spread evenly over
  // the rows within bolt_tie_length_m (a clamped washer, or a glued or riveted seam strip)
  BoltModel bolt_model{BoltModel::kPoint};
  double bolt_tie_length_m{0.02};
  std::vector<double> hole_z_m{-0.146, -0.146, -0.146, 0.146, 0.146, 0.146};
  std::vector<double> hole_theta_deg{0.0, 120.0, 240.0, 0.0, 120.0, 240.0};
  double hole_diameter_m{0.006};              // cable holes beside the discs
  double flange_mount_stiffness_n_m2{5.0e6};  // springs to ground per metre of the flange-end rim
  double tool_mount_stiffness_n_m2{1.0e6};    // the same at the tool end (cap)
  // point masses on the wall (a connector, a cable clamp, a disc with its epoxy and leads): each
  // moves with the wall where it sits (lumped onto the w, u and v points around it); no
  // stiffness of its own, no rotary inertia. Entries pair up by index.
  std::vector<double> attached_mass_kg;
  std::vector<double> attached_mass_z_m;  // tube frame
  std::vector<double> attached_mass_theta_deg;
  // loss, eta(f) = 2 zeta(f). law: every mode of the modal rung has the loss of the law
  // eta(f) = material.loss_factor (f / loss_reference_hz)^loss_exponent (0: constant eta, PVC's
  // nearly flat loss); the FD rung, whose damping matrix is C = alpha M + beta K, uses the
  // Rayleigh curve through the law at loss_low_hz and loss_high_hz (docs/shell.md gives its
  // error). rayleigh: both rungs use the Rayleigh curve through material.loss_factor at
  // loss_low_hz and loss_factor_high (0 = material.loss_factor) at loss_high_hz.
  DampingModel damping{DampingModel::kLaw};
  double loss_exponent{0.0};
  double loss_reference_hz{2000.0};
  double loss_low_hz{1000.0};
  double loss_high_hz{5000.0};
  double loss_factor_high{0.0};
  // the modal rung's frequencies (see Dispersion); thick-plate with the 2.5 x 2.5 mm grid is the
  // rung docs/fidelity.md finds within 1 % and 20 us of the reference solid
  Dispersion dispersion{Dispersion::kThickPlate};

  void Serialize(Archive* a);
  /// Cross-field checks against the tube; throws ConfigError naming the key.
  void Validate(const TubeConfig& tube) const;
  double AxialSpacing() const { return axial_spacing_m > 0.0 ? axial_spacing_m : grid_spacing_m; }
};

/// Immutable discretized shell: grid, degrees of freedom, K, M, damping, and the linear maps to
/// the contact force and the piezo outputs. Thread-safe to share.
class ShellModel {
 public:
  ShellModel(const TubeConfig& tube, const MaterialConfig& material, const ShellConfig& shell);

  int64_t dofs() const { return static_cast<int64_t>(mass_kg_.size()); }
  int axial_points() const { return nz_ + 1; }  // node rows, ends included
  int circumferential_points() const { return nth_; }
  double dz_m() const { return dz_m_; }
  double dtheta_rad() const { return dth_rad_; }
  double radius_m() const { return radius_m_; }  // mid-surface
  /// (dofs x dofs) stiffness, N/m, symmetric, lower and upper stored.
  const Eigen::SparseMatrix<double>& stiffness() const { return stiffness_; }
  /// (dofs x dofs) M^-1/2 K M^-1/2, 1/s^2: its eigenvalues are omega^2 (modes, FD stability).
  Eigen::SparseMatrix<double> MassScaledStiffness() const;
  /// (dofs) lumped mass of every DOF, kg.
  const Eigen::VectorXd& mass_kg() const { return mass_kg_; }
  /// Rayleigh coefficients: C = alpha M + beta K (the FD rung's damping).
  double rayleigh_alpha_1_s() const { return alpha_; }
  double rayleigh_beta_s() const { return beta_; }
  /// Modal damping ratio at angular frequency omega (rad/s): the loss law's (shell.damping =
  /// law) or the Rayleigh curve's.
  double DampingRatio(double omega_rad_s) const;
  /// The Rayleigh curve's damping ratio alpha / (2 omega) + beta omega / 2.
  double RayleighDampingRatio(double omega_rad_s) const;

  /// (dofs) radial force distribution of a unit outward point force at (z, theta) of the tube
  /// frame (bilinear over the four surrounding w nodes); its transpose interpolates w there.
  /// Throws ConfigError when the point lies in a hole or off the tube.
  Eigen::VectorXd RadialForceWeights(double z_m, double theta_rad) const;
  /// Whether a point force at (z, theta) has wall to act on (RadialForceWeights would not throw
  /// for a hole); ConfigError off the tube.
  bool AcceptsForce(double z_m, double theta_rad) const;
  /// (dofs) output of a piezo disc centred at (z, theta) of diameter d: outer-surface in-plane
  /// strain (eps_x + eps_th + h/2 (kappa_x + kappa_th)) averaged over the nodes under the disc
  /// (the nearest node where none lies under it). Unit: strain per m of the DOFs.
  Eigen::VectorXd SensorRow(double z_m, double theta_rad, double diameter_m) const;
  /// (mics x dofs) rows of SensorRow for a microphone array.
  Eigen::MatrixXd SensorRows(const MicArrayConfig& mics) const;
  /// The DOFs SensorRow(z, theta, d) reads, ascending (terms that cancel to zero included).
  std::vector<int64_t> SensorDofs(double z_m, double theta_rad, double diameter_m) const;
  /// SensorRow as (DOF, coefficient) terms, unmerged (a DOF may appear more than once; the sum
  /// of its terms is its entry of SensorRow).
  std::vector<std::pair<int64_t, double>> SensorTerms(double z_m, double theta_rad,
                                                      double diameter_m) const;

  /// Strain energy 1/2 q^T K q, J.
  double StrainEnergy(const Eigen::VectorXd& q_m) const;
  /// The w DOF index of node (i, theta index j), -1 when absent or fixed.
  int64_t WIndex(int i, int j) const;
  /// The u (axial) DOF at (i + 1/2, j), i in [0, axial_points() - 1), -1 when absent or fixed.
  int64_t UIndex(int i, int j) const;
  /// The v (arc) DOF at (i, j + 1/2), -1 when absent or fixed.
  int64_t VIndex(int i, int j) const;
  /// Whether w nodes (i, j) and (i, j + 1 mod circumferential_points) are joined by wall (false
  /// across a seam's kerf or a hole).
  bool ArcLinked(int i, int j) const;
  /// Tube-frame z of node row i, m.
  double NodeZ(int i) const { return -0.5 * tube_.length_m + i * dz_m_; }

  /// The mode cache's key: the serialized tube, material and shell sections less the fields
  /// that set no mode (damping, contact region, mount offset), and the grid size.
  const std::string& key() const { return key_; }

  const TubeConfig& tube() const { return tube_; }
  const MaterialConfig& material() const { return material_; }
  const ShellConfig& shell() const { return shell_; }

 private:
  // calls term(dof, coefficient) for every term of a disc's strain sum (before the division by
  // the node count, which it returns); throws ConfigError when no complete node lies under it
  int VisitSensorTerms(double z_m, double theta_rad, double diameter_m,
                       const std::function<void(int64_t, double)>& term) const;
  TubeConfig tube_;
  MaterialConfig material_;
  ShellConfig shell_;
  int nz_{0}, nth_{0};  // axial intervals, circumferential points
  double dz_m_{0.0}, dth_rad_{0.0}, radius_m_{0.0};
  std::vector<int64_t> w_index_, u_index_, v_index_;  // grid -> DOF (or kAbsent / kFixed)
  Eigen::VectorXd mass_kg_;
  Eigen::SparseMatrix<double> stiffness_;
  double alpha_{0.0}, beta_{0.0};
  bool loss_law_{true};  // shell.damping is law
  std::string key_;
  // (dofs) bilinear weights of the four w nodes around (z, theta), before normalization;
  // `absent` gets the share of nodes that do not exist (in a hole)
  Eigen::VectorXd PointWeights(double z_m, double theta_rad, double* absent) const;
};

}  // namespace sonicboom::acoustics
