#pragma once
/// What the reference-model commands (reference, rerender) share. Private to experiments.

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/solid/solid_tube.h"

namespace sonicboom::experiments {

/// The physics of the configured structure (the shell section's seams, bolts, holes, mounts),
/// none of its discretization; `ideal` (or shell.ideal) leaves a uniform tube.
solid::SolidStructure ReferenceStructure(const acoustics::ShellConfig& shell, TubeEnds ends,
                                         bool ideal);

}  // namespace sonicboom::experiments
