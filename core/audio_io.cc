#include "sonicboom/core/audio_io.h"

#include <fmt/format.h>
#include <sndfile.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <system_error>
#include <vector>

#include "sonicboom/core/errors.h"

namespace sonicboom {

namespace {

namespace fs = std::filesystem;

// Closes a SNDFILE on scope exit.
class SndFile {
 public:
  SndFile(SNDFILE* file) : file_(file) {}
  ~SndFile() { Close(); }
  SndFile(const SndFile&) = delete;
  SndFile& operator=(const SndFile&) = delete;
  SNDFILE* get() const { return file_; }
  // Returns libsndfile's error code (0 = success).
  int Close() {
    int rc = 0;
    if (file_ != nullptr) rc = sf_close(file_);
    file_ = nullptr;
    return rc;
  }

 private:
  SNDFILE* file_;
};

uint32_t ReadLe32(const unsigned char* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

// Walks the chunks of a RIFF/WAVE file (file_bytes long) and returns a description of the
// problem when the data chunk, or a chunk before it, declares more bytes than the file holds;
// an empty string when the layout is complete or the file is not plain RIFF/WAVE.
std::string RiffTruncation(const std::string& path, uintmax_t file_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::array<unsigned char, 12> header{};
  if (!in.read(reinterpret_cast<char*>(header.data()), header.size())) return "";
  if (std::memcmp(header.data(), "RIFF", 4) != 0 ||
      std::memcmp(header.data() + 8, "WAVE", 4) != 0) {
    return "";
  }
  uintmax_t offset = 12;
  while (offset + 8 <= file_bytes) {
    std::array<unsigned char, 8> chunk{};
    in.seekg(static_cast<std::streamoff>(offset));
    if (!in.read(reinterpret_cast<char*>(chunk.data()), chunk.size())) return "";
    const uintmax_t size = ReadLe32(chunk.data() + 4);
    const uintmax_t available = file_bytes - (offset + 8);
    const std::string_view id(reinterpret_cast<const char*>(chunk.data()), 4);
    if (id == "data") {
      if (size > available) {
        return fmt::format("data chunk declares {} bytes, file holds {}", size, available);
      }
      return "";
    }
    if (size > available) {
      return fmt::format("'{}' chunk declares {} bytes, file holds {}", id, size, available);
    }
    // Chunks are padded to an even size.
    offset += 8 + size + (size & 1u);
  }
  return "no data chunk before end of file";
}

// libsndfile's own diagnosis: its header log reports "data : N (should be M)" when the data
// chunk is longer than the file (covers containers other than plain RIFF/WAVE).
bool LogReportsShortData(SNDFILE* file) {
  std::vector<char> log(16384, '\0');
  sf_command(file, SFC_GET_LOG_INFO, log.data(), static_cast<int>(log.size()));
  std::string_view text(log.data());
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    if (line.substr(0, 4) == "data" && line.find("should be") != std::string_view::npos) {
      return true;
    }
    pos = end + 1;
  }
  return false;
}

}  // namespace

AudioClip ReadWav(const std::string& path, int expected_channels) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw IoError(fmt::format("{}: no such file", path));
  if (!fs::is_regular_file(path, ec)) throw IoError(fmt::format("{}: not a regular file", path));
  const uintmax_t file_bytes = fs::file_size(path, ec);
  if (ec) throw IoError(fmt::format("{}: cannot read size: {}", path, ec.message()));

  SF_INFO info{};
  SndFile file(sf_open(path.c_str(), SFM_READ, &info));
  if (file.get() == nullptr) {
    throw IoError(fmt::format("{}: not a readable sound file ({})", path, sf_strerror(nullptr)));
  }

  // libsndfile opens a truncated WAV silently with fewer frames, so check the header against
  // the file length.
  const std::string riff_problem = RiffTruncation(path, file_bytes);
  if (!riff_problem.empty()) {
    throw IoError(fmt::format("{}: truncated or corrupt WAV ({})", path, riff_problem));
  }
  if (LogReportsShortData(file.get())) {
    throw IoError(fmt::format("{}: truncated (data chunk longer than the file)", path));
  }
  if (info.frames <= 0) throw IoError(fmt::format("{}: no audio frames", path));
  if (expected_channels > 0 && info.channels != expected_channels) {
    throw IoError(
        fmt::format("{}: expected {} channels, found {}", path, expected_channels, info.channels));
  }

