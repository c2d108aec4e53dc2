#pragma once
// The mode caches' file format (the shell's base modes and Ritz variants, the reference solid's
// modes): an 8-byte magic, the key (its length,
// then its bytes), an int64 header, then raw arrays. A file is written to PATH.partial and renamed
// into place, so a reader never sees half a file; a failed write only warns (the cache saves
// time, it is never needed).

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace sonicboom::internal {

/// FNV-1a over `bytes` bytes, continuing from `h` (chain calls to hash several pieces): the hash
/// that names cache files and checksums their contents.
uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h = 1469598103934665603ull);

/// Opens `path` and reads past its magic, key and `header_count` header values into `header`;
/// false when the file is absent, truncated, of another kind or made for another key.
bool OpenCacheFile(const std::string& path, const char (&magic)[8], const std::string& key,
                   int64_t* header, size_t header_count, std::ifstream* in);

/// Reads `bytes` raw bytes into `data`; with `last`, also requires the file to end there.
bool ReadCacheBlock(std::ifstream& in, void* data, size_t bytes, bool last);

/// One raw array of a cache file.
struct CacheBlock {
  const void* data;
  size_t bytes;
};

/// Writes `path` (in `cache_dir`, created when missing) atomically: magic, key, header, blocks.
void WriteCacheFile(const std::string& cache_dir, const std::string& path, const char (&magic)[8],
                    const std::string& key, const std::vector<int64_t>& header,
                    const std::vector<CacheBlock>& blocks);

}  // namespace sonicboom::internal
