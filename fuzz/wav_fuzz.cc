// WAV reader (core ReadWav) on arbitrary bytes: an Error or a finite clip, nothing else.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "fuzz_file.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = sonicboom::fuzz::AsFile(data, size, ".wav");
  try {
    const sonicboom::AudioClip clip = sonicboom::ReadWav(path);
    // what a reader returns is usable: finite samples, a positive rate
    if (!clip.samples.allFinite() || !(clip.sample_rate_hz > 0.0)) std::abort();
  } catch (const sonicboom::Error&) {
  }
  return 0;
}
