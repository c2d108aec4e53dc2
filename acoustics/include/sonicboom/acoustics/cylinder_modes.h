#pragma once
/// Closed-form modes of an ideal thin cylindrical shell (docs/physics.md, "Shell modes"): the
/// simply supported (shear-diaphragm) tube by Flügge's 3x3 equations per (m, n), and Rayleigh's
/// inextensional modes of the free-free tube. Uses the mid-surface radius.

#include <string>
#include <vector>

#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// One mode family (m axial half-waves, m >= 0, n circumferential waves, one of 3 roots).
/// Shapes: u = U cos(k x) cos(n th), v = V sin(k x) sin(n th), w = W sin(k x) cos(n th),
/// x in [0, L] from one end, k = m pi / L, w radial outward; (U, V, W) has unit norm.
/// For n >= 1 the mode is a degenerate pair (the same shape turned by pi / (2n)).
struct ShellMode {
  int m{1};
  int n{0};
  int root{0};  // 0 = lowest (flexural for n >= 2)
  double frequency_hz{0.0};
  double u{0.0}, v{0.0}, w{0.0};
};

/// All simply-supported modes with frequency <= max_frequency_hz, ascending; m = 0 holds the
/// axially uniform shear modes u = cos(n th) (v = w = 0: no radial force drives them).
std::vector<ShellMode> SimplySupportedModes(const TubeConfig& tube, const MaterialConfig& material,
                                            double max_frequency_hz);

/// Frequencies of the lowest `count` modes of a tube with `ends`, ascending, degenerate pairs
/// listed twice. Free ends list Rayleigh's inextensional families
/// n = 2, 3, ... (m = 0 and m = 1).
std::vector<double> ClosedFormFrequencies(const TubeConfig& tube, const MaterialConfig& material,
                                          TubeEnds ends, int count);

/// Rayleigh's free-free inextensional frequency f_n0 (Hz), n >= 2.
double RayleighFrequency(const TubeConfig& tube, const MaterialConfig& material, int n);

}  // namespace sonicboom::acoustics
