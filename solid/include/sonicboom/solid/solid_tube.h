#pragma once
/// The independent reference model of the tube: a 3-D linear-elastic solid (no shell theory:
/// transverse shear, rotary inertia and thickness stretch come with it) on hexahedral spectral
/// elements in cylindrical coordinates (docs/reference_model.md). It shares the tube's geometry,
/// material and structure description with the shell model (acoustics/shell.h), nothing of its
/// discretization.
///
/// Mesh: elements are exact cylindrical sectors (theta x z x r). Each element carries a tensor
/// grid of Gauss-Lobatto-Legendre points, degree_wall along the arc and the axis and
/// degree_thickness through the wall; nodes are the quadrature points, so the mass matrix is
/// diagonal. Unknowns are the Cartesian displacements (u_x, u_y, u_z) of every node, tube frame.
///
/// Structure: a seam is a cut through the wall at a fixed theta (element boundaries are placed on
/// it and its node columns doubled), bridged by bolts: three springs (x, y, z) of the bolt's
/// stiffness between the two faces, spread over the patch the bolt clamps (bolt_patch_half_length_m
/// either side of its z; its ends are axial element edges) and through the wall. A hole is the
/// square of its area (side d sqrt(pi) / 2, arc x axis) whose sides are element edges: the
/// elements inside keep kHoleFill of their material, so the hole is the same shape on every mesh
/// (a round hole cut out of quadrature points converged at first order). Mounts are springs to
/// ground in every direction, per metre of the end rim. Simply supported ends hold u_x = u_y = 0
/// (radial and arc motion) on the end faces and leave u_z free (a shear diaphragm).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "sonicboom/core/tube.h"
#include "sonicboom/solid/gll.h"

namespace sonicboom::solid {

/// Fraction of the material a quadrature point inside a hole keeps (a void would leave nodes with
/// no mass; this keeps them, with the wave speed of the wall, far above the audio band).
inline constexpr double kHoleFill = 1e-4;

/// The discretization of the reference model (set by the options of `sonicboom reference` and
/// `sonicboom rerender`).
struct SolidMeshConfig {
  double element_arc_m{0.0135};    // target element length along the mid-surface arc
  double element_axial_m{0.0135};  // target element length along the axis
  int64_t degree_wall{4};          // GLL degree along the arc and the axis
  int64_t degree_thickness{3};     // GLL degree through the wall
  int64_t elements_through{1};     // elements through the wall
  // How the intervals between forced edges (seams, bolt patches' ends, holes' sides) are cut.
  // 0, graded: each into round(length / element) elements, so two meshes of different element
  // lengths need not refine every interval by the same ratio. n >= 1, self-similar: each into
  // n x max(1, round(length / element)) elements, except that an interval shorter than
  // fixed_interval_m stays one element; meshes of n and n' then differ by n' / n in every
  // refined element, the premise of a Richardson fit (the fixed ones are an error floor).
  int64_t subdivisions{0};
  double fixed_interval_m{0.01};
  // the shortest element accepted: 4 mm elements of the 4" tube hold over a million unknowns
  static constexpr double kMinElementM = 0.004;

  /// Range and cross-field checks against the tube; throws ConfigError naming the field and its
  /// limits (a command that sets the mesh from its options names the option too).
  void Validate(const TubeConfig& tube) const;
  /// The same mesh with every element length divided by `factor` (h-refinement).
  SolidMeshConfig Refined(double factor) const;
};

/// The structure of the configured tube: the keys of the shell model's "shell" section that are
/// physics (seams, bolts, holes, mounts, ends), not discretization.
struct SolidStructure {
  TubeEnds ends{TubeEnds::kFree};
  std::vector<double> seam_theta_deg;      // saw cuts through the wall
  std::vector<double> bolt_z_m;            // bolts along every seam, tube frame
  std::vector<double> bolt_stiffness_n_m;  // per bolt, per direction
  double bolt_patch_half_length_m{0.004};  // each bolt clamps the faces over z +- this
  std::vector<double> hole_z_m, hole_theta_deg;
  double hole_diameter_m{0.0};
  double flange_mount_stiffness_n_m2{0.0};  // springs to ground per metre of the z = -L/2 rim
  double tool_mount_stiffness_n_m2{0.0};    // the same at z = +L/2
};

/// A hole of the reference model: the square of the hole's area centred on it, through the wall.
struct HoleSquare {
  double z_lo_m, z_hi_m;              // axial span
  double theta_lo_rad, theta_hi_rad;  // arc span at the mid-surface (theta_lo may be negative)
  /// Whether the point (z, theta) lies strictly inside.
  bool Holds(double z_m, double theta_rad) const;
};
/// The squares of the structure's holes, in its order. Throws ConfigError when hole_z_m and
/// hole_theta_deg differ in length.
std::vector<HoleSquare> HoleSquares(const TubeConfig& tube, const SolidStructure& structure);

/// Immutable mesh, K and M of the solid tube. Thread-safe to share.
class SolidTubeModel {
 public:
  SolidTubeModel(const TubeConfig& tube, const MaterialConfig& material,
                 const SolidStructure& structure, const SolidMeshConfig& mesh);

