#pragma once
// The input of a fuzz target as a file: the readers under test take paths, as the CLI does.
// One scratch file per process, rewritten for every input.

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace sonicboom::fuzz {

inline const std::string& ScratchPath(const char* suffix) {
  static const std::string path = [&] {
    const char* dir = std::getenv("TMPDIR");
    return std::string(dir != nullptr && *dir != '\0' ? dir : "/tmp") + "/sonicboom_fuzz_" +
           std::to_string(getpid()) + suffix;
  }();
  return path;
}

// Writes the input to the scratch file and returns its path.
inline const std::string& AsFile(const uint8_t* data, size_t size, const char* suffix) {
  const std::string& path = ScratchPath(suffix);
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  return path;
}

}  // namespace sonicboom::fuzz
