#pragma once
/// Streams of multichannel audio for live localization: a sound device (PortAudio; headers stay
/// in device_source.cc) or a WAV file read as if it were one, so tests and replays take the same
/// path as a live session.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace sonicboom::hardware {

/// A source of audio blocks, full scale 1. Read() blocks until frames are available.
class AudioSource {
 public:
  virtual ~AudioSource() = default;
  virtual int channels() const = 0;
  virtual double sample_rate_hz() const = 0;
  /// Where the audio comes from, for messages ("device 'hw:1,0'", "file x.wav").
  virtual std::string name() const = 0;
  /// Fills `block` (channels x frames, resized by the caller) and returns the frames read, fewer
  /// than asked only at the end of a file; 0 when the stream has ended. Throws IoError.
  virtual int64_t Read(Eigen::MatrixXf* block) = 0;
  /// Reads in which the device dropped input because it was not read in time (0 for a file).
  virtual int64_t overflows() const { return 0; }
};

/// A WAV file as a stream. With `realtime`, Read() paces itself to the sample rate, as a device
/// would deliver the frames. Throws IoError naming the file.
std::unique_ptr<AudioSource> OpenWavSource(const std::string& path, bool realtime);

/// A capture device by (part of) its name, e.g. "hw:1,0" or "Scarlett"; empty: the default
/// input. Opens `channels` channels at `sample_rate_hz` (32-bit float). Throws IoError naming the
/// device and the audio library's reason when it is missing or cannot run at that rate and
/// channel count.
std::unique_ptr<AudioSource> OpenDeviceSource(const std::string& device, int channels,
                                              double sample_rate_hz);

/// Names of the input devices the audio library sees, with their input channel counts.
std::vector<std::string> ListInputDevices();

}  // namespace sonicboom::hardware
