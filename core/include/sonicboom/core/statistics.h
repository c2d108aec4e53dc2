#pragma once
/// Small summaries of measured values, one definition for every module.

#include <vector>

namespace sonicboom {

/// Median of the values (the mean of the middle two for an even count; NaN when empty).
double Median(std::vector<double> values);

}  // namespace sonicboom
