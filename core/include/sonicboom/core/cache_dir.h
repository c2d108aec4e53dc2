#pragma once
/// A mode cache directory as a whole: its entries, the budget they are kept within, and pruning
/// least recently used first. An entry's last use is its modification time (written, or touched
/// by each read: CacheFileReader). A reader holds a shared flock on the entry while it reads; a
/// pruner removes only an entry it can lock exclusively, so an entry being read stays.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sonicboom::internal {

/// The budget's variable and its default (1 GB); 0 = no cap.
inline constexpr const char* kCacheBudgetVariable = "SONICBOOM_CACHE_MAX_BYTES";
inline constexpr uint64_t kDefaultCacheBudgetBytes = 1000000000;

/// A cache file of a directory (modes-, ritz-, reference- or level-HASH.bin), or a temp file a
/// writer left (HASH.bin.partial.PID.THREAD).
struct CacheEntry {
  std::string path;
  std::string name;  // the file's name
  std::string kind;  // modes, ritz, reference or level
  uint64_t bytes{0};
  int64_t last_use_ns{0};  // its modification time, since the epoch
  bool partial{false};     // a writer's temp file
  bool stale{false};       // a temp file whose writer is gone (no such pid, or a day old)
  bool regular{true};      // false: a FIFO, device or socket under an entry's name (damaged)
};

/// A size in bytes: a plain number, optionally with k, M, G or T (powers of 1000) or Ki, Mi,
/// Gi, Ti (of 1024), in either case, and an optional B ("1G", "500MB", "2GiB", "1000000");
/// nullopt otherwise (a sign, an exponent, hex, blanks, another unit).
std::optional<uint64_t> ParseByteSize(const std::string& text);
/// A size for people: "512 B", "78.0 MB", "1.00 GB".
std::string FormatBytes(uint64_t bytes);
/// $SONICBOOM_CACHE_MAX_BYTES, else 1 GB; 0 = no cap. ConfigError naming the variable and its
/// value when it is not a size.
uint64_t CacheBudgetBytes();

/// The entries of `dir`, least recently used first; nothing else of `dir` is listed. Empty when
/// `dir` does not exist.
std::vector<CacheEntry> ListCacheEntries(const std::string& dir);

/// What PruneCache did.
struct CachePruned {
  int64_t removed{0};
  uint64_t removed_bytes{0};
  int64_t in_use{0};  // over the cap, but being read: kept
  int64_t kept{0};
  uint64_t kept_bytes{0};
};
/// Removes the entries of `dir`, least recently used first, until the rest fit in `max_bytes`
/// (0: every one), besides damaged names and stale temp files; never `keep` (a path in `dir`),
/// an entry being read or a temp file being written. The first removal that failed (a read-only
/// directory) is put in `error` when given.
CachePruned PruneCache(const std::string& dir, uint64_t max_bytes, const std::string& keep = "",
                       std::string* error = nullptr);
/// Marks the entry at `path` used now (its modification time); nothing when it is missing or
/// read-only.
void TouchCacheEntry(const std::string& path);
/// After `written` was put into `dir`: prunes `dir` to CacheBudgetBytes() (a bad variable warns
/// and keeps the default), logging what it removed.
void KeepCacheWithinBudget(const std::string& dir, const std::string& written);

}  // namespace sonicboom::internal
