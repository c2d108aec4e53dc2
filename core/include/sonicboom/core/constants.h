#pragma once
/// Mathematical constants shared by every module (one definition each).

#include <numbers>

namespace sonicboom {

inline constexpr double kPi = std::numbers::pi;
/// Radians per degree.
inline constexpr double kDeg = kPi / 180.0;

}  // namespace sonicboom
