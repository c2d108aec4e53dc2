#pragma once
/// Multichannel WAV reading and writing (libsndfile stays in audio_io.cc).

#include <Eigen/Core>
#include <string>

namespace sonicboom {

/// Audio in memory: (channels x frames), float, full scale = 1.
struct AudioClip {
  Eigen::MatrixXf samples;
  double sample_rate_hz{0.0};
  int channels() const { return static_cast<int>(samples.rows()); }
  int64_t frames() const { return samples.cols(); }
};

/// Reads a WAV file. Throws IoError naming the file when it is missing, not audio, truncated
/// (fewer frames than its header declares), empty, or has a channel count other than
/// `expected_channels` (when > 0).
AudioClip ReadWav(const std::string& path, int expected_channels = 0);

/// Writes `clip` as a WAV file with 16-bit PCM (`pcm16`) or 32-bit float samples. Values beyond
/// full scale are clipped. Written to "<path>.partial" and renamed, so a crash never leaves a
/// short file under the final name. Throws IoError.
void WriteWav(const std::string& path, const AudioClip& clip, bool pcm16 = true);

}  // namespace sonicboom
