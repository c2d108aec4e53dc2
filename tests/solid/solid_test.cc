// The reference solid (solid/): spectral-element building blocks, exact invariants of the mesh
// and K, and its modes against the closed-form theory of the ideal tube and the plate.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <numbers>
#include <tuple>

#include "sonicboom/acoustics/cylinder_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/convergence.h"
#include "sonicboom/solid/exact_match.h"
#include "sonicboom/solid/gll.h"
#include "sonicboom/solid/reference_render.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_modes.h"
#include "sonicboom/solid/solid_response.h"
#include "sonicboom/solid/solid_tube.h"
#include "sonicboom/solid/ss_exact.h"
#include "sonicboom/solid/theory.h"

namespace sonicboom::solid {
namespace {

using sonicboom::kPi;

TEST(GllTest, IntegratesPolynomialsToDegreeTwoNMinusOneAndDifferentiatesExactly) {
  for (int n = 1; n <= 8; ++n) {
    const GllRule rule = MakeGllRule(n);
    EXPECT_DOUBLE_EQ(rule.points(0), -1.0);
    EXPECT_DOUBLE_EQ(rule.points(n), 1.0);
    for (int k = 0; k <= 2 * n - 1; ++k) {
      const double exact = k % 2 == 1 ? 0.0 : 2.0 / (k + 1);
      double sum = 0.0;
      for (int i = 0; i <= n; ++i) sum += rule.weights(i) * std::pow(rule.points(i), k);
      EXPECT_NEAR(sum, exact, 1e-13) << "degree " << n << " monomial " << k;
    }
    // D x^n at the nodes = n x^(n-1)
    const Eigen::VectorXd f = rule.points.array().pow(n);
    const Eigen::VectorXd df = rule.derivative * f;
    for (int i = 0; i <= n; ++i) EXPECT_NEAR(df(i), n * std::pow(rule.points(i), n - 1), 1e-11);
    // the basis at an arbitrary point interpolates x^n exactly
    Eigen::VectorXd l, dl;
    LagrangeBasis(rule, 0.3141, &l, &dl);
    EXPECT_NEAR(l.dot(f), std::pow(0.3141, n), 1e-13);
    EXPECT_NEAR(dl.dot(f), n * std::pow(0.3141, n - 1), 1e-11);
  }
}

SolidStructure Ideal(TubeEnds ends) {
  SolidStructure s;
  s.ends = ends;
  return s;
}

// an ideal tube on elements of arc x axial metres and its modes up to max_frequency_hz
struct IdealSolve {
  std::unique_ptr<SolidTubeModel> model;
  SolidModes modes;
};
IdealSolve SolveIdeal(TubeEnds ends, double arc_m, double axial_m, double max_frequency_hz) {
  SolidMeshConfig mesh;
  mesh.element_arc_m = arc_m;
  mesh.element_axial_m = axial_m;
  IdealSolve out;
  out.model = std::make_unique<SolidTubeModel>(TubeConfig{}, MaterialConfig{}, Ideal(ends), mesh);
  SolidModeRequest request;
  request.max_frequency_hz = max_frequency_hz;
  out.modes = SolveSolidModes(*out.model, request);
  return out;
}

SolidMeshConfig Coarse() {
  SolidMeshConfig m;
  m.element_arc_m = 0.03;
  m.element_axial_m = 0.05;
  m.degree_wall = 3;
  return m;
}

TEST(SolidTubeTest, MassIsTheTubesAndRigidMotionsCostNoEnergy) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const SolidTubeModel model(tube, pvc, Ideal(TubeEnds::kFree), Coarse());
  const double r_in = tube.outer_radius_m - tube.wall_thickness_m;
  const double exact = pvc.density_kg_m3 * kPi *
                       (tube.outer_radius_m * tube.outer_radius_m - r_in * r_in) * tube.length_m;
  // each of the three components carries the whole mass
  EXPECT_NEAR(model.mass_kg().sum() / 3.0, exact, 1e-12 * exact);
  // translations and the rotation about z: K u = 0 to round-off
  const int64_t n = model.dofs();
  for (int d = 0; d < 3; ++d) {
    Eigen::VectorXd u = Eigen::VectorXd::Zero(n);
    for (int64_t i = d; i < n; i += 3) u(i) = 1.0;
    EXPECT_LT((model.stiffness() * u).cwiseAbs().maxCoeff(),
              1e-9 * model.stiffness().coeffs().cwiseAbs().maxCoeff());
  }
}

// a hole is the square of its area on element edges: it takes rho h (d^2 pi / 4) (1 - kHoleFill)
// out of the mass on any mesh, with or without seams, wherever it lies on the arc
TEST(SolidTubeTest, AHoleRemovesExactlyItsAreaOnEveryMesh) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const double r_in = tube.outer_radius_m - tube.wall_thickness_m;
  const double whole = pvc.density_kg_m3 * kPi *
                       (tube.outer_radius_m * tube.outer_radius_m - r_in * r_in) * tube.length_m;
  SolidStructure holed = Ideal(TubeEnds::kFree);
  holed.hole_diameter_m = 0.006;
  holed.hole_z_m = {0.05, -0.146};
  holed.hole_theta_deg = {0.0, 120.0};
  const double removed = 2.0 * pvc.density_kg_m3 * tube.wall_thickness_m *
                         (0.25 * kPi * 0.006 * 0.006) * (1.0 - kHoleFill);
  SolidStructure seamed = holed;
  seamed.seam_theta_deg = {90.0, 270.0};
  for (const SolidStructure& structure : {holed, seamed}) {
    for (double factor : {1.0, 1.3, 2.1}) {
      const SolidTubeModel model(tube, pvc, structure, Coarse().Refined(factor));
      EXPECT_NEAR(model.mass_kg().sum() / 3.0, whole - removed, 1e-12 * whole)
          << "refined " << factor << ", seams " << structure.seam_theta_deg.size();
    }
  }
  // the square's arc edges straddle theta = 0 (wrapped) and it holds its centre, not its corner
  const HoleSquare at_zero = HoleSquares(tube, holed)[0];
  EXPECT_TRUE(at_zero.Holds(0.05, 2.0 * kPi - 0.01));
  EXPECT_TRUE(at_zero.Holds(0.05, 0.01));
  EXPECT_FALSE(at_zero.Holds(0.05, 0.2));
  EXPECT_FALSE(at_zero.Holds(0.0, 0.0));
  // two positions and one angle: refused by the squares and by the model, naming both keys
  SolidStructure uneven = holed;
  uneven.hole_theta_deg.pop_back();
  try {
    SolidTubeModel(tube, pvc, uneven, Coarse());
    FAIL() << "accepted two holes with one angle";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("2 hole_z_m entries but 1 hole_theta_deg"),
              std::string::npos)
        << e.what();
  }
}

