// .npy reader (hardware ReadNpy) on arbitrary bytes.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "fuzz_file.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/npy.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = sonicboom::fuzz::AsFile(data, size, ".npy");
  try {
    const sonicboom::hardware::NpyArray a = sonicboom::hardware::ReadNpy(path);
    size_t n = 1;
    for (int64_t d : a.shape) n *= static_cast<size_t>(d);
    if (n != a.data.size()) std::abort();
    for (double v : a.data) {
      if (!std::isfinite(v)) std::abort();
    }
  } catch (const sonicboom::Error&) {
  }
  return 0;
}
