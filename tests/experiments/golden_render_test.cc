// What the generator renders, pinned: a few strikes of every shipped scene config and of each
// vibration model are generated through the CLI and compared with committed fingerprints
// (tests/data/goldens/render.json), so that a change to the audio or the labels is a decision,
// not an accident. Regenerated only on purpose: scripts/make_render_goldens.sh.
//
// A fingerprint is tolerant of round-off (a libm or FFT kernel that differs in the last bit on
// another CPU) but not of physics: per channel, the RMS and eight signed projections of the
// audio onto fixed +-1 sequences (a flipped polarity, a 0.1 % gain or a one-sample shift moves
// them), and the label to 1e-9.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <map>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom {
namespace {

using nlohmann::json;
using testing::RunCli;
using testing::TempDir;

constexpr int kProjections = 8;
// projections agree to this fraction of the channel's L2 norm plus a few int16 steps: round-off
// that flips the stored audio's last bit here and there stays far below it; a 0.1 % gain change
// moves a projection by 1e-3 of its own size, a sign flip by twice its size
constexpr double kProjectionTolerance = 1e-4;
constexpr double kProjectionFloor = 16.0 / 32768.0;
constexpr double kLabelTolerance = 1e-9;

struct GoldenCase {
  const char* name;
  std::string args;  // config options before the subcommand; {src} stands for the source tree
  int count;
  int first_index{0};  // (ts3: the first guided taps miss the canopy)
};

void PrintTo(const GoldenCase& c, std::ostream* os) {
  *os << c.name;
}

// (the golden keeps {src}, so that it holds in any checkout)
std::string Config(const char* file) {
  return std::string("--config '{src}/configs/") + file + "' ";
}

// the options with {src} replaced by this checkout's source tree
std::string Resolved(std::string args) {
  const std::string token = "{src}";
  for (size_t at = args.find(token); at != std::string::npos; at = args.find(token, at))
    args.replace(at, token.size(), SONICBOOM_SOURCE_DIR);
  return args;
}

std::vector<GoldenCase> Cases() {
  // the FD rung on a coarse grid and a short record, to stay within seconds
  const std::string fd =
      "--set acoustics.model=fd --set shell.grid_spacing_m=0.01 --set shell.axial_spacing_m=0.02 " +
      testing::kShortRecordArgs;
  return {
      {"default", "", 2},
      {"ts1", Config("ts1.yaml"), 2},
      {"ts2", Config("ts2.yaml"), 3},
      {"ts3", Config("ts3.yaml"), 2, 21},
      {"ts4", Config("ts4.yaml"), 3},
      {"materials", Config("materials.yaml"), 3},
      {"study", Config("study.yaml"), 2},
      // the randomized preset on a pool of two structures (the pool the preset tests solve)
      {"ts4_randomized",
       Config("ts4.yaml") + Config("randomized.yaml") + "--set randomize.structure_variants=2 ", 2},
      {"closed_form", "--set acoustics.model=modal-closed-form ", 2},
      {"fd_coarse", fd, 1},
  };
}

// (kProjections x n) the fixed +-1 sequences: bits of a 64-bit LCG, the same on every machine
std::vector<std::vector<float>> Signs(int64_t n) {
  std::vector<std::vector<float>> signs(kProjections, std::vector<float>(n));
  uint64_t state = 0x5EED5EEDULL;
  for (auto& row : signs) {
    for (auto& s : row) {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      s = (state >> 63) ? 1.0f : -1.0f;
    }
  }
  return signs;
}

// One channel's energy (sum x^2) and its projections onto the sign sequences
struct ChannelPrint {
  double energy{0.0};
  std::vector<double> projections;  // (kProjections)
};
ChannelPrint PrintOf(const std::vector<double>& x, const std::vector<std::vector<float>>& signs) {
  ChannelPrint p;
  p.projections.assign(kProjections, 0.0);
  for (size_t t = 0; t < x.size(); ++t) {
    p.energy += x[t] * x[t];
    for (int k = 0; k < kProjections; ++k) p.projections[k] += x[t] * signs[k][t];
  }
  return p;
}

// {label, channels: [{rms, projections}]} of every strike of a dataset
json Fingerprint(const std::string& path) {
  DatasetReader reader(path);
  json strikes = json::array();
  for (int64_t row = 0; row < reader.size(); ++row) {
    const StrikeSample s = reader.Read(row);
    json channels = json::array();
    const auto signs = Signs(s.audio.cols());
    for (int c = 0; c < s.audio.rows(); ++c) {
      std::vector<double> x(static_cast<size_t>(s.audio.cols()));
      for (int64_t t = 0; t < s.audio.cols(); ++t) x[static_cast<size_t>(t)] = s.audio(c, t);
      const ChannelPrint p = PrintOf(x, signs);
      channels.push_back({{"rms", std::sqrt(p.energy / s.audio.cols())},
                          {"norm", std::sqrt(p.energy)},
                          {"projections", p.projections}});
    }
    strikes.push_back({{"index", s.index},
                       {"valid", s.valid},
                       {"z_m", s.label.z_m},
                       {"theta_rad", s.label.theta_rad},
                       {"time_s", s.label.time_s},
                       {"samples", s.audio.cols()},
                       {"channels", channels}});
  }
  return strikes;
}

std::string GoldenPath() {
  return std::string(SONICBOOM_SOURCE_DIR) + "/tests/data/goldens/render.json";
}

// Compares one strike's fingerprint with its golden; returns how many values differ.
int CompareStrike(const json& got, const json& want, const std::string& where) {
  int failures = 0;
  EXPECT_EQ(got["index"], want["index"]) << where;
  EXPECT_EQ(got["valid"], want["valid"]) << where;
  EXPECT_EQ(got["samples"], want["samples"]) << where;
  for (const char* key : {"z_m", "theta_rad", "time_s"}) {
    const double a = got[key], b = want[key];
    if (std::abs(a - b) > kLabelTolerance) {
      ADD_FAILURE() << where << ": label " << key << " is " << a << ", golden " << b;
      ++failures;
    }
  }
  if (got["channels"].size() != want["channels"].size()) {
    ADD_FAILURE() << where << ": " << got["channels"].size() << " channels, golden "
                  << want["channels"].size();
    return failures + 1;
  }
  for (size_t c = 0; c < got["channels"].size(); ++c) {
    const json& g = got["channels"][c];
    const json& w = want["channels"][c];
    const double scale = std::max(w["norm"].get<double>(), 1e-12);
    for (int k = 0; k < kProjections; ++k) {
      const double a = g["projections"][k], b = w["projections"][k];
      if (std::abs(a - b) > kProjectionTolerance * scale + kProjectionFloor) {
        ADD_FAILURE() << where << " channel " << c << ": projection " << k << " is " << a
                      << ", golden " << b << " (channel norm " << scale << ", rms "
                      << g["rms"].get<double>() << " against " << w["rms"].get<double>() << ")";
        ++failures;
        break;
      }
    }
  }
  return failures;
}

class GoldenRenderTest : public ::testing::TestWithParam<GoldenCase> {};

TEST_P(GoldenRenderTest, MatchesItsCommittedFingerprint) {
  const GoldenCase& c = GetParam();
  TempDir dir;
  const std::string out = dir / "g.h5";
  const auto run = RunCli("-q --threads 2 " + Resolved(c.args) + "generate --count " +
                              std::to_string(c.count) + " --first-index " +
                              std::to_string(c.first_index) + " --out '" + out + "'",
                          dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json got = Fingerprint(out);
  // a case pins at least one strike that sounds
  bool sounds = false;
  for (const json& strike : got)
    sounds = sounds || (strike["valid"].get<bool>() && strike["channels"][0]["norm"] > 0.0);
  ASSERT_TRUE(sounds) << c.name << ": no valid strike among the ones rendered";

  // scripts/make_render_goldens.sh sets this to write the golden instead of checking it
  if (const char* write = std::getenv("SONICBOOM_WRITE_RENDER_GOLDENS"); write && *write) {
    json all = json::object();
    if (std::ifstream in(GoldenPath()); in) all = json::parse(in);
    all[c.name] = {{"args", c.args}, {"strikes", got}};
    std::ofstream(GoldenPath()) << all.dump(1) << "\n";
    GTEST_SKIP() << "wrote the golden of " << c.name;
  }
  std::ifstream in(GoldenPath());
  ASSERT_TRUE(in) << GoldenPath() << " is missing: scripts/make_render_goldens.sh writes it";
  const json all = json::parse(in);
  ASSERT_TRUE(all.contains(c.name)) << "no golden for " << c.name
                                    << ": scripts/make_render_goldens.sh writes it";
  const json& want = all[c.name];
  ASSERT_EQ(want["args"].get<std::string>(), c.args)
      << "the case's options changed since its golden was written";
  ASSERT_EQ(got.size(), want["strikes"].size());
  for (size_t i = 0; i < got.size(); ++i)
    CompareStrike(got[i], want["strikes"][i], std::string(c.name) + " strike " + std::to_string(i));
}

INSTANTIATE_TEST_SUITE_P(Configs, GoldenRenderTest, ::testing::ValuesIn(Cases()),
                         [](const auto& info) { return std::string(info.param.name); });

// The fingerprint sees what it is for: a sign flip, a 0.1 % gain and a one-sample delay of one
// channel each move it past the tolerance, and round-off does not.
TEST(GoldenFingerprintTest, SeesPolarityGainAndDelayButNotRoundOff) {
  const int64_t n = 4000;
  std::vector<double> x(n);
  for (int64_t t = 0; t < n; ++t)
    x[t] = std::exp(-t / 600.0) * std::sin(0.07 * t) + 0.3 * std::exp(-t / 200.0) * std::sin(0.9 * t);
  const auto signs = Signs(n);
  const double norm = std::sqrt(PrintOf(x, signs).energy);
  // the fingerprint's own computation (PrintOf), as the golden test applies it
  const auto moved = [&](const std::vector<double>& y) {
    const auto a = PrintOf(x, signs).projections, b = PrintOf(y, signs).projections;
    double worst = 0.0;
    for (int k = 0; k < kProjections; ++k) worst = std::max(worst, std::abs(a[k] - b[k]));
    return worst / norm;
  };
  std::vector<double> flipped(n), gained(n), delayed(n, 0.0), rounded(n);
  for (int64_t t = 0; t < n; ++t) {
    flipped[t] = -x[t];
    gained[t] = 1.001 * x[t];
    if (t + 1 < n) delayed[t + 1] = x[t];
    rounded[t] = static_cast<float>(x[t]) * (1.0 + 1e-7 * ((t % 3) - 1));
  }
  EXPECT_GT(moved(flipped), 10 * kProjectionTolerance);
  EXPECT_GT(moved(gained), kProjectionTolerance);
  EXPECT_GT(moved(delayed), kProjectionTolerance);
  EXPECT_LT(moved(rounded), 0.1 * kProjectionTolerance);
}

}  // namespace
}  // namespace sonicboom