TEST(SolidTubeTest, SensorReadsUniformHoopAndAxialStrainAndTheForceRowReadsRadialMotion) {
  const TubeConfig tube;
  const SolidTubeModel model(tube, MaterialConfig{}, Ideal(TubeEnds::kFree), Coarse());
  const double eps = 1e-4;
  const Eigen::VectorXd hoop = model.Sample(
      [&](const Eigen::Vector3d& x) { return Eigen::Vector3d(eps * x.x(), eps * x.y(), 0.0); });
  const Eigen::VectorXd axial = model.Sample(
      [&](const Eigen::Vector3d& x) { return Eigen::Vector3d(0.0, 0.0, eps * x.z()); });
  const Eigen::VectorXd shift =
      model.Sample([&](const Eigen::Vector3d&) { return Eigen::Vector3d(1e-3, -2e-3, 5e-4); });
  for (const auto& [z, th] :
       {std::pair{0.013, 0.7}, std::pair{-0.13, 2.0 * kPi / 3.0}, std::pair{0.1, -0.2}}) {
    const Eigen::VectorXd row = model.SensorRow(z, th, 0.02);
    // the cylindrical mapping is interpolated, not exact: 1e-5 of the field at degree 3
    EXPECT_NEAR(row.dot(hoop), eps, 1e-4 * eps) << z << " " << th;
    EXPECT_NEAR(row.dot(axial), eps, 1e-12 * eps);
    EXPECT_NEAR(row.dot(shift), 0.0, 1e-10 * eps);
    const Eigen::VectorXd force = model.RadialForceWeights(z, th);
    EXPECT_NEAR(force.dot(hoop), eps * tube.outer_radius_m, 1e-4 * eps * tube.outer_radius_m);
    EXPECT_NEAR(force.dot(axial), 0.0, 1e-15);
  }
  EXPECT_THROW(model.RadialForceWeights(0.2, 0.0), ConfigError);
}

// each of a surface point's three rows reads one cylindrical component of the displacement
// there: a rigid turn by eps about the axis moves the surface eps r along the arc and not at all
// along the normal or the axis; an axial shift moves it along the axis alone
TEST(SolidTubeTest, SurfacePointRowsReadTheNormalArcAndAxialDisplacement) {
  const TubeConfig tube;
  const SolidTubeModel model(tube, MaterialConfig{}, Ideal(TubeEnds::kFree), Coarse());
  const double eps = 1e-4;
  const Eigen::VectorXd turn = model.Sample(
      [&](const Eigen::Vector3d& x) { return Eigen::Vector3d(-eps * x.y(), eps * x.x(), 0.0); });
  const Eigen::VectorXd shift =
      model.Sample([&](const Eigen::Vector3d&) { return Eigen::Vector3d(0.0, 0.0, eps); });
  const std::vector<std::pair<double, double>> points = {{0.013, 0.7}, {-0.14, 4.0}, {0.1, -0.2}};
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = model.SurfacePointRows(points);
  ASSERT_EQ(rows.rows(), 9);
  ASSERT_EQ(rows.cols(), model.dofs());
  const Eigen::VectorXd read_turn = rows * turn, read_shift = rows * shift;
  for (size_t p = 0; p < points.size(); ++p) {
    const Eigen::VectorXd radial = model.RadialForceWeights(points[p].first, points[p].second);
    EXPECT_EQ((Eigen::VectorXd(rows.row(3 * p).transpose()) - radial).cwiseAbs().maxCoeff(), 0.0);
    // the cylindrical mapping is interpolated: 1e-4 of the field at this degree
    EXPECT_NEAR(read_turn(3 * p), 0.0, 1e-4 * eps * tube.outer_radius_m) << p;
    EXPECT_NEAR(read_turn(3 * p + 1), eps * tube.outer_radius_m, 1e-4 * eps * tube.outer_radius_m);
    EXPECT_NEAR(read_turn(3 * p + 2), 0.0, 1e-15);
    EXPECT_NEAR(read_shift(3 * p), 0.0, 1e-15);
    EXPECT_NEAR(read_shift(3 * p + 1), 0.0, 1e-15);
    EXPECT_NEAR(read_shift(3 * p + 2), eps, 1e-12 * eps);
  }
  EXPECT_THROW(model.SurfacePointRows({{0.0, 0.0}, {-0.2, 1.0}}), ConfigError);
}

