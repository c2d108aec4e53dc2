#pragma once
// The mode caches' file format (the shell's base modes and Ritz variants, the reference solid's
// modes): an 8-byte magic, the key (its length, then its bytes), an int64 header, raw arrays, and
// a checksum of the header and the arrays. A file is written to a temp file of its writer's own
// (PATH.partial.<pid>.<thread>) and renamed into place, so a reader never sees half a file, nor
// one writer another's; a failed write only warns (the cache saves time, it is never needed).
// Each write keeps the directory within its budget (sonicboom/core/cache_dir.h).

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace sonicboom::internal {

/// FNV-1a over `bytes` bytes, continuing from `h` (chain calls to hash several pieces): the hash
/// that names cache files and checksums their contents.
uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h = 1469598103934665603ull);

/// A cache file being read. Every header value and block read joins a running FNV-1a, which
/// Finish compares with the checksum the writer put last: a damaged file is found, not used.
/// While open it holds a shared lock on the file (a pruner keeps an entry being read) and it has
/// touched the file's modification time (its last use, for least-recently-used pruning).
class CacheFileReader {
 public:
  CacheFileReader() = default;
  ~CacheFileReader();
  CacheFileReader(const CacheFileReader&) = delete;
  CacheFileReader& operator=(const CacheFileReader&) = delete;

  /// Opens `path` and reads its magic, key and `header_count` header values into `header`; false
  /// when the file is absent, truncated, of another kind or made for another key (nothing to
  /// warn about: the caller solves and writes it). Something other than a regular file under the
  /// name (a FIFO blocked the read forever, a device fed it endlessly) or a file it may not read
  /// is named in a warning and never opened for reading: false, solved again and replaced.
  bool Open(const std::string& path, const char (&magic)[8], const std::string& key,
            int64_t* header, size_t header_count);
  /// Reads `bytes` raw bytes into `data`; false (and remembered) past the end of the file.
  bool Read(void* data, size_t bytes);
  /// True when every read held, the checksum matches and the file ends there. Otherwise warns
  /// that the file (named) is damaged and will be solved again, and returns false. Closes it.
  bool Finish();

 private:
  bool OpenRegular();
  bool ReadRaw(void* data, size_t bytes);
  void Close();

  std::string path_;
  std::FILE* file_{nullptr};
  uint64_t hash_{0};
  bool failed_{false};
};

/// One raw array of a cache file.
struct CacheBlock {
  const void* data;
  size_t bytes;
};

/// Writes `path` (in `cache_dir`, created when missing) atomically: magic, key, header, blocks,
/// and last the FNV-1a checksum of the header and the blocks.
void WriteCacheFile(const std::string& cache_dir, const std::string& path, const char (&magic)[8],
                    const std::string& key, const std::vector<int64_t>& header,
                    const std::vector<CacheBlock>& blocks);

}  // namespace sonicboom::internal
