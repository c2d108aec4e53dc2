#pragma once
// Values a recording does not have are NaN in a dataset, "not known" (docs/dataset.md): a
// command that needs one refuses the strike, naming the file, the sample row and the column
// (docs/robustness.md).

#include <cmath>
#include <cstdint>
#include <string>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/sample.h"

namespace sonicboom::experiments {

// "FILE: sample row R (index I)": where a refused value lies.
inline std::string SampleRowOf(const std::string& file, int64_t row, const StrikeSample& meta) {
  return fmt::format("{}: sample row {} (index {})", file, row, meta.index);
}

// `value` of column `column` of the sample, or SchemaError saying what it is and what the command
// needs it for (`need`) when it is NaN (not known) or infinite. With `zero_unknown` (a dataset
// of source hardware), 0 is not known either: imports before unknowns were NaN wrote 0.
inline double KnownValue(double value, const std::string& file, int64_t row,
                         const StrikeSample& meta, const char* column, const std::string& need,
                         bool zero_unknown = false) {
  if (std::isfinite(value) && !(zero_unknown && value == 0.0)) return value;
  const std::string what = std::isnan(value) ? std::string("NaN (not known)")
                           : value == 0.0
                               ? std::string(
                                     "0 in an imported dataset (not known: imports before NaN "
                                     "marked unknown values wrote 0; import it again)")
                               : fmt::format("{}", value);
  throw SchemaError(
      fmt::format("{}: {} is {}; {}", SampleRowOf(file, row, meta), column, what, need));
}

}  // namespace sonicboom::experiments