// a bolt patch's ends are element edges on every mesh: a surface point there reads one row of
// nodes (the axial basis is 1 at an element's end), a point inside the patch a whole face
TEST(SolidTubeTest, BoltPatchEndsAreElementEdges) {
  SolidStructure s;
  s.seam_theta_deg = {90.0, 270.0};
  s.bolt_z_m = {-0.1, 0.0, 0.1};
  s.bolt_stiffness_n_m = {2e7, 2e7, 2e7};
  s.bolt_patch_half_length_m = 0.004;
  for (const double refine : {1.0, 1.3, 1.7}) {
    const SolidMeshConfig mesh = Coarse().Refined(refine);
    const SolidTubeModel model(TubeConfig{}, MaterialConfig{}, s, mesh);
    const int64_t face = (mesh.degree_wall + 1) * (mesh.degree_wall + 1);
    for (const double zb : s.bolt_z_m) {
      for (const double sign : {-1.0, 1.0}) {
        // the radial row of a point off the arc's edges: x and y of each node it reads
        const double z = zb + sign * s.bolt_patch_half_length_m;
        const auto edge = model.SurfacePointRows({{z, 1.0}});
        EXPECT_EQ(edge.row(0).nonZeros(), 2 * (mesh.degree_wall + 1)) << z << " x" << refine;
      }
    }
    const auto inside = model.SurfacePointRows({{0.0013, 1.0}});
    EXPECT_EQ(inside.row(0).nonZeros(), 2 * face) << refine;
  }
}

// a self-similar family (subdivisions n) cuts every element of n = 1 longer than
// fixed_interval_m into n equal ones and leaves the shorter ones whole, along the axis and the
// arc, with the seams, bolt patches and holes of the configured tube as forced edges
TEST(SolidTubeTest, SelfSimilarMeshesCutEveryRefinedElementAlike) {
  const TubeConfig tube;
  SolidStructure s;
  s.seam_theta_deg = {90.0, 270.0};
  s.bolt_z_m = {-0.1, 0.0, 0.1};
  s.bolt_stiffness_n_m = {2e7, 2e7, 2e7};
  s.hole_diameter_m = 0.006;
  s.hole_z_m = {-0.146, 0.146};
  s.hole_theta_deg = {0.0, 120.0};
  SolidMeshConfig mesh;
  mesh.element_arc_m = mesh.element_axial_m = 0.04;
  mesh.degree_wall = mesh.degree_thickness = 1;
  mesh.subdivisions = 1;
  const SolidTubeModel base(tube, MaterialConfig{}, s, mesh);
  mesh.subdivisions = 3;
  const SolidTubeModel fine(tube, MaterialConfig{}, s, mesh);
  EXPECT_DOUBLE_EQ(base.element_length_m() / fine.element_length_m(), 3.0);
  // edges of one coordinate (ascending, sectors' shared ends once) and their length scale, m
  auto unique = [](std::vector<double> v) {
    v.erase(std::unique(v.begin(), v.end()), v.end());
    return v;
  };
  const double r = tube.mid_radius_m();
  int whole = 0, cut = 0;
  for (const auto& [coarse, refined, scale] :
       {std::tuple{base.axial_edges_m(), fine.axial_edges_m(), 1.0},
        std::tuple{unique(base.arc_edges_rad()), unique(fine.arc_edges_rad()), r}}) {
    size_t j = 0;  // index of the coarse element's start among the refined edges
    for (size_t i = 0; i + 1 < coarse.size(); ++i) {
      ASSERT_LT(j, refined.size());
      ASSERT_NEAR(refined[j], coarse[i], 1e-12) << "element " << i;
      const double len = coarse[i + 1] - coarse[i];
      const int n = len * scale < mesh.fixed_interval_m ? 1 : 3;
      (n == 1 ? whole : cut) += 1;
      for (int k = 1; k <= n; ++k) {
        ASSERT_LT(j + k, refined.size());
        EXPECT_NEAR(refined[j + k], coarse[i] + len * k / n, 1e-12) << "element " << i;
      }
      j += n;
    }
    EXPECT_EQ(j + 1, refined.size());
  }
  // left whole: along the axis the two ends beyond the holes (3.7 mm), the holes (5.3 mm) and
  // the three bolt patches (8 mm); along the arc the two holes
  EXPECT_EQ(whole, 2 + 2 + 3 + 2);
  EXPECT_GE(cut, 10);
}

