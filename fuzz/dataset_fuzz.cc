// Dataset reader (core DatasetReader over HDF5) on arbitrary bytes: open (complete or not), read
// the first samples whole, and summarize.
#include <hdf5.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>

#include "fuzz_file.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = sonicboom::fuzz::AsFile(data, size, ".h5");
  try {
    const sonicboom::DatasetReader reader(path, /*allow_incomplete=*/true);
    for (int64_t i = 0; i < std::min<int64_t>(reader.size(), 3); ++i) {
      const sonicboom::StrikeSample s = reader.Read(i);
      if (!s.audio.allFinite() || !s.proprio.allFinite()) std::abort();
    }
  } catch (const sonicboom::Error&) {
  }
  try {
    sonicboom::SummarizeDatasetJson(path);
  } catch (const sonicboom::Error&) {
  }
  // HDF5 keeps freed blocks on its own free lists: hand them back, so that what is left after an
  // input is what it leaked
  H5garbage_collect();
  return 0;
}
