#pragma once
/// What the reference-model commands (reference, rerender, fidelity) share. Private to experiments.

#include <cstdint>
#include <string>
#include <vector>
#include "sonicboom/acoustics/shell.h"

#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_tube.h"

#include "internal/reference_levels.h"

namespace sonicboom::experiments {

/// The reference solid of `config`'s tube, material, mics and structure (ReferenceStructure, or
/// a uniform tube when `ideal`) on `mesh`, its modes to band_hz, cached in cache_dir.
solid::ReferenceTubeConfig ReferenceTubeOf(const SonicBoomConfig& config,
                                           const solid::SolidMeshConfig& mesh, double band_hz,
                                           bool ideal, const std::string& cache_dir);

/// The /variation column that says which model rendered a sample of a dataset generated with
/// randomize.reference_fraction > 0: 1 the reference solid, 0 the configured vibration model.
inline constexpr const char* kReferenceRenderedName = "ref_rendered";

/// Refuses (ConfigError) a reference band `band_hz` not in (100 Hz, the Nyquist frequency of
/// sample_rate_hz), naming the option or key `name` and where the rate comes from (`rate_of`).
void CheckReferenceBand(double band_hz, double sample_rate_hz, const std::string& name,
                        const std::string& rate_of);

/// The names of the draws RenderReferenceSample returns, in its order (a dataset's /variation
/// columns for them).
const std::vector<std::string>& ReferenceVariationNames();

/// `sample`'s audio rendered by the reference solid: the label's contact (place, normal speed,
/// the first contact's effective mass, onset) struck with a striker, damping and sensor chain
/// drawn from the sample's seed (stream kReference; noise kNoise), so the result does not depend
/// on the thread. Replaces the audio, `clipped` and the label's impulse and duration; returns the
/// draws (ReferenceVariationNames). frames: the record length.
std::vector<double> RenderReferenceSample(const solid::ReferenceTube& tube, double sample_rate_hz,
                                          int64_t frames, StrikeSample* sample);

}  // namespace sonicboom::experiments
