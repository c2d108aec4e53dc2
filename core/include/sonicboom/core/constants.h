#pragma once
/// Mathematical constants shared by every module (one definition each).

#include <numbers>

namespace sonicboom {

inline constexpr double kPi = std::numbers::pi;

}  // namespace sonicboom
