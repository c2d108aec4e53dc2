// Live capture through PortAudio (blocking reads of interleaved 32-bit float frames).
#include <portaudio.h>

#include <algorithm>
#include <mutex>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/stream.h"

namespace sonicboom::hardware {
namespace {

// PortAudio initialized once for the process (terminated at exit by the OS).
void InitializePortAudio() {
  static std::once_flag once;
  static PaError status = paNoError;
  std::call_once(once, [] { status = Pa_Initialize(); });
  if (status != paNoError) {
    throw IoError(
        fmt::format("audio input: cannot initialize PortAudio: {}", Pa_GetErrorText(status)));
  }
}

// The input device whose name contains `wanted` (the default input when empty).
PaDeviceIndex FindDevice(const std::string& wanted) {
  if (wanted.empty()) {
    const PaDeviceIndex d = Pa_GetDefaultInputDevice();
    if (d == paNoDevice) throw IoError("audio input: no default input device (give --device NAME)");
    return d;
  }
  for (PaDeviceIndex d = 0; d < Pa_GetDeviceCount(); ++d) {
    const PaDeviceInfo* info = Pa_GetDeviceInfo(d);
    if (info && info->maxInputChannels > 0 &&
        std::string(info->name).find(wanted) != std::string::npos) {
      return d;
    }
  }
  std::string known;
  for (const std::string& name : ListInputDevices()) known += "\n  " + name;
  throw IoError(fmt::format("audio input: no input device named '{}'; inputs:{}", wanted,
                            known.empty() ? std::string(" none") : known));
}

class DeviceSource final : public AudioSource {
 public:
  DeviceSource(const std::string& device, int channels, double rate)
      : channels_(channels), rate_(rate) {
    InitializePortAudio();
    const PaDeviceIndex d = FindDevice(device);
    const PaDeviceInfo* info = Pa_GetDeviceInfo(d);
    name_ = fmt::format("device '{}'", info->name);
    PaStreamParameters in{};
    in.device = d;
    in.channelCount = channels;
    in.sampleFormat = paFloat32;
    in.suggestedLatency = info->defaultLowInputLatency;
    const PaError ok = Pa_IsFormatSupported(&in, nullptr, rate);
    if (ok != paFormatIsSupported) {
      throw IoError(fmt::format("{}: cannot capture {} channels at {} Hz ({} input channels): {}",
                                name_, channels, rate, info->maxInputChannels,
                                Pa_GetErrorText(ok)));
    }
    const PaError open = Pa_OpenStream(&stream_, &in, nullptr, rate, paFramesPerBufferUnspecified,
                                       paNoFlag, nullptr, nullptr);
    if (open != paNoError || Pa_StartStream(stream_) != paNoError) {
      throw IoError(fmt::format("{}: cannot start the stream: {}", name_, Pa_GetErrorText(open)));
    }
  }
  ~DeviceSource() override {
    if (stream_) {
      Pa_StopStream(stream_);
      Pa_CloseStream(stream_);
    }
  }
  int channels() const override { return channels_; }
  double sample_rate_hz() const override { return rate_; }
  std::string name() const override { return name_; }
  int64_t overflows() const override { return overflows_; }

  int64_t Read(Eigen::MatrixXf* block) override {
    interleaved_.resize(static_cast<size_t>(block->size()));
    const PaError e =
        Pa_ReadStream(stream_, interleaved_.data(), static_cast<unsigned long>(block->cols()));
    // an overflow lost frames: counted (listen reports it), and the stream goes on
    if (e == paInputOverflowed) {
      ++overflows_;
    } else if (e != paNoError) {
      throw IoError(fmt::format("{}: read failed: {}", name_, Pa_GetErrorText(e)));
    }
    // interleaved (frames x channels) -> (channels x frames)
    *block = Eigen::Map<const Eigen::MatrixXf>(interleaved_.data(), channels_, block->cols());
    return block->cols();
  }

 private:
  int channels_;
  double rate_;
  std::string name_;
  PaStream* stream_{nullptr};
  std::vector<float> interleaved_;
  int64_t overflows_{0};
};

}  // namespace

std::unique_ptr<AudioSource> OpenDeviceSource(const std::string& device, int channels,
                                              double sample_rate_hz) {
  return std::make_unique<DeviceSource>(device, channels, sample_rate_hz);
}

std::vector<std::string> ListInputDevices() {
  InitializePortAudio();
  std::vector<std::string> names;
  for (PaDeviceIndex d = 0; d < Pa_GetDeviceCount(); ++d) {
    const PaDeviceInfo* info = Pa_GetDeviceInfo(d);
    if (info && info->maxInputChannels > 0) {
      names.push_back(fmt::format("{} ({} inputs)", info->name, info->maxInputChannels));
    }
  }
  return names;
}

}  // namespace sonicboom::hardware
