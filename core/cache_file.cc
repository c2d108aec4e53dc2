#include "sonicboom/core/cache_file.h"

#include <cstring>
#include <filesystem>
#include <system_error>
#include <thread>

#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace sonicboom::internal {

uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

bool CacheFileReader::Open(const std::string& path, const char (&magic)[8], const std::string& key,
                           int64_t* header, size_t header_count) {
  path_ = path;
  in_.open(path, std::ios::binary);
  if (!in_) return false;
  // magic and key length, then the key itself
  char stored_magic[8];
  uint64_t key_size = 0;
  in_.read(stored_magic, 8);
  in_.read(reinterpret_cast<char*>(&key_size), sizeof key_size);
  if (!in_ || std::memcmp(stored_magic, magic, 8) != 0 || key_size != key.size()) return false;
  std::string stored(key_size, '\0');
  in_.read(stored.data(), static_cast<std::streamsize>(key_size));
  const size_t header_bytes = sizeof(int64_t) * header_count;
  in_.read(reinterpret_cast<char*>(header), static_cast<std::streamsize>(header_bytes));
  if (!in_ || stored != key) return false;
  hash_ = Fnv1a(header, header_bytes);
  return true;
}

bool CacheFileReader::Read(void* data, size_t bytes) {
  if (failed_) return false;
  in_.read(static_cast<char*>(data), static_cast<std::streamsize>(bytes));
  failed_ = !in_;
  if (!failed_) hash_ = Fnv1a(data, bytes, hash_);
  return !failed_;
}

bool CacheFileReader::Finish() {
  // the checksum itself is not part of what it sums
  uint64_t stored = 0;
  if (!failed_) in_.read(reinterpret_cast<char*>(&stored), sizeof stored);
  const bool ok = !failed_ && in_ && stored == hash_ && in_.peek() == std::char_traits<char>::eof();
  if (!ok) spdlog::warn("mode cache: {} is damaged or incomplete; solving again", path_);
  return ok;
}

void WriteCacheFile(const std::string& cache_dir, const std::string& path, const char (&magic)[8],
                    const std::string& key, const std::vector<int64_t>& header,
                    const std::vector<CacheBlock>& blocks) {
  std::error_code ec;
  std::filesystem::create_directories(cache_dir, ec);
  if (ec) {
    spdlog::warn("mode cache: cannot create {}: {}; continuing without it", cache_dir,
                 ec.message());
    return;
  }
  // a writer's own temp file: two processes (or threads) solving one key at once each write
  // theirs whole, and the last rename wins with a complete file
  const std::string partial = fmt::format("{}.partial.{}.{:x}", path, static_cast<long>(::getpid()),
                                          std::hash<std::thread::id>{}(std::this_thread::get_id()));
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    const uint64_t key_size = key.size();
    out.write(magic, 8);
    out.write(reinterpret_cast<const char*>(&key_size), sizeof key_size);
    out.write(key.data(), static_cast<std::streamsize>(key.size()));
    out.write(reinterpret_cast<const char*>(header.data()),
              static_cast<std::streamsize>(sizeof(int64_t) * header.size()));
    uint64_t hash = Fnv1a(header.data(), sizeof(int64_t) * header.size());
    for (const CacheBlock& b : blocks) {
      out.write(static_cast<const char*>(b.data), static_cast<std::streamsize>(b.bytes));
      hash = Fnv1a(b.data, b.bytes, hash);
    }
    out.write(reinterpret_cast<const char*>(&hash), sizeof hash);
    if (!out) {
      spdlog::warn("mode cache: cannot write {}; continuing without it", partial);
      std::filesystem::remove(partial, ec);
      return;
    }
  }
  std::filesystem::rename(partial, path, ec);
  if (ec) spdlog::warn("mode cache: cannot rename {} to {}: {}", partial, path, ec.message());
}

}  // namespace sonicboom::internal
