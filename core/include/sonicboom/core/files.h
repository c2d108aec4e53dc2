#pragma once
/// Small file helpers shared by every writer: atomic text files and checked reads.

#include <filesystem>
#include <memory>
#include <string>

namespace sonicboom {

/// Writes `text` (any bytes: the file is opened in binary mode) to "<path>.partial" and renames it
/// to `path`. Throws IoError naming the path.
void WriteTextAtomic(const std::string& path, const std::string& text);
/// Reads a whole text file. Throws IoError naming the path when missing or unreadable.
std::string ReadText(const std::string& path);
/// IoError unless `path` (links followed) is a regular file this process may read: names the
/// path and why (missing, a directory, a FIFO, device or socket, permission denied, a link loop,
/// a name too long). Every reader of a user's file calls it before opening, so that a FIFO
/// never blocks a read and a device never feeds one endlessly.
void RequireReadableFile(const std::string& path);
/// An absolute path with every existing part resolved (links, "..", other spellings), so that two
/// spellings of one file compare equal; the lexically normal absolute path where resolution fails.
std::filesystem::path ResolvedPath(const std::filesystem::path& path);
/// Whether `inner` is `outer` or lies below it (compare resolved paths).
bool IsWithin(const std::filesystem::path& inner, const std::filesystem::path& outer);
/// Creates a directory (and parents). Throws IoError naming it on failure.
void MakeDirectories(const std::string& path);
/// Puts a finished directory `finished` in the place of `path`: an existing `path` is renamed
/// aside (to "<path>.replaced"), `finished` renamed to `path`, then the old one removed; a
/// reader never meets a half-written directory under `path`. Throws IoError naming the paths.
void ReplaceDirectory(const std::string& finished, const std::string& path);
/// The one writer of an output: an exclusive lock on "<path>.lock" (flock), held while the object
/// lives and shared by every OutputLock of the same path in this process. A second process that
/// asks for it gets IoError naming the path and the holder's pid, so that two commands writing
/// one output never delete or interleave each other's work. The lock file is removed on release;
/// one left by a killed process holds no lock and is taken over.
class OutputLock {
 public:
  explicit OutputLock(const std::string& path);
  ~OutputLock();
  OutputLock(OutputLock&&) noexcept;
  OutputLock& operator=(OutputLock&&) noexcept;

  struct Held;

 private:
  std::shared_ptr<Held> held_;
};

/// Current UTC time as YYYYmmdd-HHMMSS.
std::string UtcTimestamp();

}  // namespace sonicboom
