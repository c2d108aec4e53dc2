// Statistics need data, and the rules one command keeps hold for the others (issue 58): each
// strike counts once in calibrate, each ensemble member once; every calibration inside a training
// has calibrate's minimum or keeps its scales and says so; adapt needs as many strikes and writes
// outside the run it reads; a refused resume leaves nothing behind; a finished run keeps what a
// resume needs and no more; and the messages of items 7-8 name their file and values.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "common/workspace.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sonicboom::testing::CliRun;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::ReadBytes;
using sonicboom::testing::RunCli;
using sonicboom::testing::RunCliEnv;
using sonicboom::testing::Snapshot;
using sonicboom::testing::TempDir;
using ::testing::HasSubstr;

json ReadJson(const fs::path& path) {
  return json::parse(ReadBytes(path));
}

// The suite's workspace: 16 and 40 short strikes (other indices), a tiny one-epoch run on the 40
// (about 8 validation strikes), a strike WAV of the same config.
void BuildWorkspace(const fs::path& dir) {
  sonicboom::testing::RunEach(
      {kShortRecordArgs + "-q generate --count 16 --out d16.h5",
       kShortRecordArgs + "-q generate --count 40 --first-index 1000 --out d40.h5",
       kShortRecordArgs + kTinyModelArgs + "--set train.epochs=1 -q train --data d40.h5 --out RUN",
       kShortRecordArgs + "-q synth --out X.wav --index 3"},
      dir);
}

constexpr sonicboom::testing::Workspace kWorkspace{"statistics_rules", BuildWorkspace};

// Built once per ctest run (the suite's fixture) for its tests to copy
TEST(StatisticsRulesWorkspace, IsBuilt) {
  sonicboom::testing::PublishWorkspace(kWorkspace);
}

// Each test process works in its own copy of the workspace
class StatisticsRulesTest : public sonicboom::testing::WorkspaceTest<kWorkspace> {
 protected:
  static void Must(const std::string& args) {
    const CliRun run = RunCli(args, Cwd());
    ASSERT_EQ(run.exit_code, 0) << args << "\n" << run.err;
  }
  static std::string Cwd() { return dir_->path().string(); }
  static fs::path At(const std::string& name) { return dir_->path() / name; }
  static CliRun Cli(const std::string& args) { return RunCli(args, Cwd()); }
  // a copy of RUN under `name`, to change without touching the shared run
  static void CopyRun(const std::string& name) {
    fs::copy(At("RUN"), At(name), fs::copy_options::recursive);
  }
};

// A dataset given twice, or a renamed copy, counted 16 strikes as 32 and passed the minimum.
TEST_F(StatisticsRulesTest, CalibrateCountsEachStrikeOnce) {
  CopyRun("CAL");
  const auto before = Snapshot(At("CAL"));
  CliRun run = Cli("calibrate --model CAL --data d16.h5 --data d16.h5");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("--data d16.h5 is given twice (the same file as --data d16.h5)"));
  fs::copy_file(At("d16.h5"), At("copy16.h5"));
  run = Cli("calibrate --model CAL --data d16.h5 --data copy16.h5");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("copy16.h5 row 0 (index 0) is the strike of d16.h5 row 0 "
                                 "(index 0): the same audio, arm and label; each strike counts "
                                 "once toward the 30 a fit needs"));
  EXPECT_EQ(Snapshot(At("CAL")), before);
  // 16 and 40 other strikes are 56
  run = Cli("calibrate --model CAL --data d16.h5 --data d40.h5 --json -q");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["metrics_after"]["n"], 56);
}