TEST(SolidTubeTest, RefusesMeshesThatCannotBeBuiltNamingTheKey) {
  // too long for the circumference, zero, not a number, and below the smallest element
  for (const double arc_m : {0.5, 0.0, std::nan(""), 0.001}) {
    SolidMeshConfig mesh;
    mesh.element_arc_m = arc_m;
    try {
      SolidTubeModel(TubeConfig{}, MaterialConfig{}, Ideal(TubeEnds::kFree), mesh);
      FAIL() << "accepted an element of " << arc_m << " m around the tube";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("element_arc_m"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("0.004"), std::string::npos) << e.what();
    }
  }
  // self-similar: subdivisions out of range, cutting below the smallest element, and fixed
  // intervals as long as an element
  SolidMeshConfig many, small, fixed;
  many.subdivisions = 13;
  small.subdivisions = 4;
  fixed.subdivisions = 1;
  fixed.fixed_interval_m = 0.02;
  for (const auto& [mesh, key] :
       {std::pair{many, "subdivisions = 13"}, std::pair{small, "subdivisions = 4"},
        std::pair{fixed, "fixed_interval_m = 0.02"}}) {
    try {
      SolidTubeModel(TubeConfig{}, MaterialConfig{}, Ideal(TubeEnds::kFree), mesh);
      FAIL() << "accepted " << key;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

TEST(SolidTheoryTest, LambWaveLiesBetweenMindlinAndKirchhoffLimits) {
  const MaterialConfig pvc;
  const double h = 0.00305;
  // long waves: all three agree; at kh ~ 1 Kirchhoff is far too stiff, Mindlin close to exact
  const double k_low = 5.0;
  EXPECT_NEAR(RayleighLambA0(pvc, h, k_low) / KirchhoffFlexural(pvc, h, k_low), 1.0, 1e-4);
  const double k = 1.0 / h;
  const double exact = RayleighLambA0(pvc, h, k);
  EXPECT_NEAR(MindlinFlexural(pvc, h, k) / exact, 1.0, 0.01);
  EXPECT_GT(KirchhoffFlexural(pvc, h, k) / exact, 1.15);
  // docs/reference_model.md: at kh = 0.92 (Kirchhoff's wavenumber at 20 kHz for this wall) the
  // exact frequency is 13 % below Kirchhoff's; at 20 kHz the exact wavenumber is 8 % above it
  const double k_20 = 0.92 / h;
  EXPECT_NEAR(RayleighLambA0(pvc, h, k_20) / KirchhoffFlexural(pvc, h, k_20), 0.873, 0.002);
  EXPECT_NEAR(MindlinFlexural(pvc, h, k_20) / RayleighLambA0(pvc, h, k_20), 1.0, 0.01);
  const double omega = 2.0 * kPi * 20000.0;
  auto wavenumber = [&](auto dispersion) {
    double lo = 10.0, hi = 2000.0;
    for (int i = 0; i < 100; ++i) {
      const double mid = 0.5 * (lo + hi);
      (dispersion(pvc, h, mid) < omega ? lo : hi) = mid;
    }
    return lo;
  };
  const double k_kirchhoff = wavenumber(KirchhoffFlexural);
  const double k_lamb = wavenumber(RayleighLambA0);
  EXPECT_NEAR(k_kirchhoff / k_lamb, 0.926, 0.003);
  EXPECT_NEAR(wavenumber(MindlinFlexural) / k_lamb, 1.0, 0.006);
}

TEST(SolidTheoryTest, RichardsonRecoversLimitAndOrder) {
  const std::vector<double> h{0.04, 0.03, 0.02};
  std::vector<double> f;
  for (double x : h) f.push_back(1000.0 + 3e8 * std::pow(x, 6.0));
  const Extrapolation e = Richardson(h, f);
  EXPECT_NEAR(e.limit, 1000.0, 1e-6);
  EXPECT_NEAR(e.order, 6.0, 1e-6);
  EXPECT_NEAR(e.error, 3e8 * std::pow(0.02, 6.0), 1e-6);
  // oscillating differences: no order, the last difference as the bound
  const Extrapolation bad = Richardson(h, {1.0, 1.2, 1.1});
  EXPECT_EQ(bad.order, 0.0);
  EXPECT_NEAR(bad.error, 0.1, 1e-12);
}

// The simply supported ideal tube against exact 3-D elasticity (solid/ss_exact.h), each mode
// labelled (m, n) by its shape and matched to the exact root of its family and branch: every mode
// below 1.6 kHz there, within the coarse mesh's own error. (Flügge's thin shell, which this test
// compared against before, is itself 1-4 % stiffer than 3-D elasticity for this wall.)
TEST(SolidModesTest, SimplySupportedTubeMatchesExact3dElasticityBelow1600Hz) {
  const IdealSolve solve = SolveIdeal(TubeEnds::kSimplySupported, 0.025, 0.05, 1900.0);
  EXPECT_EQ(solve.modes.rigid_body_modes, 1);  // a shear diaphragm lets the tube slide along z
  const ExactModeList exact = ExactSimplySupportedModes(TubeConfig{}, MaterialConfig{}, {});
  const SolidLabelGrid grid = MakeSolidLabelGrid(*solve.model);
  const std::vector<LabelledMode> labelled = LabelSolidModes(*solve.model, grid, solve.modes);
  const ExactComparison c = CompareByFamily(exact, labelled, 1600.0);
  EXPECT_EQ(c.exact_count, 19);  // 9 pairs and the (1, 0) torsion at 1446 Hz
  EXPECT_EQ(c.model_count, c.exact_count);
  EXPECT_EQ(c.matched, c.exact_count);
  EXPECT_LT(c.max_abs, 0.003) << "median " << c.median_abs;
  for (const LabelledMode& m : labelled) {
    if (m.frequency_hz < 1600.0) EXPECT_GT(m.label.purity, 0.9) << m.frequency_hz;
  }
}

// the free tube: six rigid-body modes, then Rayleigh's n = 2 ring pair near 220 Hz
TEST(SolidModesTest, FreeTubeHasSixRigidModesThenTheOvalPair) {
  const TubeConfig tube;
  const MaterialConfig pvc;
  const IdealSolve solve = SolveIdeal(TubeEnds::kFree, 0.04, 0.05, 400.0);
  const SolidModes& modes = solve.modes;
  const SolidTubeModel* model = solve.model.get();
  EXPECT_EQ(modes.rigid_body_modes, 6);
  ASSERT_GE(modes.omega_rad_s.size(), 2);
  const double rayleigh = acoustics::RayleighFrequency(tube, pvc, 2);
  EXPECT_NEAR(modes.omega_rad_s(0) / (2.0 * kPi) / rayleigh, 1.0, 0.02);
  EXPECT_NEAR(modes.omega_rad_s(1) / modes.omega_rad_s(0), 1.0, 1e-6);  // the degenerate pair
  // mass-normalized shapes
  const Eigen::VectorXd phi = modes.shapes.col(0);
  EXPECT_NEAR(phi.cwiseProduct(phi).dot(model->mass_kg()), 1.0, 1e-8);
  EXPECT_EQ(CountSolidModesBelow(*model, 400.0), 6 + modes.omega_rad_s.size());
  // asked for the surface rows alone, the solve returns exactly those rows of the shapes
  SolidModeRequest surface;
  surface.max_frequency_hz = 400.0;
  surface.shape_dofs = model->OuterSurfaceDofs();
  const SolidModes rows = SolveSolidModes(*model, surface);
  ASSERT_EQ(rows.shapes.rows(), static_cast<Eigen::Index>(surface.shape_dofs.size()));
  for (size_t r = 0; r < surface.shape_dofs.size(); r += 97) {
    EXPECT_EQ(rows.shapes.row(r), modes.shapes.row(surface.shape_dofs[r]));
  }
}

// a seam cuts the tube in two: without bolts the halves move freely (12 rigid-body modes), three
// bolts join them again (6)
TEST(SolidModesTest, BoltsJoinTheHalvesOfASeamedTube) {
  SolidMeshConfig mesh = Coarse();
  SolidStructure loose = Ideal(TubeEnds::kFree);
  loose.seam_theta_deg = {90.0, 270.0};
  SolidStructure bolted = loose;
  bolted.bolt_z_m = {-0.1, 0.0, 0.1};
  bolted.bolt_stiffness_n_m = {2e6, 2e6, 2e6};
  SolidModeRequest request;
  request.max_frequency_hz = 60.0;
  request.with_shapes = false;
  const TubeConfig tube;
  const MaterialConfig pvc;
  EXPECT_EQ(SolveSolidModes(SolidTubeModel(tube, pvc, loose, mesh), request).rigid_body_modes, 12);
  EXPECT_EQ(SolveSolidModes(SolidTubeModel(tube, pvc, bolted, mesh), request).rigid_body_modes, 6);
}

// one mode struck by a short half-sine: after the pulse, the response is the impulse response
// (area 2T/pi) e^(-zeta w t) sin(w_d t) / w_d; arrivals interpolate between samples
TEST(SolidResponseTest, ShortPulseGivesTheImpulseResponseAndArrivalsInterpolate) {
  PulseResponseConfig pulse;
  pulse.pulse_duration_s = 2e-5;
  pulse.sample_rate_hz = 1e7;
  pulse.window_s = 2e-3;
  pulse.loss_factor = 0.02;
  const double w = 2.0 * kPi * 1000.0, zeta = 0.01, wd = w * std::sqrt(1.0 - zeta * zeta);
  const Eigen::MatrixXd y =
      PulseResponse(Eigen::VectorXd::Constant(1, w), Eigen::MatrixXd::Constant(1, 1, 2.0),
                    Eigen::VectorXd::Constant(1, 0.5), pulse);
  const double area = 2.0 * pulse.pulse_duration_s / kPi;
  for (const double t : {2.5e-4, 7.1e-4, 1.3e-3}) {
    const Eigen::Index k = static_cast<Eigen::Index>(std::lround(t * pulse.sample_rate_hz)) - 1;
    const double tc = (k + 1) / pulse.sample_rate_hz - 0.5 * pulse.pulse_duration_s;
    const double exact = 2.0 * 0.5 * area * std::exp(-zeta * w * tc) * std::sin(wd * tc) / wd;
    EXPECT_NEAR(y(0, k), exact, 2e-3 * area / wd) << t;
  }
  Eigen::MatrixXd ramp(2, 5);
  ramp << 0.0, 1.0, 2.0, 3.0, 10.0, 0.0, 0.0, -4.0, 1.0, 0.0;
  const Eigen::VectorXd t = ThresholdArrivals(ramp, 1000.0, 0.25);
  EXPECT_NEAR(t(0), 2.5e-3, 1e-12);   // 2.5 reached halfway between samples 2 and 3
  EXPECT_NEAR(t(1), 1.25e-3, 1e-12);  // |-4| >= 1 a quarter of the way from sample 1 to 2
}

ReferenceTubeConfig CoarseReference(const std::string& cache_dir = "") {
  ReferenceTubeConfig c;
  c.structure = Ideal(TubeEnds::kFree);
  c.mesh = Coarse();
  c.max_frequency_hz = 3000.0;
  c.cache_dir = cache_dir;
  return c;
}

// a lossless strike: the striker's kinetic energy goes into its rebound and the modes, nothing
// lost (the stepped integration keeps the balance to 0.5 %)
TEST(ReferenceRenderTest, LosslessStrikeConservesEnergy) {
  const ReferenceTube tube(CoarseReference());
  ReferenceStrike strike;
  strike.z_m = 0.02;
  strike.theta_rad = 0.3;
  strike.striker_mass_kg = 0.1;  // a heavy soft mallet: a long contact that drives the low modes
  strike.striker_youngs_modulus_pa = 5e7;
  strike.striker_radius_m = 0.01;
  ReferenceRenderConfig config;
  config.loss_factor = 0.0;
  const ReferenceRender r = RenderReferenceStrike(tube, strike, config);
  EXPECT_GT(r.wall_energy_j, 0.05 * r.striker_energy_in_j);
  EXPECT_NEAR(r.striker_energy_out_j + r.wall_energy_j, r.striker_energy_in_j,
              5e-3 * r.striker_energy_in_j);
  // momentum: the impulse reverses the striker, 2 m v at most (m v (1 + e))
  EXPECT_GT(r.impulse_ns, strike.striker_mass_kg * strike.speed_m_s);
  EXPECT_LT(r.impulse_ns, 2.0 * strike.striker_mass_kg * strike.speed_m_s * 1.0001);
}

// a soft striker on the tube: Hertz's duration 2.9432 delta_max / v of a rigid target within 5 %,
// and its v^-1/5 law between 0.1 and 1 m/s within 2 %
TEST(ReferenceRenderTest, SoftStrikerFollowsHertzDuration) {
  const ReferenceTube tube(CoarseReference());
  ReferenceStrike strike;
  strike.striker_youngs_modulus_pa = 2e7;
  strike.striker_poisson_ratio = 0.45;
  strike.striker_radius_m = 0.005;
  strike.striker_mass_kg = 0.005;
  ReferenceRenderConfig config;
  config.samples = 2000;
  std::vector<double> duration;
  for (const double v : {0.1, 1.0}) {
    strike.speed_m_s = v;
    const ReferenceRender r = RenderReferenceStrike(tube, strike, config);
    EXPECT_EQ(r.touches, 1);
    const double k = ReferenceHertzStiffness(strike, TubeConfig{}, MaterialConfig{});
    const double delta_max = std::pow(5.0 * strike.striker_mass_kg * v * v / (4.0 * k), 0.4);
    EXPECT_NEAR(r.duration_s / (2.9432 * delta_max / v), 1.0, 0.05) << v;
    duration.push_back(r.duration_s);
  }
  EXPECT_NEAR(duration[1] / duration[0], std::pow(10.0, -0.2), 0.02 * std::pow(10.0, -0.2));
}

// Polarity, as the shell's (tests/acoustics/shell_test.cc): a slow (5 ms) inward push right
// under a disc dents the tube there, and the disc reads compression.
TEST(SolidResponseTest, AnInwardPushCompressesTheDiscUnderIt) {
  const ReferenceTube tube(CoarseReference());
  const MicArrayConfig mics;
  const double fs = 44100.0;
  std::vector<double> force(300, 0.0);  // N per sample: a 5 ms half-sine
  for (size_t k = 0; k < 221; ++k) force[k] = 20.0 * std::sin(std::numbers::pi * k / 220.0);
  const Eigen::VectorXd omega = tube.omega_rad_s();
  const Eigen::VectorXd inward = -tube.ModalDrive(mics.z_m[0], mics.theta_deg[0] * kDeg);
  const Eigen::MatrixXd y = ForcedResponse(omega, Eigen::VectorXd::Constant(omega.size(), 0.01),
                                           tube.disc_strain(), inward, force, 10, fs, 600);
  Eigen::Index at = 0;
  y.row(0).cwiseAbs().maxCoeff(&at);
  std::cout << "inward 5 ms push under disc 0: its peak strain " << y(0, at) << "\n";
  EXPECT_LT(y(0, at), 0.0);
}

TEST(ReferenceRenderTest, SilentBeforeTheOnsetAndRefusesABandAboveNyquist) {
  const ReferenceTube tube(CoarseReference());
  ReferenceStrike strike;
  strike.onset_s = 0.01;
  ReferenceRenderConfig config;
  const ReferenceRender r = RenderReferenceStrike(tube, strike, config);
  const int64_t onset = static_cast<int64_t>(std::ceil(0.01 * config.sample_rate_hz));
  EXPECT_EQ(r.strain.leftCols(onset).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(r.strain.rightCols(config.samples - onset).cwiseAbs().maxCoeff(), 1e-8);
  config.sample_rate_hz = 4000.0;
  try {
    RenderReferenceStrike(tube, strike, config);
    FAIL() << "rendered 3 kHz modes at 4 kHz";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("audio.sample_rate_hz"), std::string::npos) << e.what();
  }
}

// the cache returns the solve bit for bit; a damaged file is solved again, not trusted
TEST(ReferenceTubeTest, CacheRoundTripsAndRecomputesADamagedFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / fmt::format("sb-reference-{}", ::getpid());
  std::filesystem::remove_all(dir);
  const ReferenceTube solved(CoarseReference(dir.string()));
  EXPECT_FALSE(solved.from_cache());
  const ReferenceTube cached(CoarseReference(dir.string()));
  EXPECT_TRUE(cached.from_cache());
  EXPECT_EQ(cached.omega_rad_s(), solved.omega_rad_s());
  EXPECT_EQ(cached.disc_strain(), solved.disc_strain());
  EXPECT_EQ(cached.ModalDrive(0.01, 1.0), solved.ModalDrive(0.01, 1.0));
  // flip one byte in the middle of the payload
  const auto file = std::filesystem::directory_iterator(dir)->path();
  const auto size = std::filesystem::file_size(file);
  {
    std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(size / 2));
    f.put('\x5a');
  }
  const ReferenceTube again(CoarseReference(dir.string()));
  EXPECT_FALSE(again.from_cache());
  EXPECT_EQ(again.omega_rad_s(), solved.omega_rad_s());
  std::filesystem::remove_all(dir);
}

// a convergence level kept in the cache is read back bit for bit; the arrivals' own inputs (the
// loss factor) are in its key; a probe near one ring reaches that ring's nearest disc first
TEST(ConvergenceLevelTest, CacheReadsTheLevelBackAndArrivalsAreCausal) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / fmt::format("sb-convergence-{}", ::getpid());
  std::filesystem::remove_all(dir);
  ConvergenceRequest r;
  r.solid.structure = Ideal(TubeEnds::kFree);
  r.solid.mesh = Coarse();
  r.solid.max_frequency_hz = 3000.0;
  r.probes = {{0.09, 20.0}};
  r.solid.cache_dir = dir.string();
  const ConvergenceLevel solved = SolveConvergenceLevel(r);
  EXPECT_FALSE(solved.from_cache);
  ASSERT_FALSE(solved.f_hz.empty());
  ASSERT_EQ(solved.t_s.size(), 1u);
  ASSERT_EQ(solved.t_s[0].size(), 6u);
  const ConvergenceLevel cached = SolveConvergenceLevel(r);
  EXPECT_TRUE(cached.from_cache);
  EXPECT_EQ(cached.f_hz, solved.f_hz);
  EXPECT_EQ(cached.t_s, solved.t_s);
  EXPECT_EQ(cached.dofs, solved.dofs);
  EXPECT_EQ(cached.h_m, solved.h_m);
  EXPECT_EQ(cached.solve_s, solved.solve_s);
  ASSERT_EQ(solved.signature.rows(), 3 * r.signature_points);
  ASSERT_EQ(solved.signature.cols(), static_cast<Eigen::Index>(solved.f_hz.size()));
  EXPECT_EQ(cached.signature, solved.signature);
  EXPECT_GT(solved.signature.cwiseAbs().maxCoeff(), 0.0);
  // discs 3-5 sit at z = +0.13 m (3 at 0 deg, nearest the probe at 20 deg), 0-2 at -0.13 m
  const std::vector<double>& t = solved.t_s[0];
  for (int far = 0; far < 3; ++far) EXPECT_LT(t[3], t[far]) << "disc " << far;
  EXPECT_LT(t[3], t[4]);
  EXPECT_LT(t[3], t[5]);
  r.solid.material.loss_factor *= 2.0;
  EXPECT_NE(ConvergenceLevelKey(r), ConvergenceLevelKey([&] {
              ConvergenceRequest same = r;
              same.solid.material.loss_factor /= 2.0;
              return same;
            }()));
  EXPECT_FALSE(SolveConvergenceLevel(r).from_cache);
  std::filesystem::remove_all(dir);
}

// modes are followed by shape, not rank: two modes that swap order between meshes are matched to
// their own shapes, a shape outside the frequency window is left unmatched, and each mode is used
// once even where two of the other mesh resemble it
TEST(ConvergenceLevelTest, MatchModesByShapeFollowsShapesAcrossAnOrderSwap) {
  // (4 x 4) orthogonal shapes of the coarse mesh and the fine mesh's versions of them
  Eigen::MatrixXd from = Eigen::MatrixXd::Identity(4, 4);
  Eigen::MatrixXd to(4, 4);
  to.col(0) = from.col(0);
  to.col(1) = -2.0 * from.col(2) + 0.1 * from.col(1);  // shape 2, sign and scale free
  to.col(2) = from.col(1) + 0.1 * from.col(3);         // shape 1
  to.col(3) = from.col(3) + 0.05 * from.col(0);        // shape 3, beyond the window
  const std::vector<double> f_from = {100.0, 200.0, 201.0, 300.0};
  const std::vector<double> f_to = {99.0, 199.0, 200.5, 400.0};
  const std::vector<ModeMatch> m = MatchModesByShape(f_from, from, f_to, to, 0.05);
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].from, 0);
  EXPECT_NEAR(m[0].mac, 1.0, 1e-12);
  EXPECT_EQ(m[1].from, 2);  // by rank it would be 1
  EXPECT_NEAR(m[1].mac, 4.0 / 4.01, 1e-12);
  EXPECT_EQ(m[2].from, 1);
  EXPECT_EQ(m[3].from, -1);  // 300 Hz is 25 % from 400 Hz
  // two fine modes alike one coarse mode: the closer in shape takes it, the other takes what is
  // left inside its window
  Eigen::MatrixXd twins(4, 2);
  twins.col(0) = from.col(1) + 0.5 * from.col(2);
  twins.col(1) = from.col(1) + 0.2 * from.col(2);
  const std::vector<ModeMatch> t = MatchModesByShape(f_from, from, {200.0, 200.2}, twins, 0.05);
  EXPECT_EQ(t[1].from, 1);
  EXPECT_EQ(t[0].from, 2);
  EXPECT_NEAR(t[0].mac, 0.25 / 1.25, 1e-12);
  // a degenerate pair (equal frequencies) returned in another basis by the other mesh: each of
  // its modes lies in the pair's span, so both are followed, one to each
  const std::vector<double> f_pair = {100.0, 200.0, 200.0 * (1.0 + 1e-9), 300.0};
  Eigen::MatrixXd turned(4, 2);
  turned.col(0) = from.col(1) + from.col(2);
  turned.col(1) = from.col(1) - from.col(2);
  const std::vector<ModeMatch> d = MatchModesByShape(f_pair, from, {199.0, 199.0}, turned, 0.05);
  EXPECT_NEAR(d[0].mac, 1.0, 1e-12);
  EXPECT_NEAR(d[1].mac, 1.0, 1e-12);
  EXPECT_EQ(d[0].from + d[1].from, 3);  // 1 and 2
  EXPECT_NE(d[0].from, d[1].from);
}

