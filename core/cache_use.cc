// A command's working set in the mode cache: spared by the budget while the command runs,
// pruned to the budget at its end (cache_use.h).
#include "sonicboom/core/cache_use.h"

#include <filesystem>
#include <mutex>
#include <set>

#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_dir.h"

namespace sonicboom::internal {
namespace {

// the process's working set: entries written or read, and the directories written to
struct WorkingSet {
  std::mutex mutex;
  bool sparing{false};
  std::set<std::string> entries;  // canonical-ish paths (lexically normal, absolute)
  std::set<std::string> dirs;
};

WorkingSet& Set() {
  static WorkingSet set;
  return set;
}

std::string Key(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  return (ec ? std::filesystem::path(path) : absolute).lexically_normal().string();
}

}  // namespace

void SpareThisProcessesCacheEntries() {
  const std::lock_guard<std::mutex> lock(Set().mutex);
  Set().sparing = true;
}

void NoteCacheEntryUse(const std::string& path) {
  WorkingSet& s = Set();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (s.sparing) s.entries.insert(Key(path));
}

bool IsSparedCacheEntry(const std::string& path) {
  WorkingSet& s = Set();
  const std::lock_guard<std::mutex> lock(s.mutex);
  return s.sparing && s.entries.count(Key(path)) > 0;
}

void NoteCacheDirWritten(const std::string& dir) {
  WorkingSet& s = Set();
  const std::lock_guard<std::mutex> lock(s.mutex);
  if (s.sparing) s.dirs.insert(dir);
}

void PruneSparedCachesToBudget() {
  std::set<std::string> dirs;
  {
    WorkingSet& s = Set();
    const std::lock_guard<std::mutex> lock(s.mutex);
    s.sparing = false;
    dirs.swap(s.dirs);
    s.entries.clear();
  }
  for (const std::string& dir : dirs) {
    try {
      KeepCacheWithinBudget(dir, "");
    } catch (const std::exception& e) {
      spdlog::warn("mode cache: cannot prune {}: {}", dir, e.what());
    }
  }
}

}  // namespace sonicboom::internal
