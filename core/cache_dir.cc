#include "sonicboom/core/cache_dir.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <system_error>
#include <tuple>
#include <utility>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_use.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::internal {
namespace {

namespace fs = std::filesystem;

// a writer's temp file older than this is left over, whatever its pid says
constexpr int64_t kStaleTempS = 86400;

bool IsHex(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) || (c >= 'a' && c <= 'f');
  });
}

bool IsDigits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c));
  });
}

// KIND-HASH.bin (kind and partial set) or its temp file KIND-HASH.bin.partial.PID.THREAD (pid
// set); false for any other name
bool ParseEntryName(const std::string& name, CacheEntry* e, long* pid) {
  for (const char* kind : {"modes", "ritz", "reference", "level"}) {
    const std::string prefix = std::string(kind) + "-";
    if (name.rfind(prefix, 0) != 0 || name.size() < prefix.size() + 20) continue;
    if (!IsHex(name.substr(prefix.size(), 16)) || name.compare(prefix.size() + 16, 4, ".bin"))
      return false;
    e->kind = kind;
    const std::string rest = name.substr(prefix.size() + 20);
    if (rest.empty()) return true;
    // .partial.PID.THREAD
    const size_t dot = rest.find('.', 9);
    if (rest.rfind(".partial.", 0) != 0 || dot == std::string::npos ||
        !IsDigits(rest.substr(9, dot - 9)) || !IsHex(rest.substr(dot + 1)))
      return false;
    e->partial = true;
    *pid = std::strtol(rest.c_str() + 9, nullptr, 10);
    return true;
  }
  return false;
}

// a temp file whose writer is gone: no such process, or a day old (another host's, a reused pid)
bool StaleTemp(long pid, int64_t mtime_s) {
  if (std::time(nullptr) - mtime_s > kStaleTempS) return true;
  return pid != static_cast<long>(::getpid()) && ::kill(static_cast<pid_t>(pid), 0) != 0 &&
         errno == ESRCH;
}

enum class Removal { kRemoved, kInUse, kGone, kFailed };

// unlinks `path` unless a reader holds its lock (CacheFileReader); its error in *error
Removal RemoveUnlessInUse(const std::string& path, bool lock_first, std::string* error) {
  const int fd = lock_first ? ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC) : -1;
  if (fd < 0 && lock_first && errno == ENOENT) return Removal::kGone;
  if (fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return Removal::kInUse;
  }
  const int rc = ::unlink(path.c_str());
  const int err = errno;
  if (fd >= 0) ::close(fd);
  if (rc == 0) return Removal::kRemoved;
  if (err == ENOENT) return Removal::kGone;
  if (error != nullptr && error->empty())
    *error = fmt::format("cannot remove {}: {}", path, std::strerror(err));
  return Removal::kFailed;
}

}  // namespace

std::optional<uint64_t> ParseByteSize(const std::string& text) {
  const size_t digits = text.find_first_not_of("0123456789.");
  const std::string number = text.substr(0, digits);
  std::string unit = digits == std::string::npos ? "" : text.substr(digits);
  if (number.empty() || number.front() == '.' || number.back() == '.' ||
      std::count(number.begin(), number.end(), '.') > 1)
    return std::nullopt;
  // the unit in either case, with or without its B
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
  for (char& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  static const std::pair<const char*, double> kUnits[] = {
      {"", 1.0},         {"K", 1e3},           {"M", 1e6},
      {"G", 1e9},        {"T", 1e12},          {"KI", 1024.0},
      {"MI", 1048576.0}, {"GI", 1073741824.0}, {"TI", 1099511627776.0}};
  for (const auto& [name, scale] : kUnits) {
    if (unit != name) continue;
    const double v = std::strtod(number.c_str(), nullptr) * scale;
    if (!(v <= 9.2e18)) return std::nullopt;
    return static_cast<uint64_t>(std::llround(v));
  }
  return std::nullopt;
}

std::string FormatBytes(uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (bytes < 1000) return fmt::format("{} B", bytes);
  if (bytes < 1000000) return fmt::format("{:.1f} kB", b / 1e3);
  if (bytes < 1000000000) return fmt::format("{:.1f} MB", b / 1e6);
  return fmt::format("{:.2f} GB", b / 1e9);
}

uint64_t CacheBudgetBytes() {
  const char* env = std::getenv(kCacheBudgetVariable);
  if (env == nullptr || *env == '\0') return kDefaultCacheBudgetBytes;
  if (const std::optional<uint64_t> v = ParseByteSize(env)) return *v;
  throw ConfigError(fmt::format(
      "{} = '{}': expected a size in bytes such as 1000000000, 500M or 2G (k, M, G, T: powers "
      "of 1000; Ki, Mi, Gi, Ti: of 1024), or 0 for no cap",
      kCacheBudgetVariable, env));
}

std::vector<CacheEntry> ListCacheEntries(const std::string& dir) {
  std::vector<CacheEntry> entries;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    CacheEntry e;
    long pid = 0;
    e.name = it->path().filename().string();
    e.path = it->path().string();
    struct stat st {};
    if (!ParseEntryName(e.name, &e, &pid) || ::stat(e.path.c_str(), &st) != 0 ||
        S_ISDIR(st.st_mode))
      continue;
    e.regular = S_ISREG(st.st_mode);
    e.bytes = e.regular ? static_cast<uint64_t>(st.st_size) : 0;
    e.last_use_ns = int64_t{st.st_mtim.tv_sec} * 1000000000 + st.st_mtim.tv_nsec;
    e.stale = e.partial && StaleTemp(pid, st.st_mtim.tv_sec);
    entries.push_back(std::move(e));
  }
  std::sort(entries.begin(), entries.end(), [](const CacheEntry& a, const CacheEntry& b) {
    return std::tie(a.last_use_ns, a.name) < std::tie(b.last_use_ns, b.name);
  });
  return entries;
}

