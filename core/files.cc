#include "sonicboom/core/files.h"

#include <algorithm>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom {

void WriteTextAtomic(const std::string& path, const std::string& text) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw IoError(fmt::format("{}: cannot write {}: {}", path, partial, std::strerror(errno)));
    }
    out << text;
    out.flush();
    const int err = errno;
    out.close();
    if (!out) {
      // a full disk: nothing half-written left behind, nothing under the final name
      std::error_code ec;
      std::filesystem::remove(partial, ec);
      throw IoError(fmt::format(
          "{}: write failed: {}", path,
          err == ENOSPC ? "no space left on device (the disk is full)" : std::strerror(err)));
    }
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) throw IoError(fmt::format("{}: cannot rename from {}: {}", path, partial, ec.message()));
}

std::string ReadText(const std::string& path) {
  RequireReadableFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot read", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void RequireReadableFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT) throw IoError(fmt::format("{}: no such file", path));
    throw IoError(fmt::format("{}: cannot be read: {}", path, std::strerror(err)));
  }
  if (S_ISDIR(st.st_mode)) throw IoError(fmt::format("{}: is a directory", path));
  if (!S_ISREG(st.st_mode)) {
    const char* kind = S_ISFIFO(st.st_mode)   ? "a FIFO"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "not a regular file";
    throw IoError(fmt::format("{}: is {}, not a regular file; refused before reading", path, kind));
  }
  if (::access(path.c_str(), R_OK) != 0) {
    throw IoError(fmt::format("{}: cannot be read: {}", path, std::strerror(errno)));
  }
}

void MakeDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) throw IoError(fmt::format("{}: cannot create directory: {}", path, ec.message()));
}

void ReplaceDirectory(const std::string& finished, const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string aside = path + ".replaced";
  if (fs::exists(path, ec)) {
    fs::remove_all(aside, ec);
    fs::rename(path, aside, ec);
    if (ec) throw IoError(fmt::format("{}: cannot move the old one aside: {}", path, ec.message()));
  }
  fs::rename(finished, path, ec);
  if (ec) {
    throw IoError(fmt::format("{}: cannot rename {} into place: {}", path, finished, ec.message()));
  }
  fs::remove_all(aside, ec);
  if (ec) throw IoError(fmt::format("{}: cannot remove the replaced run: {}", aside, ec.message()));
}

std::string UtcTimestamp() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y%m%d-%H%M%S", &tm);
  return buf;
}

// A lock file this process holds, and how many OutputLocks share it.
struct OutputLock::Held {
  std::string lock_path;
  int fd{-1};
  pid_t owner{-1};  // a forked child inherits the table, not the lock
  ~Held() {
    // unlinked while still locked: a process that opened it meanwhile finds it gone and retries
    ::unlink(lock_path.c_str());
    ::close(fd);
  }
};

namespace {

std::mutex held_mutex;
std::map<std::string, std::weak_ptr<OutputLock::Held>>& HeldLocks() {
  static std::map<std::string, std::weak_ptr<OutputLock::Held>> held;
  return held;
}

// the pid a holder wrote into its lock file, or "?"
std::string HolderPid(int fd) {
  char buffer[32] = {};
  const ssize_t n = ::pread(fd, buffer, sizeof(buffer) - 1, 0);
  return n > 0 ? std::string(buffer, static_cast<size_t>(n)) : std::string("?");
}

}  // namespace

std::filesystem::path ResolvedPath(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  if (ec) return path.lexically_normal();
  std::filesystem::path resolved = std::filesystem::weakly_canonical(absolute, ec);
  return ec ? absolute.lexically_normal() : resolved;
}

bool IsWithin(const std::filesystem::path& inner, const std::filesystem::path& outer) {
  const auto [o, i] = std::mismatch(outer.begin(), outer.end(), inner.begin(), inner.end());
  // "a/b/" spells its trailing separator as one empty part
  return o == outer.end() || (std::next(o) == outer.end() && o->empty());
}

OutputLock::OutputLock(const std::string& path) {
  const std::string lock_path = ResolvedPath(path).string() + ".lock";
  const std::lock_guard<std::mutex> guard(held_mutex);
  std::weak_ptr<Held>& entry = HeldLocks()[lock_path];
  if ((held_ = entry.lock()) && held_->owner == ::getpid()) return;  // this process holds it
  held_.reset();
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
      throw IoError(fmt::format("{}: cannot create the lock file {}: {}", path, lock_path,
                                std::strerror(errno)));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const std::string pid = HolderPid(fd);
      ::close(fd);
      throw IoError(
          fmt::format("{}: another process (pid {}) is writing it; wait for it to finish, or write "
                      "another output",
                      path, pid));
    }
    // the file locked must still be the one at the path (a releasing holder unlinks it)
    struct stat locked {};
    struct stat named {};
    if (::fstat(fd, &locked) != 0 || ::stat(lock_path.c_str(), &named) != 0 ||
        locked.st_ino != named.st_ino || locked.st_dev != named.st_dev) {
      ::close(fd);
      continue;
    }
    const std::string pid = std::to_string(::getpid());
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
      // the pid is only for messages; the lock holds without it
    }
    held_ = std::make_shared<Held>();
    held_->lock_path = lock_path;
    held_->fd = fd;
    held_->owner = ::getpid();
    entry = held_;
    return;
  }
  throw IoError(
      fmt::format("{}: cannot take the lock file {} (it keeps being replaced)", path, lock_path));
}

OutputLock::~OutputLock() {
  const std::lock_guard<std::mutex> guard(held_mutex);
  held_.reset();
}
OutputLock::OutputLock(OutputLock&&) noexcept = default;
OutputLock& OutputLock::operator=(OutputLock&&) noexcept = default;

}  // namespace sonicboom
