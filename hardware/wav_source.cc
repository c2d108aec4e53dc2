// A WAV file read as a device stream (tests, replays of recorded sessions).
#include <algorithm>
#include <chrono>
#include <thread>

#include <fmt/format.h>

#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/stream.h"

namespace sonicboom::hardware {
namespace {

class WavSource final : public AudioSource {
 public:
  WavSource(const std::string& path, bool realtime)
      : path_(path),
        clip_(ReadWav(path)),
        realtime_(realtime),
        start_(std::chrono::steady_clock::now()) {
    if (!clip_.samples.allFinite())
      throw IoError(fmt::format("{}: holds non-finite samples", path));
  }
  int channels() const override { return clip_.channels(); }
  double sample_rate_hz() const override { return clip_.sample_rate_hz; }
  std::string name() const override { return "file " + path_; }

  int64_t Read(Eigen::MatrixXf* block) override {
    const int64_t n = std::min<int64_t>(block->cols(), clip_.frames() - next_);
    if (n <= 0) return 0;
    block->leftCols(n) = clip_.samples.middleCols(next_, n);
    next_ += n;
    // a device hands over frames no faster than they are sampled
    if (realtime_) {
      const auto due = start_ + std::chrono::duration<double>(next_ / clip_.sample_rate_hz);
      std::this_thread::sleep_until(
          std::chrono::time_point_cast<std::chrono::steady_clock::duration>(due));
    }
    return n;
  }

 private:
  std::string path_;
  AudioClip clip_;
  bool realtime_;
  std::chrono::steady_clock::time_point start_;
  int64_t next_{0};
};

}  // namespace

std::unique_ptr<AudioSource> OpenWavSource(const std::string& path, bool realtime) {
  return std::make_unique<WavSource>(path, realtime);
}

}  // namespace sonicboom::hardware
