#pragma once
/// A command's working set in the mode cache. A command that reads again what it wrote (the
/// randomized structure pool: built for a training set, read for its test set) would evict it
/// under a budget smaller than that set and build it twice; with sparing on (the CLI turns it on
/// for each command), the budget's pruning during the command leaves every entry the command
/// wrote or read, and the command's end prunes the directories it wrote to down to the budget.

#include <string>

namespace sonicboom::internal {

/// Turns sparing on for the rest of this process (until PruneSparedCachesToBudget).
void SpareThisProcessesCacheEntries();
/// Records that this process wrote or read the entry at `path` (nothing while sparing is off).
void NoteCacheEntryUse(const std::string& path);
/// True when sparing is on and this process wrote or read `path`.
bool IsSparedCacheEntry(const std::string& path);
/// Records a directory this process wrote an entry to (nothing while sparing is off).
void NoteCacheDirWritten(const std::string& dir);
/// Turns sparing off and prunes every directory this process wrote to down to the budget
/// (KeepCacheWithinBudget); never throws.
void PruneSparedCachesToBudget();

}  // namespace sonicboom::internal
