// `sonicboom pretrain`: the recommended recipe in one command, on a small tube and a tiny model.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/files.h"

namespace sonicboom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using testing::RunCli;
using testing::TempDir;

// the recipe's layers with the structure pool off (its set-up takes minutes) and a tiny network
constexpr const char* kSmallLayer = R"(randomize:
  structure_variants: 0
  bolt_count: []
  bolt_z_jitter_m: []
  bolt_stiffness_scale: []
  flange_mount_scale: []
  tool_mount_scale: []
  poisson_ratio: []
  mic_z_offset_m: []
  mic_theta_offset_deg: []
audio:
  record_duration_s: 0.6
  onset_time_s: 0.3
  onset_jitter_s: 0.05
model:
  width: 16
  blocks: 1
  heads: 2
train:
  epochs: 2
  batch_size: 8
  ensemble_members: 2
)";

// One command makes a finished run: the ensemble, its recipe record with both datasets' counts
// and the calibration beyond the pool, no work directory left; the datasets go unless kept; a
// second run onto it is refused without --force.
TEST(PretrainCliTest, OneCommandMakesACalibratedRunAndKeepsItsOutput) {
  TempDir dir;
  WriteTextAtomic(dir / "small.yaml", kSmallLayer);
  const std::string args =
      "--config small.yaml -q --json pretrain --strikes 100 --calibration-strikes 40 --out RUN";
  auto run = RunCli(args, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir / "RUN/ensemble.json"));
  EXPECT_FALSE(fs::exists(dir / "RUN.partial"));
  EXPECT_FALSE(fs::exists(dir / "RUN/data"));
  const json record = json::parse(ReadText(dir / "RUN/pretrain.json"));
  EXPECT_EQ(record["strikes"], 100);
  EXPECT_GT(record["valid_train"].get<int64_t>(), 80);
  EXPECT_GE(record["calibration"]["metrics_after"]["n"].get<int64_t>(), 30);
  // the intervals fitted by the likelihood on the calibration strikes (the choice of the as-built
  // validation families), said in the run
  EXPECT_EQ(record["calibration_fit"], "likelihood");
  // calibrated on tubes beyond the as-built ranges: the wall's modulus 0.7-1.3x (training
  // 0.8-1.2x, configs/built_beyond.yaml); the test's layer cleared the pool's ranges for both
  EXPECT_EQ(record["calibration_ranges"]["youngs_modulus_scale"], json::array({0.7, 1.3}))
      << record.dump();
  EXPECT_EQ(record["calibration_ranges"]["flange_mount_scale"], json::array()) << record.dump();
  const json ensemble = json::parse(ReadText(dir / "RUN/ensemble.json"));
  EXPECT_NE(ensemble["uncertainty"]["method"].get<std::string>().find("minimizing the mean NLL"),
            std::string::npos)
      << ensemble["uncertainty"].dump();
  // the run's config is the recipe's: the as-built layer and the waveform model
  const std::string config = ReadText(dir / "RUN/config.yaml");
  EXPECT_NE(config.find("soft_striker_fraction: 0.25"), std::string::npos);
  EXPECT_NE(config.find("audio_representation: waveform"), std::string::npos);
  // the run localizes like any other
  run = RunCli("--config small.yaml -q generate --count 40 --first-index 900 --out T.h5",
               dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("-q --json eval --model RUN --data T.h5", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  // refitted by coverage on labelled strikes of the user's tube: 90 % of them inside their 90 %
  // intervals (the conformal quantile covers at least the level), and the run says how
  run = RunCli("-q --json calibrate --model RUN --data T.h5 --fit coverage", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json refit = json::parse(run.out);
  EXPECT_GE(refit["metrics_after"]["z_coverage_90"].get<double>(), 0.9) << run.out;
  // (unless the scale stops at its bound: a tiny network's angles, 90 degrees off, are spread
  // near uniformly, and no concentration 1e-4x the stored one can cover them at 90 %)
  if (refit["relative"]["kappa_scale"].get<double>() > 1e-4)
    EXPECT_GE(refit["metrics_after"]["theta_coverage_90"].get<double>(), 0.9) << run.out;
  else
    EXPECT_GT(refit["metrics_after"]["theta_coverage_90"].get<double>(),
              refit["metrics_before"]["theta_coverage_90"].get<double>()) << run.out;
  EXPECT_NE(ReadText(dir / "RUN/ensemble.json").find("covering 90 %"), std::string::npos);
  // a finished run is not replaced without --force
  run = RunCli(args, dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--force"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace sonicboom
