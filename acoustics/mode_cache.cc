// The on-disk mode cache: SolveShellModes' result stored bit for bit under a hash of the
// structure's key and the request, and read back when both come again.
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include <pwd.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

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

// the user's home in the passwd database, when it is a directory other than /
std::string PasswdHome() {
  struct passwd pw {};
  struct passwd* found = nullptr;
  std::vector<char> buf(16384);
  if (::getpwuid_r(::getuid(), &pw, buf.data(), buf.size(), &found) != 0 || found == nullptr ||
      pw.pw_dir == nullptr)
    return "";
  const std::string home = pw.pw_dir;
  std::error_code ec;
  const bool usable =
      home.size() > 1 && home.front() == '/' && std::filesystem::is_directory(home, ec);
  return usable ? home : "";
}

}  // namespace

uint64_t CacheKeyHash(const std::string& key) {
  return internal::Fnv1a(key.data(), key.size());
}

ModeCacheChoice ChooseModeCacheDir(const ModeCacheEnvironment& env) {
  namespace fs = std::filesystem;
  const fs::path below = fs::path("sonicboom") / "modes";
  if (!env.cache_dir.empty()) return {env.cache_dir, ""};
  if (fs::path(env.xdg_cache_home).is_absolute())
    return {(env.xdg_cache_home / below).string(), ""};
  if (!env.home.empty()) return {(fs::path(env.home) / ".cache" / below).string(), ""};
  const std::string set = "set SONICBOOM_CACHE_DIR (or acoustics.mode_cache_dir) to choose one";
  if (!env.passwd_home.empty()) {
    const std::string dir = (fs::path(env.passwd_home) / ".cache" / below).string();
    return {dir, fmt::format("HOME is unset: the mode cache is {} (the user's home in the "
                             "passwd database); {}",
                             dir, set)};
  }
  return {"", fmt::format("the mode cache is off: HOME is unset and the user has no home "
                          "directory, so every run solves its modes again (minutes); {}",
                          set)};
}

std::string DefaultModeCacheDir() {
  const auto env = [](const char* name) {
    const char* v = std::getenv(name);
    return std::string(v != nullptr ? v : "");
  };
  ModeCacheEnvironment e{env("SONICBOOM_CACHE_DIR"), env("XDG_CACHE_HOME"), env("HOME"), ""};
  if (e.cache_dir.empty() && e.home.empty()) e.passwd_home = PasswdHome();
  const ModeCacheChoice choice = ChooseModeCacheDir(e);
  static std::once_flag warned;
  if (!choice.warning.empty()) std::call_once(warned, [&] { spdlog::warn("{}", choice.warning); });
  return choice.dir;
}

namespace {

// the key CachedShellModes stores a request under (its file is named by the key's hash)
std::string ShellModesKey(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                          bool with_shapes) {
  return fmt::format("{} | band={:.17g} count={} shapes={}", model.key(), max_frequency_hz,
                     max_count, with_shapes);
}

}  // namespace

std::string ShellModesCachePath(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                                bool with_shapes, const std::string& cache_dir) {
  const std::string key = ShellModesKey(model, max_frequency_hz, max_count, with_shapes);
  return (std::filesystem::path(cache_dir) / fmt::format("modes-{:016x}.bin", CacheKeyHash(key)))
      .string();
}

ShellModes CachedShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                            bool with_shapes, const std::string& cache_dir, bool* hit) {
  if (hit != nullptr) *hit = false;
  if (cache_dir.empty()) return SolveShellModes(model, max_frequency_hz, max_count, with_shapes);
  const std::string key = ShellModesKey(model, max_frequency_hz, max_count, with_shapes);
  const std::string path =
      ShellModesCachePath(model, max_frequency_hz, max_count, with_shapes, cache_dir);
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