// the same seamed tube on two meshes: every mode below 1.4 kHz of the finer is followed to a mode
// of the coarser by its shape alone, within 2 % in frequency (before the bolt patches' ends were
// element edges, two pairs changed places between these meshes and were followed all the same)
TEST(ConvergenceLevelTest, SignaturesFollowTheModesOfASeamedTubeToAFinerMesh) {
  ConvergenceRequest r;
  r.solid.structure.seam_theta_deg = {90.0, 270.0};
  r.solid.structure.bolt_z_m = {-0.1, 0.1};
  r.solid.structure.bolt_stiffness_n_m = {2e7, 2e7};
  SolidMeshConfig mesh;
  mesh.element_arc_m = 0.025;
  mesh.element_axial_m = 0.03;
  mesh.degree_wall = 4;
  mesh.degree_thickness = 2;
  r.solid.mesh = mesh;
  r.solid.max_frequency_hz = 1600.0;
  const ConvergenceLevel coarse = SolveConvergenceLevel(r);
  r.solid.mesh = mesh.Refined(1.25);
  const ConvergenceLevel fine = SolveConvergenceLevel(r);
  const std::vector<ModeMatch> m =
      MatchModesByShape(coarse.f_hz, coarse.signature, fine.f_hz, fine.signature, 0.05);
  int below = 0;
  for (size_t k = 0; k < fine.f_hz.size() && fine.f_hz[k] < 1400.0; ++k) {
    ++below;
    ASSERT_GE(m[k].from, 0) << k;
    EXPECT_GT(m[k].mac, 0.98) << k;
    EXPECT_NEAR(coarse.f_hz[m[k].from] / fine.f_hz[k], 1.0, 0.02) << k;
  }
  EXPECT_GT(below, 30);
}

}  // namespace
}  // namespace sonicboom::solid
