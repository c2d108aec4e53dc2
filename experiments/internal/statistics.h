#pragma once
/// Small summaries of measured values shared by the experiments. Private to experiments.

#include <vector>

namespace sonicboom::experiments {

/// Median of the values (the mean of the middle two for an even count; NaN when empty).
double Median(std::vector<double> values);

}  // namespace sonicboom::experiments
