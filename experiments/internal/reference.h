#pragma once
/// What the reference-model commands (reference, rerender, fidelity) share. Private to experiments.

#include <cstdint>
#include <string>
#include "sonicboom/acoustics/shell.h"

#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_tube.h"

#include "internal/reference_structure.h"

namespace sonicboom::experiments {

/// The reference mesh of a command's options (elements of element_m, the GLL degrees), checked
/// against the tube; a ConfigError names `option` and its value with the limit it broke.
solid::SolidMeshConfig ReferenceMesh(double element_m, int64_t degree_wall,
                                     int64_t degree_thickness, const TubeConfig& tube,
                                     const std::string& option);

/// The reference solid of `config`'s tube, material, mics and structure (ReferenceStructure, or
/// a uniform tube when `ideal`) on `mesh`, its modes to band_hz, cached in cache_dir.
solid::ReferenceTubeConfig ReferenceTubeOf(const SonicBoomConfig& config,
                                           const solid::SolidMeshConfig& mesh, double band_hz,
                                           bool ideal, const std::string& cache_dir);

}  // namespace sonicboom::experiments
