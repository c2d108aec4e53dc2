#pragma once
/// Small file helpers shared by every writer: atomic text files and checked reads.

#include <string>

namespace sonicboom {

/// Writes `text` (any bytes: the file is opened in binary mode) to "<path>.partial" and renames it
/// to `path`. Throws IoError naming the path.
void WriteTextAtomic(const std::string& path, const std::string& text);
/// Reads a whole text file. Throws IoError naming the path when missing or unreadable.
std::string ReadText(const std::string& path);
/// Creates a directory (and parents). Throws IoError naming it on failure.
void MakeDirectories(const std::string& path);
/// Puts a finished directory `finished` in the place of `path`: an existing `path` is renamed
/// aside (to "<path>.replaced"), `finished` renamed to `path`, then the old one removed; a
/// reader never meets a half-written directory under `path`. Throws IoError naming the paths.
void ReplaceDirectory(const std::string& finished, const std::string& path);
/// Current UTC time as YYYYmmdd-HHMMSS.
std::string UtcTimestamp();

}  // namespace sonicboom
