#pragma once
/// Natural modes of the discretized shell (shell.h): K phi = omega^2 M phi by shift-invert block
/// Lanczos on M^-1/2 K M^-1/2, sliced over frequency. Sylvester's inertia (the number of negative
/// pivots of an LDL^T factorization of K - s M is the number of modes below s) plans the slices and
/// tells each how many modes it holds, so no mode of the requested range is missed. Slices are
/// solved concurrently (oneTBB); the plan depends on inertia counts only, so the result is the same
/// bit for bit for any number of threads.

#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "sonicboom/acoustics/shell.h"

namespace sonicboom::acoustics {

/// Frequencies below this are rigid-body motion of a free structure (0 in the continuum; the
/// discretization leaves them at a fraction of a hertz) and are not listed as modes.
constexpr double kRigidBodyHz = 20.0;

struct ShellModes {
  Eigen::VectorXd omega_rad_s;  // (modes) elastic modes, ascending
  Eigen::MatrixXd shapes;       // (dofs x modes) mass-normalized: phi^T M phi = 1
  int64_t rigid_body_modes{0};  // modes below kRigidBodyHz, not listed
};

/// The elastic modes with frequency <= max_frequency_hz, or the lowest max_count of them
/// (whichever limit is given; 0 = no limit; at least one must be given). with_shapes = false
/// skips the eigenvectors. Throws ConfigError for a range that holds more than 20000 modes.
ShellModes SolveShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                           bool with_shapes = true);

/// SolveShellModes through an on-disk cache: the result is stored bit for bit in cache_dir under
/// a hash of ShellModel::key() and the request, and read back when the same structure and request
/// come again (the stored key is compared in full). An empty cache_dir disables the cache; a file
/// that cannot be read is recomputed and replaced. *hit (optional) tells whether it was read.
ShellModes CachedShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                            bool with_shapes, const std::string& cache_dir, bool* hit = nullptr);

/// The file CachedShellModes keeps this request in, under cache_dir.
std::string ShellModesCachePath(const ShellModel& model, double max_frequency_hz,
                                int64_t max_count, bool with_shapes, const std::string& cache_dir);

/// What the default mode cache directory is chosen from (empty = unset).
struct ModeCacheEnvironment {
  std::string cache_dir;       // $SONICBOOM_CACHE_DIR
  std::string xdg_cache_home;  // $XDG_CACHE_HOME (only an absolute path counts)
  std::string home;            // $HOME
  std::string passwd_home;     // the user's home directory in the passwd database
};
/// The directory, and a warning when the choice is one the user should hear of ("" = none).
struct ModeCacheChoice {
  std::string dir;  // "" = no cache
  std::string warning;
};
/// $SONICBOOM_CACHE_DIR, else $XDG_CACHE_HOME/sonicboom/modes, else $HOME/.cache/sonicboom/modes;
/// with HOME unset the passwd home's .cache/sonicboom/modes (warned), else none (warned: every
/// run solves its modes again). Both warnings name HOME, SONICBOOM_CACHE_DIR and
/// acoustics.mode_cache_dir.
ModeCacheChoice ChooseModeCacheDir(const ModeCacheEnvironment& env);

/// ChooseModeCacheDir of this process's environment; its warning is logged once per process.
std::string DefaultModeCacheDir();

/// The hash that names a cache file (FNV-1a of its full key; the file stores the key too).
uint64_t CacheKeyHash(const std::string& key);

/// The number of modes (rigid-body ones included) with frequency below f_hz, by inertia.
int64_t CountModesBelow(const ShellModel& model, double f_hz);

}  // namespace sonicboom::acoustics
