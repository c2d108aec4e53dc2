// The configured structure (the shell section's seams, bolts, holes, mounts) as the reference
// solid takes it. Its own file so that apps/reference_levels compiles it without the CLI.
#include "internal/reference_structure.h"

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

}  // namespace sonicboom::experiments
