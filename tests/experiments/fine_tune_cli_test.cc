// `train --init-from RUN` chooses its fine-tune by cross-validation (--tune auto, the default):
// fine_tune.json records the candidates' folds and the choice, which is never worse on the folds
// than the pretrained run; too few strikes and conflicting options are refused; a recipe given
// is trained as before.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "common/workspace.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sonicboom::testing::CliRun;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::ReadBytes;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;
using ::testing::HasSubstr;

// The suite's workspace: a tiny run pretrained on 40 short strikes, 12 and 4 more of the same kind.
void BuildWorkspace(const fs::path& dir) {
  sonicboom::testing::RunEach(
      {kShortRecordArgs + "-q generate --count 40 --out P.h5",
       kShortRecordArgs + "-q generate --count 12 --first-index 2000 --out F12.h5",
       kShortRecordArgs + "-q generate --count 4 --first-index 3000 --out F4.h5",
       kShortRecordArgs + kTinyModelArgs + "--set train.epochs=3 -q train --data P.h5 --out PRE"},
      dir);
}

constexpr sonicboom::testing::Workspace kWorkspace{"fine_tune_cli", BuildWorkspace};

// Built once per ctest run (the suite's fixture) for its tests to copy
TEST(FineTuneCliWorkspace, IsBuilt) {
  sonicboom::testing::PublishWorkspace(kWorkspace);
}

// Each test process works in its own copy of the workspace
class FineTuneCliTest : public sonicboom::testing::WorkspaceTest<kWorkspace> {
 protected:
  static CliRun Cli(const std::string& args) { return RunCli(args, dir_->path().string()); }
  static fs::path At(const std::string& name) { return dir_->path() / name; }
  static json ReadJson(const std::string& name) { return json::parse(ReadBytes(At(name))); }
};

TEST_F(FineTuneCliTest, AutoRecordsItsCandidatesAndIsNeverWorseOnTheFolds) {
  const CliRun run = Cli("train --init-from PRE --data F12.h5 --out AUTO --epochs 1 -q --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = ReadJson("AUTO/fine_tune.json");
  EXPECT_EQ(json::parse(run.out)["fine_tune"], j);
  EXPECT_EQ(j["tune"], "auto");
  EXPECT_EQ(j["strikes"], 12);
  EXPECT_EQ(j["folds"], 5);
  EXPECT_EQ(j["epochs"], 1);
  ASSERT_EQ(j["candidates"].size(), 3u);
  EXPECT_EQ(j["candidates"][0]["name"], "pretrained");
  EXPECT_EQ(j["candidates"][1]["freeze"], "all-but-head");
  EXPECT_EQ(j["candidates"][1]["learning_rate"], 1e-4);
  EXPECT_EQ(j["candidates"][2]["freeze"], "none");
  EXPECT_EQ(j["candidates"][2]["learning_rate"], 3e-4);
  double chosen_cm = -1.0;
  for (const json& c : j["candidates"]) {
    EXPECT_EQ(c["fold_med_cm"].size(), 5u) << c["name"];
    if (c["name"] == j["chosen"]) chosen_cm = c["mean_med_cm"].get<double>();
  }
  // the choice is not worse on the folds than the pretrained weights
  ASSERT_GT(chosen_cm, 0.0) << j.dump(2);
  EXPECT_LE(chosen_cm, j["candidates"][0]["mean_med_cm"].get<double>());
  EXPECT_EQ(json::parse(run.out)["held_out"]["n"], 12);
  EXPECT_FALSE(fs::exists(At("AUTO/cross_validation")));
  if (j["chosen"] == "pretrained") {
    // the pretrained run kept as it is, calibration included
    EXPECT_EQ(ReadBytes(At("AUTO/model.pt")), ReadBytes(At("PRE/model.pt")));
    EXPECT_EQ(ReadJson("AUTO/model.json")["uncertainty"],
              ReadJson("PRE/model.json")["uncertainty"]);
  }
}

TEST_F(FineTuneCliTest, TooFewStrikesOrARecipeBesideAutoAreRefused) {
  CliRun run = Cli("train --init-from PRE --data F4.h5 --out FEW -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err,
              HasSubstr("4 labelled strikes: --tune auto cross-validates over at least 5"));
  EXPECT_FALSE(fs::exists(At("FEW")));
  EXPECT_FALSE(fs::exists(At("FEW.partial")));
  run = Cli("train --init-from PRE --data F12.h5 --out X --tune auto --lr 1e-3 -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("--tune auto chooses the freeze mode and learning rate itself"));
  run = Cli("train --data F12.h5 --out X --tune auto -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("give --init-from RUN"));
  run = Cli("train --init-from PRE --data F12.h5 --out X --tune auto --pseudo-labels 0.5 -q");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("--pseudo-labels replaces"));
  run = Cli("train --init-from PRE --data F12.h5 --out X --tune best -q");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_FALSE(fs::exists(At("X")));
}

TEST_F(FineTuneCliTest, AGivenRecipeIsTrainedAsGiven) {
  const CliRun run =
      Cli("train --init-from PRE --data F12.h5 --out FIXED --freeze all-but-head "
          "--epochs 1 -q");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(ReadJson("FIXED/fine_tune.json"),
            (json{{"init_from", "PRE"}, {"freeze", "all-but-head"}, {"norm", "keep"}}));
}

}  // namespace
}  // namespace sonicboom::experiments