// An ensemble.json naming one member twice was accepted by localize and calibrate.
TEST_F(StatisticsRulesTest, AnEnsembleNamesEachMemberOnce) {
  fs::create_directories(At("ENS"));
  fs::copy(At("RUN"), At("ENS") / "member0", fs::copy_options::recursive);
  fs::copy_file(At("RUN") / "config.yaml", At("ENS") / "config.yaml");
  std::ofstream(At("ENS") / "ensemble.json") << R"({"members": ["member0", "member0"]})";
  for (const std::string args :
       {"localize --model ENS --wav X.wav -q", "calibrate --model ENS --data d40.h5 -q"}) {
    const CliRun run = Cli(args);
    EXPECT_EQ(run.exit_code, 1) << args;
    EXPECT_THAT(run.err, HasSubstr("ENS/ensemble.json: member \"member0\" is named twice "
                                   "(entries 1 and 2); each network counts once in the mixture"))
        << args;
  }
  // another name for the same directory
  fs::create_directory_symlink("member0", At("ENS") / "again");
  std::ofstream(At("ENS") / "ensemble.json") << R"({"members": ["member0", "again"]})";
  const CliRun run = Cli("localize --model ENS --wav X.wav -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("member \"again\" is the directory of member \"member0\""));
}

// train, a fine-tune and a pseudo-label run fitted the scales on 1-2 validation strikes.
TEST_F(StatisticsRulesTest, TrainingCalibratesOnTheMinimumOrKeepsItsScalesAndSaysSo) {
  const json fresh = ReadJson(At("RUN") / "model.json")["uncertainty"];
  EXPECT_EQ(fresh["z_std_scale"], 1.0);
  EXPECT_EQ(fresh["kappa_scale"], 1.0);
  EXPECT_THAT(fresh["method"].get<std::string>(), HasSubstr("fewer than the 30 a fit needs; "
                                                            "scales 1 kept"));
  // a run calibrated on 56 strikes, fine-tuned and self-trained on 16 (3 validation strikes)
  CopyRun("PRE");
  Must("calibrate --model PRE --data d16.h5 --data d40.h5 -q");
  const json pre = ReadJson(At("PRE") / "model.json")["uncertainty"];
  ASSERT_NE(pre["z_std_scale"], 1.0);
  for (const std::string extra : {"", " --pseudo-labels 1"}) {
    const std::string out = extra.empty() ? "TUNED" : "SELF";
    const CliRun run =
        Cli("train --init-from PRE --data d16.h5 --tune fixed --epochs 1 -q --out " + out + extra);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    EXPECT_THAT(run.err, HasSubstr("interval scales not fitted"));
    const json u = ReadJson(At(out) / "model.json")["uncertainty"];
    EXPECT_EQ(u["z_std_scale"], pre["z_std_scale"]) << out;
    EXPECT_EQ(u["kappa_scale"], pre["kappa_scale"]) << out;
    EXPECT_THAT(u["method"].get<std::string>(),
                HasSubstr("a fit needs; the pretrained scales of PRE/model.json kept"))
        << out;
  }
}

// adapt re-estimated the normalization from one strike, and wrote inside the run it read.
TEST_F(StatisticsRulesTest, AdaptNeedsTheMinimumAndWritesOutsideItsRun) {
  const auto before = Snapshot(At("RUN"));
  CliRun run = Cli("adapt --model RUN --data d16.h5 --out A16 -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("d16.h5: 16 valid strike(s); adapt re-estimates the input and "
                                 "BatchNorm statistics on at least 30"));
  EXPECT_FALSE(fs::exists(At("A16")));
  run = Cli("adapt --model RUN --data d40.h5 --out RUN/sub -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("RUN/sub: --out lies inside an input (--model RUN)"));
  EXPECT_EQ(Snapshot(At("RUN")), before);
  run = Cli("adapt --model RUN --data d40.h5 --out A40 -q");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(At("A40") / "model.json"));
}

// A refused `train --resume` of a finished run left a copy of it as RUN.partial, and one of an
// interrupted run rewrote its config.yaml.
TEST_F(StatisticsRulesTest, ARefusedResumeLeavesNothingBehind) {
  const std::string wider = kShortRecordArgs +
                            "--set model.width=32 --set model.blocks=1 --set model.heads=2 "
                            "--set train.epochs=2 -q train --data d40.h5 --resume --out ";
  CopyRun("FINISHED");
  const auto finished = Snapshot(At("FINISHED"));
  CliRun run = Cli(wider + "FINISHED");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("the checkpoint was written for a different model config"));
  EXPECT_FALSE(fs::exists(At("FINISHED.partial")));
  EXPECT_FALSE(fs::exists(At("FINISHED.lock")));
  EXPECT_EQ(Snapshot(At("FINISHED")), finished);
  CopyRun("BROKEN.partial");
  const auto interrupted = Snapshot(At("BROKEN.partial"));
  run = Cli(wider + "BROKEN");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_EQ(Snapshot(At("BROKEN.partial")), interrupted);
  EXPECT_FALSE(fs::exists(At("BROKEN")));
}

