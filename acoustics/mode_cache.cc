// The on-disk mode cache: SolveShellModes' result stored bit for bit under a hash of the
// structure's key and the request, and read back when both come again.
#include <cstdlib>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/cache_file.h"

namespace sonicboom::acoustics {

namespace {

constexpr char kCacheMagic[8] = {'S', 'B', 'M', 'O', 'D', 'E', 'S', '2'};

// file layout (sonicboom/core/cache_file.h): header {rigid, modes, rows}, omega (modes), shapes
// (rows x modes), checksum
bool ReadModes(const std::string& path, const std::string& key, ShellModes* out) {
  internal::CacheFileReader in;
  int64_t header[3];
  if (!in.Open(path, kCacheMagic, key, header, 3)) return false;
  const bool sized = header[0] >= 0 && header[1] >= 0 && header[1] < (1 << 24) && header[2] >= 0 &&
                     header[2] < (1 << 28);
  if (sized) {
    out->rigid_body_modes = header[0];
    out->omega_rad_s.resize(header[1]);
    out->shapes.resize(header[2], header[2] > 0 ? header[1] : 0);
    in.Read(out->omega_rad_s.data(), sizeof(double) * out->omega_rad_s.size());
    in.Read(out->shapes.data(), sizeof(double) * out->shapes.size());
  }
  return in.Finish() && sized;
}

void WriteModes(const std::string& cache_dir, const std::string& path, const std::string& key,
                const ShellModes& modes) {
  internal::WriteCacheFile(cache_dir, path, kCacheMagic, key,
                           {modes.rigid_body_modes, modes.omega_rad_s.size(), modes.shapes.rows()},
                           {{modes.omega_rad_s.data(), sizeof(double) * modes.omega_rad_s.size()},
                            {modes.shapes.data(), sizeof(double) * modes.shapes.size()}});
}

}  // namespace

uint64_t CacheKeyHash(const std::string& key) {
  return internal::Fnv1a(key.data(), key.size());
}

std::string DefaultModeCacheDir() {
  if (const char* dir = std::getenv("SONICBOOM_CACHE_DIR"); dir != nullptr && *dir != '\0')
    return dir;
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return (std::filesystem::path(home) / ".cache" / "sonicboom" / "modes").string();
  }
  return "";
}

ShellModes CachedShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                            bool with_shapes, const std::string& cache_dir, bool* hit) {
  if (hit != nullptr) *hit = false;
  if (cache_dir.empty()) return SolveShellModes(model, max_frequency_hz, max_count, with_shapes);
  const std::string key = fmt::format("{} | band={:.17g} count={} shapes={}", model.key(),
                                      max_frequency_hz, max_count, with_shapes);
  const std::string path =
      (std::filesystem::path(cache_dir) / fmt::format("modes-{:016x}.bin", CacheKeyHash(key)))
          .string();
  ShellModes modes;
  if (ReadModes(path, key, &modes)) {
    if (hit != nullptr) *hit = true;
    return modes;
  }
  modes = SolveShellModes(model, max_frequency_hz, max_count, with_shapes);
  WriteModes(cache_dir, path, key, modes);
  return modes;
}

}  // namespace sonicboom::acoustics
