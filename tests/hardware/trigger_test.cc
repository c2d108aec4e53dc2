// The onset trigger: records cut at the right frames whatever the block sizes, one record per
// strike, padding at the stream's ends, and refused settings.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "common/test_util.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/stream.h"
#include "sonicboom/hardware/trigger.h"

namespace sonicboom::hardware {
namespace {

using ::testing::HasSubstr;

TriggerConfig Small() {
  TriggerConfig c;
  c.sample_rate_hz = 8000;
  c.channels = 3;
  c.record_frames = 4000;
  c.pre_trigger_frames = 1000;
  c.frame = 32;
  return c;
}

// Noise (RMS 1e-3) with a decaying burst (peak 0.3) starting at each of `onsets`.
Eigen::MatrixXf Stream(int64_t frames, const std::vector<int64_t>& onsets) {
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 1e-3f);
  Eigen::MatrixXf x(3, frames);
  for (int64_t t = 0; t < frames; ++t) {
    for (int c = 0; c < 3; ++c) x(c, t) = noise(rng);
  }
  for (int64_t onset : onsets) {
    for (int64_t t = onset; t < std::min(frames, onset + 2000); ++t) {
      for (int c = 0; c < 3; ++c)
        x(c, t) += 0.3f * std::exp(-(t - onset) / 300.0f) * std::sin(0.3f * (t - onset) + c);
    }
  }
  return x;
}

// Feeds `x` in blocks of the given sizes (cycled), then flushes.
std::vector<TriggeredRecord> Feed(const TriggerConfig& c, const Eigen::MatrixXf& x,
                                  const std::vector<int64_t>& sizes) {
  OnsetTrigger trigger(c);
  std::vector<TriggeredRecord> out;
  int64_t at = 0;
  for (size_t k = 0; at < x.cols(); ++k) {
    const int64_t n = std::min(sizes[k % sizes.size()], x.cols() - at);
    trigger.Push(x.middleCols(at, n), &out);
    at += n;
  }
  trigger.Flush(&out);
  return out;
}

TEST(TriggerTest, CutsOneRecordPerStrikeAtItsOnsetForAnyBlockSize) {
  const std::vector<int64_t> onsets = {5000, 12000, 20010};
  const Eigen::MatrixXf x = Stream(30000, onsets);
  for (const std::vector<int64_t>& sizes :
       std::vector<std::vector<int64_t>>{{1024}, {7, 333, 4096}, {30000}}) {
    const std::vector<TriggeredRecord> records = Feed(Small(), x, sizes);
    ASSERT_EQ(records.size(), onsets.size()) << sizes.size();
    for (size_t k = 0; k < onsets.size(); ++k) {
      // the onset lies in the energy frame that holds the burst's start
      EXPECT_LE(std::abs(records[k].onset_frame - onsets[k]), 32) << k;
      const int64_t start = records[k].onset_frame - 1000;
      EXPECT_EQ(records[k].audio, x.middleCols(start, 4000)) << k;
    }
  }
}

TEST(TriggerTest, RingingInsideARecordStartsNoOtherAndTheEndsArePadded) {
  // a second burst 0.1 s after the first lies inside its record: one record
  EXPECT_EQ(Feed(Small(), Stream(12000, {3000, 3800}), {512}).size(), 1u);
  // a strike at the very start: the missing pre-trigger frames repeat the first frame
  Eigen::MatrixXf x = Stream(9000, {200});
  std::vector<TriggeredRecord> r = Feed(Small(), x, {256});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].audio.col(0), x.col(0));
  // a strike near the end: the record is completed with the last frame
  x = Stream(9000, {7000});
  r = Feed(Small(), x, {256});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].audio.col(3999), x.col(8999));
  // noise alone triggers nothing
  EXPECT_TRUE(Feed(Small(), Stream(20000, {}), {1000}).empty());
}

TEST(TriggerTest, RefusesSettingsThatCannotCutARecord) {
  TriggerConfig c = Small();
  c.pre_trigger_frames = 3990;
  EXPECT_THAT(sonicboom::testing::ThrownMessage<ConfigError>([&] { OnsetTrigger t(c); }),
              HasSubstr("pre_trigger_frames = 3990"));
  c = Small();
  c.frame = 0;
  EXPECT_THROW(OnsetTrigger{c}, ConfigError);
  OnsetTrigger t(Small());
  std::vector<TriggeredRecord> out;
  EXPECT_THROW(t.Push(Eigen::MatrixXf::Zero(2, 10), &out), IoError);
}

TEST(TriggerTest, WavSourceDeliversTheFileInBlocks) {
  sonicboom::testing::TempDir dir;
  const Eigen::MatrixXf x = Stream(5000, {1000});
  WriteWav(dir / "s.wav", AudioClip{x, 8000.0}, /*pcm16=*/false);
  const auto source = OpenWavSource(dir / "s.wav", /*realtime=*/false);
  EXPECT_EQ(source->channels(), 3);
  Eigen::MatrixXf block(3, 2048), all(3, 0);
  for (int64_t n; (n = source->Read(&block)) > 0;) {
    all.conservativeResize(Eigen::NoChange, all.cols() + n);
    all.rightCols(n) = block.leftCols(n);
  }
  EXPECT_EQ(all, x);
}

}  // namespace
}  // namespace sonicboom::hardware
