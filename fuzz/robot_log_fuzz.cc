// Robot-log CSV reader (hardware ReadProprioCsv) on arbitrary bytes.
#include <cstdint>
#include <cstdlib>

#include "fuzz_file.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/capture.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = sonicboom::fuzz::AsFile(data, size, ".csv");
  try {
    const Eigen::MatrixXf proprio = sonicboom::hardware::ReadProprioCsv(path);
    if (proprio.cols() != 10 || proprio.rows() < 1 || !proprio.allFinite()) std::abort();
  } catch (const sonicboom::Error&) {
  }
  return 0;
}
