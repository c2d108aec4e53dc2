#include "sonicboom/core/audio_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A fresh directory under the system temp dir, removed after each test.
class AudioIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device entropy;
    for (int attempt = 0; attempt < 100; ++attempt) {
      const fs::path candidate =
          fs::temp_directory_path() / ("sonicboom_audio_io_test_" + std::to_string(::getpid()) +
                                       "_" + std::to_string(entropy()));
      if (fs::create_directory(candidate)) {
        dir_ = candidate;
        return;
      }
    }
    FAIL() << "could not create a temp dir";
  }
  void TearDown() override {
    std::error_code ignored;
    if (!dir_.empty()) fs::remove_all(dir_, ignored);
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

// (channels x frames) deterministic test clip at 44.1 kHz, values in [-1, 1] incl. both ends.
AudioClip TestClip(int channels, int64_t frames) {
  AudioClip clip;
  clip.sample_rate_hz = 44100.0;
  clip.samples.resize(channels, frames);
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
  for (int64_t t = 0; t < frames; ++t) {
    for (int c = 0; c < channels; ++c) clip.samples(c, t) = uniform(rng);
  }
  clip.samples(0, 0) = 1.0f;
  clip.samples(0, 1) = -1.0f;
  clip.samples(0, 2) = 0.0f;
  clip.samples(0, 3) = 0.5f;
  return clip;
}

// Message of the IoError thrown by f, or a test failure.
template <typename F>
std::string IoErrorMessage(F f) {
  try {
    f();
  } catch (const IoError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected IoError";
  return "";
}

TEST_F(AudioIoTest, RoundTripPcm16WithinOneStep) {
  const AudioClip clip = TestClip(6, 5000);
  const std::string path = Path("pcm16.wav");
  WriteWav(path, clip, /*pcm16=*/true);
  EXPECT_FALSE(fs::exists(path + ".partial"));
  const AudioClip back = ReadWav(path, 6);
  EXPECT_EQ(back.sample_rate_hz, 44100.0);
  ASSERT_EQ(back.channels(), 6);
  ASSERT_EQ(back.frames(), 5000);
  const float error = (back.samples - clip.samples).cwiseAbs().maxCoeff();
  EXPECT_LE(error, 1.0f / 32767.0f);
  // 16 bits really were used: the error is not zero.
  EXPECT_GT(error, 0.0f);
  // Data chunk: 5000 frames x 6 channels x 2 bytes after a short header.
  EXPECT_LT(fs::file_size(path), 5000u * 6u * 2u + 200u);
}

TEST_F(AudioIoTest, RoundTripFloatIsExact) {
  const AudioClip clip = TestClip(6, 3000);
  const std::string path = Path("float.wav");
  WriteWav(path, clip, /*pcm16=*/false);
  const AudioClip back = ReadWav(path);
  ASSERT_EQ(back.channels(), 6);
  ASSERT_EQ(back.frames(), 3000);
  EXPECT_TRUE(back.samples == clip.samples);
  EXPECT_GT(fs::file_size(path), 3000u * 6u * 4u);
}

TEST_F(AudioIoTest, ClipsBeyondFullScale) {
  AudioClip clip;
  clip.sample_rate_hz = 48000.0;
  clip.samples.resize(2, 3);
  clip.samples << 1.5f, -2.0f, 0.25f, 1.0f, -1.0f, -0.25f;
  for (bool pcm16 : {true, false}) {
    const std::string path = Path(pcm16 ? "clip16.wav" : "clipf.wav");
    WriteWav(path, clip, pcm16);
    const AudioClip back = ReadWav(path, 2);
    EXPECT_EQ(back.sample_rate_hz, 48000.0);
    EXPECT_NEAR(back.samples(0, 0), 1.0f, 1.0f / 32767.0f) << "pcm16 " << pcm16;
    EXPECT_EQ(back.samples(0, 1), -1.0f) << "pcm16 " << pcm16;
    EXPECT_EQ(back.samples(0, 2), 0.25f) << "pcm16 " << pcm16;
  }
}

TEST_F(AudioIoTest, OverwritesExistingFile) {
  const std::string path = Path("again.wav");
  WriteWav(path, TestClip(2, 100));
  WriteWav(path, TestClip(3, 50));
  const AudioClip back = ReadWav(path);
  EXPECT_EQ(back.channels(), 3);
  EXPECT_EQ(back.frames(), 50);
}

TEST_F(AudioIoTest, MissingFileNamesPath) {
  const std::string path = Path("nowhere.wav");
  EXPECT_THAT(IoErrorMessage([&] { ReadWav(path); }), HasSubstr(path));
}

TEST_F(AudioIoTest, TextFileNamedWavIsRejected) {
  const std::string path = Path("notes.wav");
  std::ofstream(path) << "this is not audio, just a text file\n";
  EXPECT_THAT(IoErrorMessage([&] { ReadWav(path); }), HasSubstr(path));
}

TEST_F(AudioIoTest, TruncatedWavIsRejected) {
  for (bool pcm16 : {true, false}) {
    const std::string path = Path(pcm16 ? "cut16.wav" : "cutf.wav");
    WriteWav(path, TestClip(6, 44100), pcm16);
    ASSERT_NO_THROW(ReadWav(path, 6));
    fs::resize_file(path, fs::file_size(path) / 2);
    const std::string message = IoErrorMessage([&] { ReadWav(path, 6); });
    EXPECT_THAT(message, HasSubstr(path));
    EXPECT_THAT(message, HasSubstr("truncated"));
  }
}

TEST_F(AudioIoTest, WavCutByOneByteIsRejected) {
  const std::string path = Path("short.wav");
  WriteWav(path, TestClip(6, 1000));
  fs::resize_file(path, fs::file_size(path) - 1);
  EXPECT_THAT(IoErrorMessage([&] { ReadWav(path); }), HasSubstr("truncated"));
}

TEST_F(AudioIoTest, EmptyWavIsRejected) {
  // Hand-made 44-byte PCM16 mono header with an empty data chunk.
  const std::string path = Path("empty.wav");
  std::ofstream out(path, std::ios::binary);
  auto u32 = [&](uint32_t v) {
    for (int i = 0; i < 4; ++i) out.put(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  auto u16 = [&](uint16_t v) {
    out.put(static_cast<char>(v & 0xff));
    out.put(static_cast<char>(v >> 8));
  };
  out << "RIFF";
  u32(36);
  out << "WAVEfmt ";
  u32(16);
  u16(1);      // PCM
  u16(1);      // channels
  u32(44100);  // rate
  u32(88200);  // bytes per second
  u16(2);      // block align
  u16(16);     // bits
  out << "data";
  u32(0);
  out.close();
  ASSERT_EQ(fs::file_size(path), 44u);
  EXPECT_THAT(IoErrorMessage([&] { ReadWav(path); }), HasSubstr(path));
}

TEST_F(AudioIoTest, WrongChannelCountIsRejected) {
  const std::string path = Path("stereo.wav");
  WriteWav(path, TestClip(2, 100));
  const std::string message = IoErrorMessage([&] { ReadWav(path, 6); });
  EXPECT_THAT(message, HasSubstr(path));
  EXPECT_THAT(message, HasSubstr("expected 6 channels, found 2"));
  EXPECT_NO_THROW(ReadWav(path, 2));
}

TEST_F(AudioIoTest, WriteIntoMissingDirectoryLeavesNothing) {
  const std::string path = Path("no/such/dir/out.wav");
  EXPECT_THROW(WriteWav(path, TestClip(6, 100)), IoError);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".partial"));
  EXPECT_FALSE(fs::exists(Path("no")));
}

TEST_F(AudioIoTest, WriteRejectsEmptyAndNonFiniteClips) {
  AudioClip empty;
  empty.sample_rate_hz = 44100.0;
  EXPECT_THROW(WriteWav(Path("empty.wav"), empty), IoError);
  AudioClip bad = TestClip(2, 10);
  bad.samples(1, 5) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(WriteWav(Path("nan.wav"), bad), IoError);
  EXPECT_FALSE(fs::exists(Path("nan.wav")));
  EXPECT_FALSE(fs::exists(Path("nan.wav.partial")));
}

}  // namespace
}  // namespace sonicboom
