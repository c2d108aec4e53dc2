#pragma once
/// What the reference solid's convergence levels take from a config and options: its structure,
/// its mesh and the sequence of meshes `sonicboom reference` refines. Private to experiments (and
/// apps/reference_levels, which compiles it without the CLI, so that the levels it solves are the
/// ones the command reads back).

#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/solid/convergence.h"
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
  // when set, a self-similar family instead of levels and ratio: level l cuts every interval
  // between forced edges into subdivisions[l] x the elements of element_m
  // (SolidMeshConfig::subdivisions), ascending, 3 to 6 levels
  std::vector<int64_t> subdivisions;
  // self-similar: intervals between forced edges shorter than this stay one element (0: none)
  double fixed_interval_m = solid::SolidMeshConfig{}.fixed_interval_m;
};

/// The options of ReferenceLevelOptions on a command (`sonicboom reference`,
/// apps/reference_levels), with one help text for both.
void AddReferenceLevelOptions(CLI::App* cmd, ReferenceLevelOptions* o);

/// The physics of the configured structure (the shell section's seams, bolts, holes, mounts),
/// none of its discretization; `ideal` (or shell.ideal) leaves a uniform tube.
solid::SolidStructure ReferenceStructure(const acoustics::ShellConfig& shell, TubeEnds ends,
                                         bool ideal);

/// The reference mesh of a command's options (elements of element_m, the GLL degrees), checked
/// against the tube; a ConfigError names `option` and its value with the limit it broke.
solid::SolidMeshConfig ReferenceMesh(double element_m, int64_t degree_wall,
                                     int64_t degree_thickness, const TubeConfig& tube,
                                     const std::string& option);

/// One request per level of `o` (coarse to fine) for the tube, material and discs given and the
/// structure of `shell`, each kept in cache_dir. Refuses (ConfigError naming the option) levels
/// outside [3, 6], a ratio outside (1, 2], subdivisions that do not ascend, a band outside
/// (100, 40000] Hz, a mesh that cannot be built.
std::vector<solid::ConvergenceRequest> ReferenceLevelRequests(
    const ReferenceLevelOptions& o, const TubeConfig& tube, const MaterialConfig& material,
    const MicArrayConfig& mics, const acoustics::ShellConfig& shell, const std::string& cache_dir);

}  // namespace sonicboom::experiments
