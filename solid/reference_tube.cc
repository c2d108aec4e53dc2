#include "sonicboom/solid/reference_tube.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/solid_modes.h"

namespace sonicboom::solid {
namespace {

// bump when anything the solve computes changes (2: bolt patches' ends are element edges; 3:
// holes are squares of their area on element edges)
constexpr int kReferenceModelVersion = 3;
constexpr char kMagic[8] = {'S', 'B', 'R', 'E', 'F', 'M', '0', '1'};

}  // namespace

// Every field of these structs is in the key below, or deliberately left out (the tube's contact
// region, the material's loss factor: they change no mode). A struct that grows fails here, so
// that its new field is put into the key, or these sizes updated, on purpose (x86-64 sizes).
static_assert(sizeof(TubeConfig) == 48 && sizeof(MaterialConfig) == 32 &&
                  sizeof(MicArrayConfig) == 56 && sizeof(SolidStructure) == 160 &&
                  sizeof(SolidMeshConfig) == 56,
              "a config struct changed: update ReferenceCacheKey and these sizes");

std::string ReferenceCacheKey(const ReferenceTubeConfig& c) {
  const SolidStructure& s = c.structure;
  std::string key = fmt::format(
      "reference v{} tube {:.17g} {:.17g} {:.17g} material {:.17g} {:.17g} {:.17g} mesh {:.17g} "
      "{:.17g} {} {} {} ends {} seams {:.17g} bolts {:.17g} k {:.17g} patch {:.17g} holes {:.17g} "
      "/ {:.17g} d "
      "{:.17g} mounts {:.17g} {:.17g} mics {:.17g} / {:.17g} d {:.17g} band {:.17g}",
      kReferenceModelVersion, c.tube.outer_radius_m, c.tube.wall_thickness_m, c.tube.length_m,
      c.material.youngs_modulus_pa, c.material.poisson_ratio, c.material.density_kg_m3,
      c.mesh.element_arc_m, c.mesh.element_axial_m, c.mesh.degree_wall, c.mesh.degree_thickness,
      c.mesh.elements_through, static_cast<int>(s.ends), fmt::join(s.seam_theta_deg, ","),
      fmt::join(s.bolt_z_m, ","), fmt::join(s.bolt_stiffness_n_m, ","), s.bolt_patch_half_length_m,
      fmt::join(s.hole_z_m, ","), fmt::join(s.hole_theta_deg, ","), s.hole_diameter_m,
      s.flange_mount_stiffness_n_m2, s.tool_mount_stiffness_n_m2, fmt::join(c.mics.z_m, ","),
      fmt::join(c.mics.theta_deg, ","), c.mics.disc_diameter_m, c.max_frequency_hz);
  // self-similar meshes only, so that the keys of graded meshes solved before stay
  if (c.mesh.subdivisions != 0)
    key +=
        fmt::format(" subdivisions {} fixed {:.17g}", c.mesh.subdivisions, c.mesh.fixed_interval_m);
  return key;
}

ReferenceTube::ReferenceTube(const ReferenceTubeConfig& config) : config_(config) {
  model_ = std::make_unique<SolidTubeModel>(config_.tube, config_.material, config_.structure,
                                            config_.mesh);
  config_.mics.Validate(config_.tube);
  surface_dofs_ = model_->OuterSurfaceDofs();
  Solve();
}

ReferenceTube::~ReferenceTube() = default;

void ReferenceTube::Solve() {
  const std::string key = ReferenceCacheKey(config_);
  std::string path;
  if (!config_.cache_dir.empty()) {
    path = (std::filesystem::path(config_.cache_dir) /
            fmt::format("reference-{:016x}.bin", internal::Fnv1a(key.data(), key.size())))
               .string();
  }
  // a cached file (sonicboom/core/cache_file.h): header {modes, mics, surface DOFs}, omega, the
  // discs' read-outs, the surface shapes, checksum
  internal::CacheFileReader in;
  int64_t header[3] = {0, 0, 0};
  if (!path.empty() && in.Open(path, kMagic, key, header, 3)) {
    const bool sized = header[0] >= 0 && header[0] < (1 << 20) &&
                       header[1] == config_.mics.count() &&
                       header[2] == static_cast<int64_t>(surface_dofs_.size());
    if (sized) {
      omega_rad_s_.resize(header[0]);
      disc_strain_.resize(header[1], header[0]);
      surface_shapes_.resize(header[2], header[0]);
      in.Read(omega_rad_s_.data(), sizeof(double) * omega_rad_s_.size());
      in.Read(disc_strain_.data(), sizeof(double) * disc_strain_.size());
      in.Read(surface_shapes_.data(), sizeof(double) * surface_shapes_.size());
    }
    if (in.Finish() && sized) {
      from_cache_ = true;
      return;
    }
  }

  SolidModeRequest request;
  request.max_frequency_hz = config_.max_frequency_hz;
  request.shape_dofs = surface_dofs_;
  request.projection_rows = model_->SensorRows(config_.mics).sparseView();
  const SolidModes modes = SolveSolidModes(*model_, request);
  omega_rad_s_ = modes.omega_rad_s;
  disc_strain_ = modes.projections;
  surface_shapes_ = modes.shapes;
  if (path.empty()) return;
  internal::WriteCacheFile(config_.cache_dir, path, kMagic, key,
                           {omega_rad_s_.size(), disc_strain_.rows(), surface_shapes_.rows()},
                           {{omega_rad_s_.data(), sizeof(double) * omega_rad_s_.size()},
                            {disc_strain_.data(), sizeof(double) * disc_strain_.size()},
                            {surface_shapes_.data(), sizeof(double) * surface_shapes_.size()}});
}

Eigen::VectorXd ReferenceTube::ModalDrive(double z_m, double theta_rad) const {
  // the point force's few nonzero weights (ascending DOFs, all on the outer surface), each
  // times its surface DOF's row of the shapes
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows =
      model_->SurfacePointRows({{z_m, theta_rad}});
  Eigen::VectorXd drive = Eigen::VectorXd::Zero(omega_rad_s_.size());
  for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(rows, 0); it; ++it) {
    const auto at = std::lower_bound(surface_dofs_.begin(), surface_dofs_.end(), it.col());
    SONICBOOM_DEMAND(at != surface_dofs_.end() && *at == it.col());
    if (it.value() != 0.0)
      drive += it.value() * surface_shapes_.row(at - surface_dofs_.begin()).transpose();
  }
  return drive;
}

}  // namespace sonicboom::solid
