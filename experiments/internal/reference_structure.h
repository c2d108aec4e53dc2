#pragma once
/// The configured structure as the reference solid takes it. Private to experiments (and
/// apps/reference_levels, which compiles it without the CLI).

#include <cstdint>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/solid/solid_tube.h"

namespace sonicboom::experiments {

/// The meshes of `sonicboom reference` (and apps/reference_levels): the coarsest mesh, the
/// number of levels and the refinement between them, the band and the tube's structure.
struct ReferenceLevelOptions {
  TubeEnds ends = TubeEnds::kFree;
  bool ideal = false;
  double max_frequency_hz = 20000.0;
  double element_m = 0.0135;  // element length of the coarsest mesh
  int64_t degree_wall = 4;
  int64_t degree_thickness = 3;
  int64_t levels = 3;
  double ratio = 1.25;  // element length of level l: element_m / ratio^l
};

/// The physics of the configured structure (the shell section's seams, bolts, holes, mounts),
/// none of its discretization; `ideal` (or shell.ideal) leaves a uniform tube.
solid::SolidStructure ReferenceStructure(const acoustics::ShellConfig& shell, TubeEnds ends,
                                         bool ideal);

}  // namespace sonicboom::experiments
