#include "sonicboom/core/files.h"

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom {

void WriteTextAtomic(const std::string& path, const std::string& text) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError(fmt::format("{}: cannot write (does its directory exist?)", path));
    out << text;
    out.flush();
    if (!out) throw IoError(fmt::format("{}: write failed", path));
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) throw IoError(fmt::format("{}: cannot rename from {}: {}", path, partial, ec.message()));
}

std::string ReadText(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IoError(fmt::format("{}: no such file", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot read", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
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

}  // namespace sonicboom
