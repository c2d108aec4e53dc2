// The reference solid's levels from a config and options: structure, mesh, the refined sequence.
// Its own file so that apps/reference_levels compiles it without the CLI.
#include "internal/reference_levels.h"

#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {

solid::SolidStructure ReferenceStructure(const acoustics::ShellConfig& shell, TubeEnds ends,
                                         bool ideal) {
  solid::SolidStructure s;
  s.ends = ends;
  // the solid has no lumped masses: a tube with them would be rendered without them
  if (!shell.attached_mass_kg.empty()) {
    throw ConfigError(fmt::format(
        "shell.attached_mass_kg: the reference solid carries no attached masses ({} set); "
        "render a tube with them by the shell rungs",
        shell.attached_mass_kg.size()));
  }
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
  const bool self_similar = !o.subdivisions.empty();
  const int64_t levels = self_similar ? static_cast<int64_t>(o.subdivisions.size()) : o.levels;
  if (levels < 3 || levels > 6)
    throw ConfigError(fmt::format("--{} must give 3 to 6 levels (Richardson needs three), got {}",
                                  self_similar ? "subdivisions" : "levels", levels));
  for (size_t l = 0; self_similar && l < o.subdivisions.size(); ++l) {
    if (o.subdivisions[l] < 1 || (l > 0 && o.subdivisions[l] <= o.subdivisions[l - 1]))
      throw ConfigError(fmt::format("--subdivisions {}: must be positive and ascending",
                                    fmt::join(o.subdivisions, ",")));
  }
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
  // level l: elements of element_m / ratio^l (the keys of the cached levels follow this exactly),
  // or element_m's intervals cut into subdivisions[l] times as many
  std::vector<solid::ConvergenceRequest> requests;
  for (int64_t l = 0; l < levels; ++l) {
    if (self_similar) {
      request.solid.mesh = base;
      request.solid.mesh.subdivisions = o.subdivisions[l];
      request.solid.mesh.fixed_interval_m = o.fixed_interval_m;
      try {
        request.solid.mesh.Validate(tube);
      } catch (const ConfigError& e) {
        throw ConfigError(fmt::format("--subdivisions {} --fixed-interval-m {}: {}",
                                      o.subdivisions[l], o.fixed_interval_m, e.what()));
      }
    } else {
      request.solid.mesh = base.Refined(std::pow(o.ratio, l));
    }
    requests.push_back(request);
  }
  return requests;
}

void AddReferenceLevelOptions(CLI::App* cmd, ReferenceLevelOptions* o) {
  cmd->add_flag("--ideal", o->ideal, "ideal uniform tube (no seam, holes, bolts or mounts)");
  cmd->add_option("--max-frequency", o->max_frequency_hz, "modes up to this frequency (Hz)");
  cmd->add_option("--element-m", o->element_m, "element length of the coarsest mesh (m)");
  cmd->add_option("--degree-wall", o->degree_wall, "GLL degree along the wall");
  cmd->add_option("--degree-thickness", o->degree_thickness, "GLL degree through the wall");
  auto* levels = cmd->add_option("--levels", o->levels, "meshes, each --ratio finer than the last");
  auto* ratio = cmd->add_option("--ratio", o->ratio, "refinement ratio between levels");
  auto* subdivisions =
      cmd->add_option("--subdivisions", o->subdivisions,
                      "self-similar meshes instead of --levels and --ratio: e.g. 3,4,5 cuts every "
                      "element of --element-m into 3, 4 and 5 (intervals between forced edges "
                      "under --fixed-interval-m stay one element)")
          ->delimiter(',')
          ->excludes(levels)
          ->excludes(ratio);
  cmd->add_option("--fixed-interval-m", o->fixed_interval_m,
                  "with --subdivisions: intervals between forced edges (seams, bolt patches, "
                  "holes) shorter than this stay one element on every level (m; 0: none)")
      ->needs(subdivisions);
}

}  // namespace sonicboom::experiments
