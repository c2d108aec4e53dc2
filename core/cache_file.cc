#include "sonicboom/core/cache_file.h"

#include <cstring>
#include <filesystem>
#include <system_error>

#include <spdlog/spdlog.h>

namespace sonicboom::internal {

uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

bool OpenCacheFile(const std::string& path, const char (&magic)[8], const std::string& key,
                   int64_t* header, size_t header_count, std::ifstream* in) {
  in->open(path, std::ios::binary);
  if (!*in) return false;
  // magic and key length, then the key itself
  char stored_magic[8];
  uint64_t key_size = 0;
  in->read(stored_magic, 8);
  in->read(reinterpret_cast<char*>(&key_size), sizeof key_size);
  if (!*in || std::memcmp(stored_magic, magic, 8) != 0 || key_size != key.size()) return false;
  std::string stored(key_size, '\0');
  in->read(stored.data(), static_cast<std::streamsize>(key_size));
  in->read(reinterpret_cast<char*>(header),
           static_cast<std::streamsize>(sizeof(int64_t) * header_count));
  return static_cast<bool>(*in) && stored == key;
}

bool ReadCacheBlock(std::ifstream& in, void* data, size_t bytes, bool last) {
  in.read(static_cast<char*>(data), static_cast<std::streamsize>(bytes));
  if (!in) return false;
  return !last || in.peek() == std::char_traits<char>::eof();
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
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    const uint64_t key_size = key.size();
    out.write(magic, 8);
    out.write(reinterpret_cast<const char*>(&key_size), sizeof key_size);
    out.write(key.data(), static_cast<std::streamsize>(key.size()));
    out.write(reinterpret_cast<const char*>(header.data()),
              static_cast<std::streamsize>(sizeof(int64_t) * header.size()));
    for (const CacheBlock& b : blocks) {
      out.write(static_cast<const char*>(b.data), static_cast<std::streamsize>(b.bytes));
    }
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