  int64_t dofs() const { return static_cast<int64_t>(mass_kg_.size()); }
  int64_t nodes() const { return static_cast<int64_t>(node_dof_.size()) / 3; }
  int64_t elements() const { return static_cast<int64_t>(elements_.size()); }
  /// (dofs x dofs) stiffness, N/m, symmetric, both triangles stored.
  const Eigen::SparseMatrix<double>& stiffness() const { return stiffness_; }
  /// (dofs) diagonal (GLL-lumped) mass, kg.
  const Eigen::VectorXd& mass_kg() const { return mass_kg_; }
  /// (dofs x dofs) M^-1/2 K M^-1/2, 1/s^2: its eigenvalues are omega^2.
  Eigen::SparseMatrix<double> MassScaledStiffness() const;

  /// (dofs) loads of a unit outward radial point force on the outer surface at (z, theta), tube
  /// frame (the spectral interpolation of the element holding the point); its transpose reads
  /// the outward displacement there. Throws ConfigError off the tube.
  Eigen::VectorXd RadialForceWeights(double z_m, double theta_rad) const;
  /// (3 points x dofs) the same for unit forces along the outward normal, the arc (increasing
  /// theta) and the axis at each (z, theta) of `points_z_theta` (m, rad), rows point-major
  /// (r, theta, z); each row transposed reads that displacement component there. Sparse: a
  /// point's rows touch the nodes of one element face. Throws ConfigError off the tube.
  Eigen::SparseMatrix<double, Eigen::RowMajor> SurfacePointRows(
      const std::vector<std::pair<double, double>>& points_z_theta) const;
  /// (dofs) output of a piezo disc of diameter d centred at (z, theta) on the outer surface: the
  /// in-plane strain eps_zz + eps_thth averaged over the disc (a polar quadrature of the disc).
  /// Unit: strain per m of the DOFs.
  Eigen::VectorXd SensorRow(double z_m, double theta_rad, double diameter_m) const;
  /// (count x dofs) SensorRow of every disc of the array.
  Eigen::MatrixXd SensorRows(const MicArrayConfig& mics) const;
  /// Every DOF of the nodes on the outer surface, ascending: the support of RadialForceWeights.
  std::vector<int64_t> OuterSurfaceDofs() const;
  /// (dofs) a displacement field u(x) (m, tube frame) sampled at the nodes (held components
  /// left out): the spectral interpolation of the field.
  Eigen::VectorXd Sample(const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& field) const;
  /// The h of h-refinement, m: the mean element length along the arc and the axis; for a
  /// self-similar mesh (mesh().subdivisions >= 1) the asked element length over the subdivisions.
  double element_length_m() const { return element_length_m_; }
  /// Axial element edges, ascending from -L/2 to L/2, m.
  const std::vector<double>& axial_edges_m() const { return z_edges_m_; }
  /// Arc element edges of each sector between seams in turn (one periodic sector for an uncut
  /// tube), each ascending from its seam to the next, rad.
  const std::vector<double>& arc_edges_rad() const { return arc_edges_rad_; }

  const TubeConfig& tube() const { return tube_; }
  const MaterialConfig& material() const { return material_; }
  const SolidStructure& structure() const { return structure_; }
  const SolidMeshConfig& mesh() const { return mesh_; }

 private:
  struct Element {
    double theta0_rad, dtheta_rad;  // arc span
    double z0_m, dz_m;              // axial span
    double r0_m, dr_m;              // radial span
    std::vector<int64_t> nodes;     // ((k * (p+1) + j) * (p+1) + i): i arc, j axial, k radial
  };
  // k (sum_t w_t u_t)^2 added to the energy: a spring on a combination of DOFs (a DOF to ground,
  // or an interpolated face against another), as triplets of K
  static void AddTie(const std::vector<std::pair<int64_t, double>>& terms, double k,
                     std::vector<Eigen::Triplet<double>>* triplets);
  void BuildMesh();
  void Assemble();
  void AddSprings();
  // the element holding the outer-surface point (z, theta) and its reference coordinates there
  const Element& Locate(double z_m, double theta_rad, double* xi, double* eta) const;
  // d(strain)/d(u) of the outer-surface in-plane strain eps_zz + eps_thth at reference point
  // (xi, eta, zeta = 1) of element e, added into row with weight `scale`
  void AddSurfaceStrain(const Element& e, double xi, double eta, double scale,
                        Eigen::VectorXd* row) const;

  TubeConfig tube_;
  MaterialConfig material_;
  SolidStructure structure_;
  SolidMeshConfig mesh_;
  GllRule wall_, thick_;  // the GLL rules along the wall and through it
  std::vector<HoleSquare> holes_;  // the structure's holes: their sides are element edges
  std::vector<Element> elements_;
  std::vector<int64_t> node_dof_;  // (nodes x 3) DOF of each Cartesian component, -1 when held
  std::vector<Eigen::Vector3d> node_position_m_;
  Eigen::VectorXd mass_kg_;
  Eigen::SparseMatrix<double> stiffness_;
  double element_length_m_{0.0};
  int rows_{0}, layers_{0};               // axial node rows, radial node layers
  std::vector<double> column_theta_rad_;  // arc node columns
  std::vector<double> z_edges_m_;         // axial element edges, ascending, -L/2 to L/2
  std::vector<double> arc_edges_rad_;     // arc element edges, sector by sector
  // a bolt patch's or a hole's edge closer than this to an edge already placed is not made one
  static constexpr double kMinEdgeGapM = 0.001;
};

}  // namespace sonicboom::solid
