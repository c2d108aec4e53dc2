#include "sonicboom/core/cache_file.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <thread>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_dir.h"
#include "sonicboom/core/cache_use.h"

namespace sonicboom::internal {
namespace {

const char* FileKindName(mode_t mode) {
  return S_ISDIR(mode)    ? "a directory"
         : S_ISFIFO(mode) ? "a FIFO"
         : S_ISCHR(mode)  ? "a character device"
         : S_ISBLK(mode)  ? "a block device"
         : S_ISSOCK(mode) ? "a socket"
                          : "something else";
}

}  // namespace

uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

CacheFileReader::~CacheFileReader() {
  Close();
}

void CacheFileReader::Close() {
  if (file_ != nullptr) std::fclose(file_);  // releases the shared lock
  file_ = nullptr;
}

// opens path_ when it is a regular file, locked shared and touched; a FIFO, device, socket or
// directory under an entry's name is damaged: warned about and never opened for reading
bool CacheFileReader::OpenRegular() {
  struct stat st {};
  if (::stat(path_.c_str(), &st) != 0) {
    if (errno != ENOENT)
      spdlog::warn("mode cache: cannot read {}: {}; solving again", path_, std::strerror(errno));
    return false;
  }
  // O_NONBLOCK: a FIFO put there between the stat and the open does not block it either
  int fd = S_ISREG(st.st_mode) ? ::open(path_.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC) : -1;
  const int open_errno = errno;
  if (fd >= 0 && (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))) {
    ::close(fd);
    fd = -1;
  }
  if (!S_ISREG(st.st_mode)) {
    spdlog::warn("mode cache: {} is {}, not a regular file; solving again", path_,
                 FileKindName(st.st_mode));
    return false;
  }
  if (fd < 0) {
    spdlog::warn("mode cache: cannot read {}: {}; solving again", path_, std::strerror(open_errno));
    return false;
  }
  // an exclusive lock is a pruner removing the file: a miss, as if it were gone
  if (::flock(fd, LOCK_SH | LOCK_NB) != 0) {
    ::close(fd);
    return false;
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  ::futimens(fd, nullptr);  // its last use; a read-only cache keeps its old time
  NoteCacheEntryUse(path_);  // in the running command's working set
  file_ = ::fdopen(fd, "rb");
  if (file_ == nullptr) ::close(fd);
  return file_ != nullptr;
}

bool CacheFileReader::ReadRaw(void* data, size_t bytes) {
  return file_ != nullptr && std::fread(data, 1, bytes, file_) == bytes;
}

bool CacheFileReader::Open(const std::string& path, const char (&magic)[8], const std::string& key,
                           int64_t* header, size_t header_count) {
  Close();
  path_ = path;
  failed_ = false;
  if (!OpenRegular()) return false;
  // magic and key length, then the key itself
  char stored_magic[8];
  uint64_t key_size = 0;
  if (!ReadRaw(stored_magic, 8) || !ReadRaw(&key_size, sizeof key_size) ||
      std::memcmp(stored_magic, magic, 8) != 0 || key_size != key.size()) {
    Close();
    return false;
  }
  std::string stored(key_size, '\0');
  const size_t header_bytes = sizeof(int64_t) * header_count;
  if (!ReadRaw(stored.data(), key_size) || !ReadRaw(header, header_bytes) || stored != key) {
    Close();
    return false;
  }
  hash_ = Fnv1a(header, header_bytes);
  return true;
}

bool CacheFileReader::Read(void* data, size_t bytes) {
  if (failed_) return false;
  failed_ = !ReadRaw(data, bytes);
  if (!failed_) hash_ = Fnv1a(data, bytes, hash_);
  return !failed_;
}

bool CacheFileReader::Finish() {
  // the checksum itself is not part of what it sums
  uint64_t stored = 0;
  const bool ok =
      !failed_ && ReadRaw(&stored, sizeof stored) && stored == hash_ && std::fgetc(file_) == EOF;
  Close();
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
  if (ec) {
    spdlog::warn("mode cache: cannot rename {} to {}: {}", partial, path, ec.message());
    std::filesystem::remove(partial, ec);
    return;
  }
  KeepCacheWithinBudget(cache_dir, path);
}

}  // namespace sonicboom::internal
