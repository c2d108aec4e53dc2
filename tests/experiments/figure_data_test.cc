// Figure data sized to the figure: `inspect --png` of a default strike (2 s, six channels) wrote
// 10.9 MB of JSON beside a 0.65 MB PNG; the waveforms are now envelopes and the spectrograms
// pooled, whatever the record's length.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#include "common/test_util.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::CliRun;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;

TEST(InspectFigureTest, FigureDataStaysUnderAMegabyteAndDrawsTheStrike) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  // default records (2 s at 44.1 kHz): 529 200 samples of six channels (rendered by the closed
  // form: no shell mode solve)
  ASSERT_EQ(RunCli("-q --set acoustics.model=modal-closed-form generate --count 3 --out D.h5", cwd)
                .exit_code,
            0);
  const CliRun run = RunCli("-q inspect D.h5 --png F.png --strike 1 --plot '" +
                                std::string(SONICBOOM_SOURCE_DIR) + "/scripts/plot.py'",
                            cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ASSERT_TRUE(fs::is_regular_file(dir.path() / "F.png"));
  EXPECT_FALSE(fs::exists(dir.path() / "F.png.partial.png"));
  const auto bytes = fs::file_size(dir.path() / "F.png.json");
  EXPECT_LT(bytes, 1000000u) << bytes;
  std::ifstream in(dir.path() / "F.png.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  const nlohmann::json& strike = j["strike"];
  EXPECT_EQ(strike["frames"], 88200);
  ASSERT_EQ(strike["envelopes"].size(), 6u);
  EXPECT_EQ(strike["envelopes"][0]["min"].size(), 1500u);
  const nlohmann::json& db = strike["spectrograms"]["db"];
  ASSERT_EQ(db.size(), 6u);
  EXPECT_EQ(db[0].size(), 64u);
  EXPECT_LE(db[0][0].size(), 300u);
  // the envelope holds the strike: its loudest column is far above the record's first
  double first = 0.0, loudest = 0.0;
  for (size_t k = 0; k < strike["envelopes"][0]["max"].size(); ++k) {
    const double a = strike["envelopes"][0]["max"][k].get<double>() -
                     strike["envelopes"][0]["min"][k].get<double>();
    if (k == 0) first = a;
    loudest = std::max(loudest, a);
  }
  EXPECT_GT(loudest, 10.0 * first);
  // the spectrogram's dB lie between the floor and 0, and 0 is reached (the loudest bin)
  int top = -1000, bottom = 1000;
  for (const auto& channel : db) {
    for (const auto& row : channel) {
      for (const auto& v : row) {
        top = std::max(top, v.get<int>());
        bottom = std::min(bottom, v.get<int>());
      }
    }
  }
  EXPECT_EQ(top, 0);
  EXPECT_GE(bottom, -80);
}

}  // namespace
}  // namespace sonicboom::experiments
