#pragma once
/// Modes of a varied structure without a new eigensolve: a Rayleigh-Ritz projection of the varied
/// stiffness and mass onto the base structure's modes, enriched by static corrections. A variant
/// must share the base's grid, degrees of freedom and wall: bolts (count, positions, stiffness),
/// mounts, Poisson's ratio and attached masses may change; holes, seams, grid, the tube's size,
/// modulus, density and thickness need a full solve.
///
/// Basis: the base modes Phi (dofs x N, mass-normalized) and, for the lowest `enrichment` of
/// them, the static response K_v^-1 (dK - omega_k^2 dM) phi_k of the variant to its stiffness
/// and mass change (the first-order shape correction in its quasi-static limit), made
/// M-orthonormal and M-orthogonal to Phi under the base mass M. The reduced problem
/// Q^T K_v Q y = omega^2 Q^T M_v Q y (Q^T M_v Q = I + Q^T dM Q: the identity when no mass is
/// added) is solved densely; the shapes Q y are mass-normalized for the variant.
///
/// Cost: the shell's stiffness depends on Poisson's ratio only through three factors,
/// K_shell(nu) = X1 / (1 - nu) + X2 / (1 + nu) + X3 (membrane and bending pair energies, shear and
/// twist, free edges), so Phi^T K_shell(nu) Phi is a combination of three projections made once;
/// a variant adds the projection of its springs (bolts and mounts: a few seam and rim DOFs).
/// docs/randomization.md gives the error against full solves.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_modes.h"

namespace sonicboom::acoustics {

/// Static corrections in the basis (of the lowest base modes).
constexpr int64_t kRitzEnrichment = 48;

/// Immutable: the base structure, its modes and the projections every variant reuses.
/// Project is const and thread-safe.
class ShellRitzProjector {
 public:
  /// base_modes must carry their shapes. Throws Error when they do not.
  ShellRitzProjector(const ShellModel& base, const ShellModes& base_modes,
                     int64_t enrichment = kRitzEnrichment);
  ~ShellRitzProjector();
  ShellRitzProjector(const ShellRitzProjector&) = delete;
  ShellRitzProjector& operator=(const ShellRitzProjector&) = delete;

  /// The variant's elastic modes up to max_frequency_hz (ascending, mass-normalized shapes,
  /// dofs x modes). Throws ConfigError when the variant differs from the base in DOFs or wall.
  ShellModes Project(const ShellModel& varied, double max_frequency_hz) const;
  /// The same with the shapes at `rows` only (computed in single precision).
  ModeRows Project(const ShellModel& varied, double max_frequency_hz,
                   const std::vector<int64_t>& rows) const;

  struct Impl;  // opaque: the base and the projections

 private:
  std::unique_ptr<Impl> impl_;
};

/// Project(varied, max_frequency_hz, rows) through an on-disk cache in cache_dir ("" = none):
/// the modes are stored in single precision under a hash of the base's and the variant's keys,
/// the band, the enrichment and the rows, and read back as they were computed. `projector` is
/// called (once, from any thread) only when the file is missing or does not match. Each call
/// marks the base's entry (CachedShellModes(base, max_frequency_hz, 0, true)) used too, so that a
/// cache budget prunes a pool's variants before the base they are projected from.
ModeRows CachedRitzModes(const std::function<const ShellRitzProjector&()>& projector,
                         const ShellModel& base, const ShellModel& varied, double max_frequency_hz,
                         const std::vector<int64_t>& rows, const std::string& cache_dir,
                         bool* hit = nullptr);

/// One variant's modes by a projector made for it alone.
ShellModes RitzShellModes(const ShellModel& base, const ShellModes& base_modes,
                          const ShellModel& varied, double max_frequency_hz,
                          int64_t enrichment = kRitzEnrichment);

}  // namespace sonicboom::acoustics