// A finished run kept a checkpoint of three times its model (the weights again and Adam's two
// moments); it keeps the moments, and training it further is one longer run, bit for bit.
TEST_F(StatisticsRulesTest, AFinishedRunKeepsWhatResumingNeedsAndNoMore) {
  const auto model = static_cast<double>(fs::file_size(At("RUN") / "model.pt"));
  const auto checkpoint = static_cast<double>(fs::file_size(At("RUN") / "checkpoint.pt"));
  std::cout << "model.pt " << model << " bytes, checkpoint.pt " << checkpoint << " bytes\n";
  EXPECT_LT(checkpoint, 2.2 * model);
  EXPECT_GT(checkpoint, 1.8 * model);  // Adam's two moments of every weight
  CopyRun("LONGER");
  const std::string two =
      kShortRecordArgs + kTinyModelArgs + "--set train.epochs=2 -q train --data d40.h5 ";
  Must(two + "--out LONGER --resume");
  Must(two + "--out STRAIGHT");
  EXPECT_EQ(ReadBytes(At("LONGER") / "model.pt"), ReadBytes(At("STRAIGHT") / "model.pt"));
  EXPECT_EQ(ReadJson(At("LONGER") / "model.json")["epochs_trained"], 2);
}

// Messages of item 8 that named the wrong rate, no variable, the wrong reason or no file.
TEST_F(StatisticsRulesTest, MessagesNameTheFileAndTheValues) {
  // a 22.05 kHz dataset (closed-form modes: no solve at its band): its own config's rate beside
  // this command's
  Must(kShortRecordArgs +
       "--set audio.sample_rate_hz=22050 --set acoustics.model=modal-closed-form -q generate "
       "--count 2 --out d22.h5");
  CliRun run = Cli("--set features.gating=false -q train --data d22.h5 --out R22");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("d22.h5: records of 13230 frames at 22050 Hz (its own config: "
                                 "audio.record_duration_s = 0.6 s at audio.sample_rate_hz = "
                                 "22050 Hz), but this command's config reads "
                                 "audio.record_duration_s = 2 s at audio.sample_rate_hz = 44100 "
                                 "Hz, 88200 frames"));
  // the temporary directory by its variable
  run = RunCliEnv("-q geometry-check --count 1", Cwd(), {{"TMPDIR", "/nonexistent"}});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("TMPDIR=/nonexistent: not a directory"));
  // weights that are a device, by their kind
  fs::create_directories(At("ZERO"));
  for (const char* name : {"model.json", "config.yaml"}) {
    fs::copy_file(At("RUN") / name, At("ZERO") / name);
  }
  fs::create_symlink("/dev/zero", At("ZERO") / "model.pt");
  run = Cli("eval --model ZERO --data d40.h5 -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("ZERO/model.pt: is a character device"));
  // features of other shapes than the model's: the model's file and both shapes
  run = Cli("eval --model RUN --data d40.h5 -q --set features.n_mels=40");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("RUN/model.json: features to localize: mels = 40, but the model "
                                 "expects 50 (the features: audio 6 x 40 x "));
  EXPECT_THAT(run.err, HasSubstr("; the model's: audio 6 x 50 x "));
  // a dataset without rows has none to draw (it said "rows 0 to -1")
  DatasetInfo info;
  info.audio_frames = 26460;
  info.proprio_rows = 50;
  DatasetWriter(At("EMPTY.h5").string(), info).Finish();
  run = Cli("inspect EMPTY.h5 --png e.png --plot " + std::string(SONICBOOM_SOURCE_DIR) +
            "/scripts/plot.py");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("EMPTY.h5: holds no strikes"));
  EXPECT_FALSE(fs::exists(At("e.png")));
  EXPECT_FALSE(fs::exists(At("e.png.json")));
}

}  // namespace
}  // namespace sonicboom::experiments