  // Interleaved frames are the columns of the (channels x frames) column-major matrix.
  AudioClip clip;
  clip.sample_rate_hz = static_cast<double>(info.samplerate);
  clip.samples.resize(info.channels, info.frames);
  const sf_count_t read = sf_readf_float(file.get(), clip.samples.data(), info.frames);
  if (read != info.frames) {
    throw IoError(fmt::format("{}: truncated: read {} of {} frames ({})", path, read, info.frames,
                              sf_strerror(file.get())));
  }
  // a float WAV may hold NaN or infinity: refused here, at the file's own frame
  if (!clip.samples.allFinite()) {
    for (int64_t t = 0; t < clip.frames(); ++t) {
      for (int c = 0; c < clip.channels(); ++c) {
        const float x = clip.samples(c, t);
        if (!std::isfinite(x)) {
          throw IoError(fmt::format("{}: frame {} ({:.4f} s) of channel {} is {}", path, t,
                                    t / clip.sample_rate_hz, c, x));
        }
      }
    }
  }
  return clip;
}

void WriteWav(const std::string& path, const AudioClip& clip, bool pcm16) {
  if (clip.channels() < 1 || clip.frames() < 1) {
    throw IoError(fmt::format("{}: nothing to write ({} channels x {} frames)", path,
                              clip.channels(), clip.frames()));
  }
  const long rate = std::lround(clip.sample_rate_hz);
  if (!(clip.sample_rate_hz > 0.0) || rate < 1) {
    throw IoError(fmt::format("{}: invalid sample rate {} Hz", path, clip.sample_rate_hz));
  }
  if (!clip.samples.allFinite()) {
    throw IoError(fmt::format("{}: refusing to write non-finite samples", path));
  }

  const std::string partial = path + ".partial";
  SF_INFO info{};
  info.samplerate = static_cast<int>(rate);
  info.channels = clip.channels();
  info.format = SF_FORMAT_WAV | (pcm16 ? SF_FORMAT_PCM_16 : SF_FORMAT_FLOAT);
  SndFile file(sf_open(partial.c_str(), SFM_WRITE, &info));
  if (file.get() == nullptr) {
    throw IoError(
        fmt::format("{}: cannot open {} for writing ({})", path, partial, sf_strerror(nullptr)));
  }
  auto fail = [&](const std::string& why) {
    file.Close();
    std::error_code ignored;
    fs::remove(partial, ignored);
    throw IoError(fmt::format("{}: write failed: {}", path, why));
  };

  // Frames go out in blocks of kBlock, clipped to [-1, 1]. PCM16 is quantised here as
  // round(x * 32768) clamped to [-32768, 32767], the inverse of libsndfile's read scaling
  // (1/32768), so a round trip is within half a step except at +1.
  constexpr int64_t kBlock = 4096;
  const int64_t channels = clip.channels();
  std::vector<short> pcm;
  std::vector<float> flt;
  for (int64_t start = 0; start < clip.frames(); start += kBlock) {
    const int64_t len = std::min(kBlock, clip.frames() - start);
    const float* src = clip.samples.data() + start * channels;
    sf_count_t written = 0;
    if (pcm16) {
      pcm.resize(static_cast<size_t>(len * channels));
      for (int64_t i = 0; i < len * channels; ++i) {
        const double x = std::clamp(static_cast<double>(src[i]), -1.0, 1.0);
        pcm[i] = static_cast<short>(std::clamp<long>(std::lround(x * 32768.0), -32768, 32767));
      }
      written = sf_writef_short(file.get(), pcm.data(), len);
    } else {
      flt.resize(static_cast<size_t>(len * channels));
      for (int64_t i = 0; i < len * channels; ++i) flt[i] = std::clamp(src[i], -1.0f, 1.0f);
      written = sf_writef_float(file.get(), flt.data(), len);
    }
    if (written != len) fail(sf_strerror(file.get()));
  }
  if (file.Close() != 0) fail("closing the file failed");

  std::error_code ec;
  fs::rename(partial, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(partial, ignored);
    throw IoError(fmt::format("{}: cannot rename from {}: {}", path, partial, ec.message()));
  }
}

}  // namespace sonicboom