CachePruned PruneCache(const std::string& dir, uint64_t max_bytes, const std::string& keep,
                       std::string* error) {
  const std::string keep_name = keep.empty() ? "" : fs::path(keep).filename().string();
  const std::vector<CacheEntry> entries = ListCacheEntries(dir);
  uint64_t total = 0;
  for (const CacheEntry& e : entries) total += e.partial ? 0 : e.bytes;
  CachePruned r;
  for (const CacheEntry& e : entries) {
    // counted: a cache file (not a temp file, not a damaged name)
    const bool counted = e.regular && !e.partial;
    const bool over = counted && (max_bytes == 0 || total > max_bytes);
    // the running command's working set stays until its end (cache_use.h)
    const bool spared = counted && IsSparedCacheEntry(e.path);
    if (e.name == keep_name || spared || (!over && e.regular && !e.stale)) {
      if (counted) ++r.kept, r.kept_bytes += e.bytes;
      continue;
    }
    const Removal removal = RemoveUnlessInUse(e.path, counted, error);
    if (removal == Removal::kRemoved) ++r.removed, r.removed_bytes += e.bytes;
    if (removal == Removal::kInUse) ++r.in_use;
    if (!counted) continue;
    if (removal == Removal::kRemoved || removal == Removal::kGone) {
      total -= e.bytes;
    } else {
      ++r.kept, r.kept_bytes += e.bytes;
    }
  }
  return r;
}

void TouchCacheEntry(const std::string& path) {
  ::utimensat(AT_FDCWD, path.c_str(), nullptr, 0);
  NoteCacheEntryUse(path);
}

void KeepCacheWithinBudget(const std::string& dir, const std::string& written) {
  uint64_t budget = kDefaultCacheBudgetBytes;
  try {
    budget = CacheBudgetBytes();
  } catch (const ConfigError& e) {
    spdlog::warn("mode cache: {}; keeping {} within the default {}", e.what(), dir,
                 FormatBytes(budget));
  }
  if (budget == 0) return;
  if (!written.empty()) {
    NoteCacheEntryUse(written);
    NoteCacheDirWritten(dir);
  }
  const CachePruned p = PruneCache(dir, budget, written);
  if (p.removed > 0) {
    spdlog::info(
        "mode cache: removed {} least recently used file(s) ({}) to keep {} within its "
        "budget of {} ({})",
        p.removed, FormatBytes(p.removed_bytes), dir, FormatBytes(budget), kCacheBudgetVariable);
  }
  if (p.kept_bytes > budget && !IsSparedCacheEntry(written)) {
    spdlog::info(
        "mode cache: {} holds {}, over its budget of {} ({}): the entry just written{} "
        "kept",
        dir, FormatBytes(p.kept_bytes), FormatBytes(budget), kCacheBudgetVariable,
        p.in_use > 0 ? fmt::format(" and {} being read are", p.in_use) : " is");
  }
}

}  // namespace sonicboom::internal
