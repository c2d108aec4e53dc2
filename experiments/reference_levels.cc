// The reference solid's levels from a config and options: structure, mesh, the refined sequence.
// Its own file so that apps/reference_levels compiles it without the CLI.
#include "internal/reference_levels.h"

#include <cmath>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {

solid::SolidStructure ReferenceStructure(const acoustics::ShellConfig& shell, TubeEnds ends,
                                         bool ideal) {
  solid::SolidStructure s;
  s.ends = ends;
  if (ideal || shell.ideal) return s;
  s.seam_theta_deg = shell.seam_theta_deg;
  s.bolt_z_m = shell.bolt_z_m;
  for (size_t b = 0; b < shell.bolt_z_m.size(); ++b) {
    const double scale = shell.bolt_stiffness_scale.empty() ? 1.0 : shell.bolt_stiffness_scale[b];
    s.bolt_stiffness_n_m.push_back(shell.bolt_stiffness_n_m * scale);
  }
  // a point bolt clamps a washer's width; a tie spreads over its length
  s.bolt_patch_half_length_m =
      shell.bolt_model == acoustics::BoltModel::kTie ? 0.5 * shell.bolt_tie_length_m : 0.004;
  s.hole_z_m = shell.hole_z_m;
  s.hole_theta_deg = shell.hole_theta_deg;
  s.hole_diameter_m = shell.hole_diameter_m;
  s.flange_mount_stiffness_n_m2 = shell.flange_mount_stiffness_n_m2;
  s.tool_mount_stiffness_n_m2 = shell.tool_mount_stiffness_n_m2;
  return s;
}

solid::SolidMeshConfig ReferenceMesh(double element_m, int64_t degree_wall,
                                     int64_t degree_thickness, const TubeConfig& tube,
                                     const std::string& option) {
  solid::SolidMeshConfig mesh;
  mesh.element_arc_m = element_m;
  mesh.element_axial_m = element_m;
  mesh.degree_wall = degree_wall;
  mesh.degree_thickness = degree_thickness;
  try {
    mesh.Validate(tube);
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{} {}: {}", option, element_m, e.what()));
  }
  return mesh;
}

std::vector<solid::ConvergenceRequest> ReferenceLevelRequests(
    const ReferenceLevelOptions& o, const TubeConfig& tube, const MaterialConfig& material,
    const MicArrayConfig& mics, const acoustics::ShellConfig& shell, const std::string& cache_dir) {
  if (o.levels < 3 || o.levels > 6)
    throw ConfigError(
        fmt::format("--levels must be in [3, 6] (Richardson needs three), got {}", o.levels));
  if (!(o.ratio > 1.0 && o.ratio <= 2.0))
    throw ConfigError(fmt::format("--ratio must be in (1, 2], got {}", o.ratio));
  if (!(o.max_frequency_hz > 100.0 && o.max_frequency_hz <= 40000.0))
    throw ConfigError(
        fmt::format("--max-frequency must be in (100, 40000] Hz, got {}", o.max_frequency_hz));
  const solid::SolidMeshConfig base =
      ReferenceMesh(o.element_m, o.degree_wall, o.degree_thickness, tube, "--element-m");
  solid::ConvergenceRequest request;
  request.solid.tube = tube;
  request.solid.material = material;
  request.solid.mics = mics;
  request.solid.structure = ReferenceStructure(shell, o.ends, o.ideal);
  request.solid.max_frequency_hz = o.max_frequency_hz;
  request.solid.cache_dir = cache_dir;
  // level l: elements of element_m / ratio^l (the keys of the cached levels follow this exactly)
  std::vector<solid::ConvergenceRequest> requests;
  for (int64_t l = 0; l < o.levels; ++l) {
    request.solid.mesh = base.Refined(std::pow(o.ratio, l));
    requests.push_back(request);
  }
  return requests;
}

}  // namespace sonicboom::experiments
