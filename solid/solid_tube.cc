#include "sonicboom/solid/solid_tube.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/gll.h"

namespace sonicboom::solid {
namespace {

constexpr double kTwoPi = 2.0 * kPi;

// theta in [start, start + 2 pi)
double WrapFrom(double theta_rad, double start_rad) {
  double t = std::fmod(theta_rad - start_rad, kTwoPi);
  if (t < 0.0) t += kTwoPi;
  return start_rad + t;
}

// how one coordinate's intervals between forced edges are cut into elements (lengths m)
struct IntervalCut {
  double target_m;       // element length asked for
  int64_t subdivisions;  // 0: graded; n >= 1: self-similar (SolidMeshConfig::subdivisions)
  double fixed_m;        // self-similar: intervals shorter than this stay one element
  double min_gap_m;      // a break closer than this to the last edge or the end is dropped
  // the number of elements of an interval of length len_m
  int Count(double len_m) const {
    const int base = std::max(1, static_cast<int>(std::lround(len_m / target_m)));
    if (subdivisions == 0) return base;
    return len_m < fixed_m ? 1 : base * static_cast<int>(subdivisions);
  }
};

// edges of elements from `from` to `to` (one coordinate, m), with every break of `breaks` (m)
// that lies more than cut.min_gap_m inside the interval and from the last edge as an edge of its
// own, each interval between cut evenly into cut.Count(length) elements
std::vector<double> CutInterval(double from, double to, std::vector<double> breaks,
                                const IntervalCut& cut) {
  std::sort(breaks.begin(), breaks.end());
  std::vector<double> edges{from};
  auto cut_to = [&](double end) {
    const double start = edges.back(), len = end - start;
    const int n = cut.Count(len);
    for (int k = 1; k < n; ++k) edges.push_back(start + len * k / n);
    edges.push_back(end);
  };
  for (double b : breaks) {
    if (b - edges.back() < cut.min_gap_m || b > to - cut.min_gap_m) continue;
    cut_to(b);
  }
  cut_to(to);
  return edges;
}

}  // namespace

std::vector<HoleSquare> HoleSquares(const TubeConfig& tube, const SolidStructure& structure) {
  if (structure.hole_z_m.size() != structure.hole_theta_deg.size()) {
    throw ConfigError(fmt::format("reference structure: {} hole_z_m entries but {} hole_theta_deg",
                                  structure.hole_z_m.size(), structure.hole_theta_deg.size()));
  }
  // side d sqrt(pi) / 2: the area of the round hole of diameter d; the arc at mid-surface radius
  const double half_side = 0.25 * std::sqrt(kPi) * structure.hole_diameter_m;
  const double half_angle = half_side / tube.mid_radius_m();
  std::vector<HoleSquare> out;
  for (size_t h = 0; h < structure.hole_z_m.size(); ++h) {
    const double th = structure.hole_theta_deg[h] * kDeg;
    out.push_back({structure.hole_z_m[h] - half_side, structure.hole_z_m[h] + half_side,
                   th - half_angle, th + half_angle});
  }
  return out;
}

bool HoleSquare::Holds(double z_m, double theta_rad) const {
  const double th = WrapFrom(theta_rad, theta_lo_rad);
  return z_m > z_lo_m && z_m < z_hi_m && th > theta_lo_rad && th < theta_hi_rad;
}

void SolidMeshConfig::Validate(const TubeConfig& tube) const {
  // from kMinElementM (below it the unknowns run into the millions) up to half the mid-surface
  // circumference around the tube and the tube's length along it
  const double arc = std::numbers::pi * tube.mid_radius_m();
  if (!(element_arc_m >= kMinElementM && element_arc_m <= arc)) {
    throw ConfigError(fmt::format(
        "solid mesh: element_arc_m = {} m must lie in [{}, {:.4f}] m (half the mid-surface "
        "circumference)",
        element_arc_m, kMinElementM, arc));
  }
  if (!(element_axial_m >= kMinElementM && element_axial_m <= tube.length_m)) {
    throw ConfigError(
        fmt::format("solid mesh: element_axial_m = {} m must lie in [{}, {}] m (the tube's length)",
                    element_axial_m, kMinElementM, tube.length_m));
  }
  if (degree_wall < 1 || degree_wall > 12 || degree_thickness < 1 || degree_thickness > 12) {
    throw ConfigError(
        fmt::format("solid mesh: degree_wall = {} and degree_thickness = {} must lie in [1, 12]",
                    degree_wall, degree_thickness));
  }
  if (subdivisions < 0 || subdivisions > 12) {
    throw ConfigError(
        fmt::format("solid mesh: subdivisions = {} must lie in [0, 12] (0: graded)", subdivisions));
  }
  const double element_min = std::min(element_arc_m, element_axial_m);
  if (subdivisions > 0 && !(fixed_interval_m >= 0.0 && fixed_interval_m <= element_min)) {
    throw ConfigError(fmt::format(
        "solid mesh: fixed_interval_m = {} m must lie in [0, {}] m (the shorter element length)",
        fixed_interval_m, element_min));
  }
  if (subdivisions > 0 && element_min / subdivisions < kMinElementM) {
    throw ConfigError(fmt::format(
        "solid mesh: subdivisions = {} cut elements of {} m below the shortest accepted, {} m",
        subdivisions, element_min, kMinElementM));
  }
  if (elements_through < 1 || elements_through > 8) {
    throw ConfigError(
        fmt::format("solid mesh: elements_through = {} must lie in [1, 8]", elements_through));
  }
}

SolidMeshConfig SolidMeshConfig::Refined(double factor) const {
  SolidMeshConfig out = *this;
  out.element_arc_m /= factor;
  out.element_axial_m /= factor;
  return out;
}

SolidTubeModel::SolidTubeModel(const TubeConfig& tube, const MaterialConfig& material,
                               const SolidStructure& structure, const SolidMeshConfig& mesh)
    : tube_(tube), material_(material), structure_(structure), mesh_(mesh) {
  tube_.Validate();
  mesh_.Validate(tube_);
  if (structure_.bolt_stiffness_n_m.size() != structure_.bolt_z_m.size()) {
    throw ConfigError(fmt::format("reference structure: {} bolt stiffnesses for {} bolts",
                                  structure_.bolt_stiffness_n_m.size(),
                                  structure_.bolt_z_m.size()));
  }
  holes_ = HoleSquares(tube_, structure_);
  wall_ = MakeGllRule(static_cast<int>(mesh_.degree_wall));
  thick_ = MakeGllRule(static_cast<int>(mesh_.degree_thickness));
  BuildMesh();
  Assemble();
  AddSprings();
}

void SolidTubeModel::BuildMesh() {
  const int p = static_cast<int>(mesh_.degree_wall);
  const int q = static_cast<int>(mesh_.degree_thickness);
  const int nr = static_cast<int>(mesh_.elements_through);
  const GllRule &wall = wall_, &thick = thick_;
  const double r_mid = tube_.mid_radius_m(), h = tube_.wall_thickness_m;
  const double r_in = tube_.outer_radius_m - h;

  // axial element edges: the ends of every bolt's patch on a seam and of every hole's square
  // are edges, so that a patch or a hole covers whole elements on every mesh (ends inside
  // elements, placed differently by each mesh, made the modes converge irregularly); each interval
  // between is cut into elements of about element_axial_m (graded or self-similar, IntervalCut)
  const double half = 0.5 * tube_.length_m;
  // one coordinate's cut: elements of about target_m, graded or self-similar as the mesh asks
  auto cut_of = [&](double target_m) {
    return IntervalCut{target_m, mesh_.subdivisions, mesh_.fixed_interval_m, kMinEdgeGapM};
  };
  std::vector<double> breaks;
  if (!structure_.seam_theta_deg.empty()) {
    for (double zb : structure_.bolt_z_m) {
      for (double sign : {-1.0, 1.0})
        breaks.push_back(zb + sign * structure_.bolt_patch_half_length_m);
    }
  }
  for (const HoleSquare& hole : holes_) breaks.insert(breaks.end(), {hole.z_lo_m, hole.z_hi_m});
  z_edges_m_ = CutInterval(-half, half, breaks, cut_of(mesh_.element_axial_m));
  const int nz = static_cast<int>(z_edges_m_.size()) - 1;
  const double dr = h / nr;
  rows_ = nz * p + 1;
  layers_ = nr * q + 1;

  // arc sectors between seams (one periodic sector for an uncut tube)
  std::vector<double> seams;
  for (double s : structure_.seam_theta_deg)
    seams.push_back(WrapFrom(s * std::numbers::pi / 180.0, 0.0));
  std::sort(seams.begin(), seams.end());
  seams.erase(std::unique(seams.begin(), seams.end()), seams.end());
  const bool periodic = seams.empty();
  if (periodic) seams.push_back(0.0);
  // each sector cut at the arc edges of the holes' squares (arc lengths at mid-surface, m)
  struct Sector {
    std::vector<double> edges_rad;  // element edges, ascending, first at the sector's seam
    int first_column;
  };
  std::vector<Sector> sectors;
  int columns = 0;
  for (size_t s = 0; s < seams.size(); ++s) {
    const double next = s + 1 < seams.size() ? seams[s + 1] : seams[0] + kTwoPi;
    std::vector<double> arc_breaks_m;
    for (const HoleSquare& hole : holes_) {
      for (double th : {hole.theta_lo_rad, hole.theta_hi_rad})
        arc_breaks_m.push_back(WrapFrom(th, seams[s]) * r_mid);
    }
    Sector sec{
        CutInterval(seams[s] * r_mid, next * r_mid, arc_breaks_m, cut_of(mesh_.element_arc_m)),
        columns};
    for (double& edge : sec.edges_rad) edge /= r_mid;
    arc_edges_rad_.insert(arc_edges_rad_.end(), sec.edges_rad.begin(), sec.edges_rad.end());
    const int ne = static_cast<int>(sec.edges_rad.size()) - 1;
    columns += ne * p + (periodic ? 0 : 1);
    sectors.push_back(std::move(sec));
  }
  column_theta_rad_.assign(columns, 0.0);
  auto column_of = [&](const Sector& sec, int e, int i) {
    const int c = e * p + i;
    return periodic ? c % columns : sec.first_column + c;
  };

  // elements, their nodes, and the node positions
  const int64_t nodes_total = static_cast<int64_t>(columns) * rows_ * layers_;
  node_position_m_.assign(nodes_total, Eigen::Vector3d::Zero());
  double arc_sum = 0.0;
  int arc_count = 0;
  for (const Sector& sec : sectors) {
    const int ne = static_cast<int>(sec.edges_rad.size()) - 1;
    arc_sum += sec.edges_rad.back() - sec.edges_rad.front();
    arc_count += ne;
    for (int e = 0; e < ne; ++e) {
      const double dth = sec.edges_rad[e + 1] - sec.edges_rad[e];
      for (int ez = 0; ez < nz; ++ez) {
        for (int er = 0; er < nr; ++er) {
          Element el{sec.edges_rad[e],
                     dth,
                     z_edges_m_[ez],
                     z_edges_m_[ez + 1] - z_edges_m_[ez],
                     r_in + er * dr,
                     dr,
                     {}};
          el.nodes.reserve((p + 1) * (p + 1) * (q + 1));
          for (int k = 0; k <= q; ++k) {
            for (int j = 0; j <= p; ++j) {
              for (int i = 0; i <= p; ++i) {
                const int c = column_of(sec, e, i);
                const int row = ez * p + j, layer = er * q + k;
                const int64_t node = (static_cast<int64_t>(layer) * rows_ + row) * columns + c;
                const double th = el.theta0_rad + 0.5 * (wall.points(i) + 1.0) * dth;
                const double z = el.z0_m + 0.5 * (wall.points(j) + 1.0) * el.dz_m;
                const double r = el.r0_m + 0.5 * (thick.points(k) + 1.0) * dr;
                column_theta_rad_[c] = th;
                node_position_m_[node] = {r * std::cos(th), r * std::sin(th), z};
                el.nodes.push_back(node);
              }
            }
          }
          elements_.push_back(std::move(el));
        }
      }
    }
  }
  // h of h-refinement: graded meshes' mean element length; a self-similar family's base
  // element over its subdivisions, which shrinks every refined element by the same ratio
  element_length_m_ =
      mesh_.subdivisions == 0
          ? 0.5 * (arc_sum * r_mid / arc_count + tube_.length_m / nz)
          : 0.5 * (mesh_.element_arc_m + mesh_.element_axial_m) / mesh_.subdivisions;

  // DOFs: three per node; simply supported end faces hold u_x and u_y
  node_dof_.assign(3 * nodes_total, -1);
  int64_t next = 0;
  for (int64_t node = 0; node < nodes_total; ++node) {
    const int row = static_cast<int>((node / columns) % rows_);
    const bool end = row == 0 || row == rows_ - 1;
    for (int d = 0; d < 3; ++d) {
      if (structure_.ends == TubeEnds::kSimplySupported && end && d < 2) continue;
      node_dof_[3 * node + d] = next++;
    }
  }
}

void SolidTubeModel::Assemble() {
  const int p = static_cast<int>(mesh_.degree_wall);
  const int q = static_cast<int>(mesh_.degree_thickness);
  const GllRule &wall = wall_, &thick = thick_;
  const double e_mod = material_.youngs_modulus_pa, nu = material_.poisson_ratio;
  const double lambda = e_mod * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  const double mu = e_mod / (2.0 * (1.0 + nu));
  const double rho = material_.density_kg_m3;
  const int n_local = (p + 1) * (p + 1) * (q + 1);
  const int64_t n_dofs = *std::max_element(node_dof_.begin(), node_dof_.end()) + 1;
  mass_kg_ = Eigen::VectorXd::Zero(n_dofs);

  // holes: an element inside a hole's square (its edges are element edges) keeps kHoleFill of
  // its material
  auto fill = [&](const Element& el) {
    const double z = el.z0_m + 0.5 * el.dz_m, th = el.theta0_rad + 0.5 * el.dtheta_rad;
    for (const HoleSquare& hole : holes_) {
      if (hole.Holds(z, th)) return kHoleFill;
    }
    return 1.0;
  };
  auto local = [&](int i, int j, int k) { return (k * (p + 1) + j) * (p + 1) + i; };

  // element matrices in chunks of elements, each chunk summed into its own sparse matrix
  constexpr int64_t kChunk = 64;
  const int64_t n_elements = elements();
  const int64_t n_chunks = (n_elements + kChunk - 1) / kChunk;
  std::vector<Eigen::SparseMatrix<double>> parts(n_chunks);
  std::vector<Eigen::VectorXd> masses(n_chunks);
  tbb::parallel_for(int64_t{0}, n_chunks, [&](int64_t chunk) {
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd mass = Eigen::VectorXd::Zero(n_dofs);
    Eigen::MatrixXd ke(3 * n_local, 3 * n_local);
    std::vector<std::pair<int, Eigen::Vector3d>> line;  // (local node, physical gradient 1/m)
    for (int64_t ei = chunk * kChunk; ei < std::min(n_elements, (chunk + 1) * kChunk); ++ei) {
      const Element& el = elements_[ei];
      ke.setZero();
      const double el_fill = fill(el);
      for (int k = 0; k <= q; ++k) {
        for (int j = 0; j <= p; ++j) {
          for (int i = 0; i <= p; ++i) {
            const double th = el.theta0_rad + 0.5 * (wall.points(i) + 1.0) * el.dtheta_rad;
            const double r = el.r0_m + 0.5 * (thick.points(k) + 1.0) * el.dr_m;
            const Eigen::Vector3d e_r(std::cos(th), std::sin(th), 0.0);
            const Eigen::Vector3d e_th(-std::sin(th), std::cos(th), 0.0);
            const Eigen::Vector3d e_z(0.0, 0.0, 1.0);
            // quadrature weight times the Jacobian r (dth/2)(dz/2)(dr/2), times the hole fill
            const double w = wall.weights(i) * wall.weights(j) * thick.weights(k) * r * 0.125 *
                             el.dtheta_rad * el.dz_m * el.dr_m * el_fill;
            const int qn = local(i, j, k);
            for (int d = 0; d < 3; ++d) {
              const int64_t dof = node_dof_[3 * el.nodes[qn] + d];
              if (dof >= 0) mass(dof) += rho * w;
            }
            // basis gradients at this point: only the nodes on its three grid lines
            line.clear();
            const Eigen::Vector3d g_th = e_th * (2.0 / (r * el.dtheta_rad));
            const Eigen::Vector3d g_z = e_z * (2.0 / el.dz_m);
            const Eigen::Vector3d g_r = e_r * (2.0 / el.dr_m);
            line.emplace_back(qn, wall.derivative(i, i) * g_th + wall.derivative(j, j) * g_z +
                                      thick.derivative(k, k) * g_r);
            for (int a = 0; a <= p; ++a) {
              if (a != i) line.emplace_back(local(a, j, k), wall.derivative(i, a) * g_th);
              if (a != j) line.emplace_back(local(i, a, k), wall.derivative(j, a) * g_z);
            }
            for (int a = 0; a <= q; ++a) {
              if (a != k) line.emplace_back(local(i, j, a), thick.derivative(k, a) * g_r);
            }
            // isotropic elasticity: K_(a i)(b j) += w [lambda g_a,i g_b,j + mu g_a,j g_b,i
            // + mu delta_ij g_a . g_b]
            for (const auto& [a, ga] : line) {
              for (const auto& [b, gb] : line) {
                const Eigen::Matrix3d block =
                    w * (lambda * ga * gb.transpose() + mu * gb * ga.transpose() +
                         mu * ga.dot(gb) * Eigen::Matrix3d::Identity());
                ke.block<3, 3>(3 * a, 3 * b) += block;
              }
            }
          }
        }
      }
      for (int a = 0; a < n_local; ++a) {
        for (int da = 0; da < 3; ++da) {
          const int64_t row = node_dof_[3 * el.nodes[a] + da];
          if (row < 0) continue;
          for (int b = 0; b < n_local; ++b) {
            for (int db = 0; db < 3; ++db) {
              const int64_t col = node_dof_[3 * el.nodes[b] + db];
              const double v = ke(3 * a + da, 3 * b + db);
              if (col >= 0 && v != 0.0) triplets.emplace_back(row, col, v);
            }
          }
        }
      }
    }
    parts[chunk].resize(n_dofs, n_dofs);
    parts[chunk].setFromTriplets(triplets.begin(), triplets.end());
    masses[chunk] = std::move(mass);
  });
  // sum the chunks in order (the same sums for any thread count)
  stiffness_.resize(n_dofs, n_dofs);
  for (int64_t c = 0; c < n_chunks; ++c) {
    stiffness_ += parts[c];
    mass_kg_ += masses[c];
    parts[c] = Eigen::SparseMatrix<double>();
  }
}

void SolidTubeModel::AddTie(const std::vector<std::pair<int64_t, double>>& terms, double k,
                            std::vector<Eigen::Triplet<double>>* triplets) {
  for (const auto& [ra, wa] : terms) {
    for (const auto& [rb, wb] : terms) triplets->emplace_back(ra, rb, k * wa * wb);
  }
}

void SolidTubeModel::AddSprings() {
  const int p = static_cast<int>(mesh_.degree_wall);
  const int q = static_cast<int>(mesh_.degree_thickness);
  const int columns = static_cast<int>(column_theta_rad_.size());
  const int64_t n_dofs = dofs();
  // share of the wall each node layer stands for (thickness quadrature weights, sum 1)
  std::vector<double> layer_share(layers_, 0.0);
  for (int64_t er = 0; er < mesh_.elements_through; ++er) {
    for (int k = 0; k <= q; ++k) {
      layer_share[er * q + k] += 0.5 * thick_.weights(k) / mesh_.elements_through;
    }
  }
  auto node_at = [&](int layer, int row, int column) {
    return (static_cast<int64_t>(layer) * rows_ + row) * columns + column;
  };
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<std::pair<int64_t, double>> terms;  // (DOF, weight) of one spring's stretch

  // bolts: across each seam, between the last column before it and the first after it
  const double z_first = -0.5 * tube_.length_m;
  const int nz = static_cast<int>(z_edges_m_.size()) - 1;
  if (!structure_.seam_theta_deg.empty()) {
    // column c ends a sector where column c + 1 starts the next at the same theta
    for (int c = 0; c < columns; ++c) {
      const int next = (c + 1) % columns;
      const double gap = std::abs(WrapFrom(column_theta_rad_[next] - column_theta_rad_[c], -1.0));
      if (gap > 1e-12) continue;
      for (size_t b = 0; b < structure_.bolt_z_m.size(); ++b) {
        // the bolt clamps a patch of the two faces, bolt_patch_half_length_m either side of its
        // z: springs of bolt_stiffness / patch length per metre, integrated over the patch's part
        // of every element row by that row's GLL points (a point spring on a 3-D solid would
        // soften without limit as the mesh is refined); the patch's ends are element edges
        const double lo = structure_.bolt_z_m[b] - structure_.bolt_patch_half_length_m;
        const double hi = structure_.bolt_z_m[b] + structure_.bolt_patch_half_length_m;
        SONICBOOM_DEMAND(hi > lo && "a bolt patch has a length (shell.bolt_tie_length_m > 0)");
        const double k_per_m = structure_.bolt_stiffness_n_m[b] / (hi - lo);
        for (int ez = 0; ez < nz; ++ez) {
          const double z0 = z_edges_m_[ez], z1 = z_edges_m_[ez + 1];
          const double a = std::max(lo, z0), bnd = std::min(hi, z1);
          if (!(bnd > a)) continue;
          for (int g = 0; g <= p; ++g) {
            // the g-th GLL point of [a, bnd], and the element row's basis there
            const double z = a + 0.5 * (wall_.points(g) + 1.0) * (bnd - a);
            const double w = 0.5 * wall_.weights(g) * (bnd - a);
            Eigen::VectorXd l, dl;
            LagrangeBasis(wall_, std::clamp(2.0 * (z - z0) / (z1 - z0) - 1.0, -1.0, 1.0), &l, &dl);
            for (int layer = 0; layer < layers_; ++layer) {
              const double k = k_per_m * w * layer_share[layer];
              for (int d = 0; d < 3; ++d) {
                // (face c) - (face next) at z
                terms.clear();
                for (int j = 0; j <= p; ++j) {
                  if (l(j) == 0.0) continue;
                  const int row = ez * p + j;
                  const int64_t at = node_dof_[3 * node_at(layer, row, c) + d];
                  const int64_t across = node_dof_[3 * node_at(layer, row, next) + d];
                  if (at >= 0) terms.emplace_back(at, l(j));
                  if (across >= 0) terms.emplace_back(across, -l(j));
                }
                AddTie(terms, k, &triplets);
              }
            }
          }
        }
      }
    }
  }

  // mounts: springs to ground along each end rim, by the arc each node column stands for
  std::vector<double> column_arc_m(columns, 0.0);
  for (const Element& el : elements_) {
    if (el.z0_m > z_first + 1e-12 ||
        el.r0_m > tube_.outer_radius_m - tube_.wall_thickness_m + 1e-12)
      continue;  // one element per arc span: the first axial, innermost
    for (int i = 0; i <= p; ++i) {
      const int c = static_cast<int>(el.nodes[i] % columns);
      column_arc_m[c] += 0.5 * wall_.weights(i) * el.dtheta_rad * tube_.mid_radius_m();
    }
  }
  for (const auto& [row, k_per_m] : {std::pair{0, structure_.flange_mount_stiffness_n_m2},
                                     std::pair{rows_ - 1, structure_.tool_mount_stiffness_n_m2}}) {
    if (k_per_m <= 0.0) continue;
    for (int c = 0; c < columns; ++c) {
      for (int layer = 0; layer < layers_; ++layer) {
        for (int d = 0; d < 3; ++d) {
          const int64_t dof = node_dof_[3 * node_at(layer, row, c) + d];
          if (dof < 0) continue;
          AddTie({{dof, 1.0}}, k_per_m * column_arc_m[c] * layer_share[layer], &triplets);
        }
      }
    }
  }
  if (triplets.empty()) return;
  Eigen::SparseMatrix<double> springs(n_dofs, n_dofs);
  springs.setFromTriplets(triplets.begin(), triplets.end());
  stiffness_ += springs;
  stiffness_.makeCompressed();
}

Eigen::SparseMatrix<double> SolidTubeModel::MassScaledStiffness() const {
  const Eigen::VectorXd s = mass_kg_.cwiseSqrt().cwiseInverse();
  Eigen::SparseMatrix<double> a = s.asDiagonal() * stiffness_ * s.asDiagonal();
  a.makeCompressed();
  return a;
}

const SolidTubeModel::Element& SolidTubeModel::Locate(double z_m, double theta_rad, double* xi,
                                                      double* eta) const {
  const double half = 0.5 * tube_.length_m;
  if (!(std::abs(z_m) <= half)) {
    throw ConfigError(
        fmt::format("reference model: z = {} m lies off the tube (|z| <= {} m)", z_m, half));
  }
  const double r_outer_in = tube_.outer_radius_m - 1e-9;
  for (const Element& el : elements_) {
    if (el.r0_m + el.dr_m < r_outer_in) continue;  // outer layer only
    const double th = WrapFrom(theta_rad, el.theta0_rad);
    if (th > el.theta0_rad + el.dtheta_rad + 1e-12) continue;
    if (z_m < el.z0_m - 1e-12 || z_m > el.z0_m + el.dz_m + 1e-12) continue;
    *xi = std::clamp(2.0 * (th - el.theta0_rad) / el.dtheta_rad - 1.0, -1.0, 1.0);
    *eta = std::clamp(2.0 * (z_m - el.z0_m) / el.dz_m - 1.0, -1.0, 1.0);
    return el;
  }
  SONICBOOM_DEMAND(false && "every surface point lies in an element");
  return elements_.front();
}

Eigen::VectorXd SolidTubeModel::RadialForceWeights(double z_m, double theta_rad) const {
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = SurfacePointRows({{z_m, theta_rad}});
  return Eigen::VectorXd(rows.row(0).transpose());
}

Eigen::SparseMatrix<double, Eigen::RowMajor> SolidTubeModel::SurfacePointRows(
    const std::vector<std::pair<double, double>>& points_z_theta) const {
  const int p = static_cast<int>(mesh_.degree_wall), q = static_cast<int>(mesh_.degree_thickness);
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd li, dli, lj, dlj;
  for (size_t n = 0; n < points_z_theta.size(); ++n) {
    const auto [z_m, theta_rad] = points_z_theta[n];
    double xi, eta;
    const Element& el = Locate(z_m, theta_rad, &xi, &eta);
    LagrangeBasis(wall_, xi, &li, &dli);
    LagrangeBasis(wall_, eta, &lj, &dlj);
    // (3 x 3) rows: the outward normal, the arc and the axis in Cartesian components
    Eigen::Matrix3d dir;
    dir << std::cos(theta_rad), std::sin(theta_rad), 0.0, -std::sin(theta_rad), std::cos(theta_rad),
        0.0, 0.0, 0.0, 1.0;
    // the element's outer face (k = q) interpolates the surface point
    for (int j = 0; j <= p; ++j) {
      for (int i = 0; i <= p; ++i) {
        const int64_t node = el.nodes[(q * (p + 1) + j) * (p + 1) + i];
        for (int d = 0; d < 3; ++d) {
          const int64_t dof = node_dof_[3 * node + d];
          if (dof < 0) continue;
          for (int c = 0; c < 3; ++c) {
            const double w = li(i) * lj(j) * dir(c, d);
            if (w != 0.0) triplets.emplace_back(static_cast<int>(3 * n + c), dof, w);
          }
        }
      }
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> rows(3 * points_z_theta.size(), dofs());
  rows.setFromTriplets(triplets.begin(), triplets.end());
  return rows;
}

void SolidTubeModel::AddSurfaceStrain(const Element& el, double xi, double eta, double scale,
                                      Eigen::VectorXd* row) const {
  const int p = static_cast<int>(mesh_.degree_wall), q = static_cast<int>(mesh_.degree_thickness);
  Eigen::VectorXd li, dli, lj, dlj;
  LagrangeBasis(wall_, xi, &li, &dli);
  LagrangeBasis(wall_, eta, &lj, &dlj);
  const double th = el.theta0_rad + 0.5 * (xi + 1.0) * el.dtheta_rad;
  const double r = el.r0_m + el.dr_m;
  const Eigen::Vector3d e_r(std::cos(th), std::sin(th), 0.0),
      e_th(-std::sin(th), std::cos(th), 0.0);
  const Eigen::Vector3d e_z(0.0, 0.0, 1.0);
  for (int k = 0; k <= q; ++k) {
    const double lk = k == q ? 1.0 : 0.0;        // l_k(1)
    const double dlk = thick_.derivative(q, k);  // l_k'(1)
    for (int j = 0; j <= p; ++j) {
      for (int i = 0; i <= p; ++i) {
        const Eigen::Vector3d g = e_th * (2.0 / (r * el.dtheta_rad)) * dli(i) * lj(j) * lk +
                                  e_z * (2.0 / el.dz_m) * li(i) * dlj(j) * lk +
                                  e_r * (2.0 / el.dr_m) * li(i) * lj(j) * dlk;
        if (g.isZero(0.0)) continue;
        // eps_zz + eps_thth = sum_a (e_z . u_a)(e_z . g_a) + (e_th . u_a)(e_th . g_a)
        const Eigen::Vector3d c = e_z * g.z() + e_th * e_th.dot(g);
        const int64_t node = el.nodes[(k * (p + 1) + j) * (p + 1) + i];
        for (int d = 0; d < 3; ++d) {
          const int64_t dof = node_dof_[3 * node + d];
          if (dof >= 0) (*row)(dof) += scale * c(d);
        }
      }
    }
  }
}

Eigen::VectorXd SolidTubeModel::SensorRow(double z_m, double theta_rad, double diameter_m) const {
  // polar quadrature of the disc: Gauss-Legendre in radius (weight rho d rho), uniform in angle
  constexpr int kRings = 5, kAngles = 24;
  static const double kGauss[kRings] = {-0.9061798459386640, -0.5384693101056831, 0.0,
                                        0.5384693101056831, 0.9061798459386640};
  static const double kGaussW[kRings] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                                         0.4786286704993665, 0.2369268850561891};
  const double a = 0.5 * diameter_m, r_out = tube_.outer_radius_m;
  Eigen::VectorXd row = Eigen::VectorXd::Zero(dofs());
  double total = 0.0;
  for (int ir = 0; ir < kRings; ++ir) {
    const double rho = 0.5 * a * (kGauss[ir] + 1.0);
    const double w_r = 0.5 * a * kGaussW[ir] * rho;
    for (int ia = 0; ia < kAngles; ++ia) {
      const double phi = 2.0 * std::numbers::pi * (ia + 0.5) / kAngles;
      const double z = z_m + rho * std::cos(phi), th = theta_rad + rho * std::sin(phi) / r_out;
      double xi, eta;
      const Element& el = Locate(z, th, &xi, &eta);
      AddSurfaceStrain(el, xi, eta, w_r, &row);
      total += w_r;
    }
  }
  return row / total;
}

Eigen::MatrixXd SolidTubeModel::SensorRows(const MicArrayConfig& mics) const {
  Eigen::MatrixXd rows(mics.count(), dofs());
  for (int m = 0; m < mics.count(); ++m) {
    rows.row(m) =
        SensorRow(mics.z_m[m], mics.theta_deg[m] * std::numbers::pi / 180.0, mics.disc_diameter_m)
            .transpose();
  }
  return rows;
}

std::vector<int64_t> SolidTubeModel::OuterSurfaceDofs() const {
  const int64_t per_layer = nodes() / layers_;
  std::vector<int64_t> out;
  for (int64_t node = (layers_ - 1) * per_layer; node < nodes(); ++node) {
    for (int d = 0; d < 3; ++d) {
      if (node_dof_[3 * node + d] >= 0) out.push_back(node_dof_[3 * node + d]);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

Eigen::VectorXd SolidTubeModel::Sample(
    const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& field) const {
  Eigen::VectorXd u = Eigen::VectorXd::Zero(dofs());
  for (int64_t node = 0; node < nodes(); ++node) {
    const Eigen::Vector3d value = field(node_position_m_[node]);
    for (int d = 0; d < 3; ++d) {
      const int64_t dof = node_dof_[3 * node + d];
      if (dof >= 0) u(dof) = value(d);
    }
  }
  return u;
}

}  // namespace sonicboom::solid
