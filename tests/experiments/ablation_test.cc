// `sonicboom ablate`: every config of a directory trained and evaluated into one table;
// finished runs reused, a variant identical to a given run copied, a diverged one reported; a bad
// config refused before any training.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/test_util.h"

namespace sonicboom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using testing::RunCli;
using testing::TempDir;

const std::string kTiny =
    testing::kShortRecordArgs + testing::kTinyModelArgs + "--set train.epochs=1 ";

void Write(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

TEST(AblateTest, TrainsEveryConfigIntoOneTableAndReusesFinishedRuns) {
  TempDir dir;
  ASSERT_EQ(RunCli(kTiny + "generate --count 24 --out D.h5 -q", dir.path().string()).exit_code, 0);
  ASSERT_EQ(
      RunCli(kTiny + "generate --count 8 --first-index 100 --out T.h5 -q", dir.path().string())
          .exit_code,
      0);
  // a second held-out set (paper Fig. 6 scores the ablations on every scenario)
  ASSERT_EQ(
      RunCli(kTiny + "generate --count 5 --first-index 200 --out U.h5 -q", dir.path().string())
          .exit_code,
      0);
  Write(dir / "abl/01-all.yaml", "# every modality\n{}\n");
  Write(dir / "abl/02-proprio.yaml", "# proprioception only\nmodel:\n  modalities: [proprio]\n");
  Write(dir / "abl/03-no_norm.yaml",
        "# no normalization\ntrain:\n  normalize: false\nfeatures:\n  gcc_window_s: 0.1\n");
  const std::string cmd =
      kTiny + "ablate --data D.h5 --test T.h5 --test U.h5 --out A --configs abl --json -q";
  auto run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  ASSERT_EQ(j["ablations"].size(), 3u);
  // file order, numeric prefix dropped, layers applied
  EXPECT_EQ(j["ablations"][0]["name"], "all");
  EXPECT_EQ(j["ablations"][1]["name"], "proprio");
  EXPECT_EQ(j["ablations"][1]["modalities"], json({"proprio"}));
  EXPECT_EQ(j["ablations"][2]["normalize"], false);
  EXPECT_EQ(j["ablations"][0]["gcc_span_s"], 1.5);
  EXPECT_EQ(j["ablations"][2]["gcc_span_s"], 0.1);
  EXPECT_EQ(j["ablations"][0]["description"], "every modality");
  for (const json& row : j["ablations"]) {
    EXPECT_EQ(row["test"]["n"], 8) << row.dump();
    // every test set scored, the first one's errors the row's own
    ASSERT_EQ(row["tests"].size(), 2u) << row.dump();
    EXPECT_EQ(row["tests"][0]["test"], row["test"]);
    EXPECT_EQ(row["tests"][1]["data"], "U.h5");
    EXPECT_EQ(row["tests"][1]["test"]["n"], 5) << row.dump();
    EXPECT_GT(row["test"]["med_cm"].get<double>(), 0.0) << row.dump();
    EXPECT_TRUE(fs::exists(dir.path() / "A" / row["name"].get<std::string>() / "model.json"));
  }
  // the proprio-only run has no audio encoder: its model differs from the full one
  std::ifstream full(dir / "A/all/model.json"), prop(dir / "A/proprio/model.json");
  EXPECT_NE(json::parse(full)["model"].dump(), json::parse(prop)["model"].dump());
  std::ifstream table(dir / "A/table.md");
  const std::string text((std::istreambuf_iterator<char>(table)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| proprio | proprio |"), std::string::npos) << text;
  EXPECT_NE(text.find("| MED T (cm) | MED U (cm) |"), std::string::npos) << text;

  // a second run reuses every finished run: identical rows, training time included
  run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json again = json::parse(run.out);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(again["ablations"][i]["train_s"], j["ablations"][i]["train_s"]);
    // the same model files (torch's thread count may differ without training: float reductions)
    EXPECT_NEAR(again["ablations"][i]["test"]["med_cm"].get<double>(),
                j["ablations"][i]["test"]["med_cm"].get<double>(), 1e-6);
  }

  // a changed layer file: that variant alone is trained again, not taken from its old run
  Write(dir / "abl/02-proprio.yaml",
        "# proprioception only\nmodel:\n  modalities: [proprio]\ntrain:\n  learning_rate: 0.01\n");
  const auto old_time = fs::last_write_time(dir / "A/proprio/model.json");
  const auto kept_time = fs::last_write_time(dir / "A/all/model.json");
  run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(fs::last_write_time(dir / "A/proprio/model.json"), old_time);
  EXPECT_EQ(fs::last_write_time(dir / "A/all/model.json"), kept_time);
  std::ifstream config(dir / "A/proprio/config.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(config)),
                         std::istreambuf_iterator<char>());
  EXPECT_NE(yaml.find("learning_rate: 0.01"), std::string::npos);
}

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(AblateTest, VariantIdenticalToAGivenRunIsCopiedNotTrained) {
  TempDir dir;
  ASSERT_EQ(RunCli(kTiny + "generate --count 16 --out D.h5 -q", dir.path().string()).exit_code, 0);
  auto run = RunCli(kTiny + "train --data D.h5 --out M -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  Write(dir / "abl/01-all.yaml", "# every modality\n{}\n");
  Write(dir / "abl/02-proprio.yaml", "# proprioception only\nmodel:\n  modalities: [proprio]\n");
  const std::string cmd =
      kTiny + "ablate --data D.h5 --test D.h5 --out A --configs abl --reuse M --json";
  run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  json j = json::parse(run.out);
  // `all` is M's network on M's strikes: M's files and training time, said in the row and table
  EXPECT_EQ(ReadAll(dir / "A/all/model.pt"), ReadAll(dir / "M/model.pt"));
  EXPECT_EQ(ReadAll(dir / "A/all/metrics.jsonl"), ReadAll(dir / "M/metrics.jsonl"));
  EXPECT_EQ(j["ablations"][0]["copied_from"], "M");
  double m_seconds = 0.0;
  std::ifstream metrics(dir / "M/metrics.jsonl");
  for (std::string line; std::getline(metrics, line);) {
    m_seconds += json::parse(line)["epoch_seconds"].get<double>();
  }
  EXPECT_DOUBLE_EQ(j["ablations"][0]["train_s"].get<double>(), m_seconds);
  EXPECT_NE(run.err.find("copied"), std::string::npos) << run.err;
  // another config is trained: not M's network
  EXPECT_TRUE(j["ablations"][1]["copied_from"].is_null());
  EXPECT_NE(ReadAll(dir / "A/proprio/model.pt"), ReadAll(dir / "M/model.pt"));
  EXPECT_NE(ReadAll(dir / "A/table.md").find("\\* all: copied from M"), std::string::npos);
  // reused on a second run, still said to be a copy
  run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["ablations"][0]["copied_from"], "M");
  // a run that is not a finished one is refused, naming the option
  run = RunCli(kTiny + "ablate --data D.h5 --test D.h5 --out B --configs abl --reuse nowhere",
               dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--reuse nowhere"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "B/all"));
}

TEST(AblateTest, AVariantWhoseTrainingDivergesIsARowNotTheEndOfTheOthers) {
  TempDir dir;
  ASSERT_EQ(RunCli(kTiny + "generate --count 16 --out D.h5 -q", dir.path().string()).exit_code, 0);
  // the blown-up rate makes the loss non-finite within its epochs; the variant after it still runs
  Write(dir / "abl/01-blowup.yaml",
        "# a rate no network survives\ntrain:\n  learning_rate: 1.0e+30\n  epochs: 3\n");
  Write(dir / "abl/02-all.yaml", "# every modality\n{}\n");
  const std::string cmd = kTiny + "ablate --data D.h5 --test D.h5 --out A --configs abl --json -q";
  auto run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  ASSERT_EQ(j["ablations"].size(), 2u);
  const json& blowup = j["ablations"][0];
  ASSERT_TRUE(blowup["diverged"].is_string()) << blowup.dump();
  EXPECT_NE(blowup["diverged"].get<std::string>().find("training loss became"), std::string::npos)
      << blowup.dump();
  EXPECT_TRUE(blowup["test"].is_null()) << blowup.dump();
  EXPECT_TRUE(blowup["tests"][0]["test"].is_null()) << blowup.dump();
  EXPECT_FALSE(fs::exists(dir / "A/blowup/model.json"));
  // the next variant trained and scored as usual
  EXPECT_TRUE(j["ablations"][1]["diverged"].is_null());
  EXPECT_EQ(j["ablations"][1]["test"]["n"], 16);
  const std::string table = ReadAll(dir / "A/table.md");
  EXPECT_NE(table.find("(16 strikes)"), std::string::npos) << table;
  EXPECT_NE(table.find("| diverged† | diverged† | diverged† |"), std::string::npos) << table;
  EXPECT_NE(table.find("† blowup: not scored; training loss became"), std::string::npos) << table;
  // a rerun keeps the finding: not trained again
  const auto mark = fs::last_write_time(dir / "A/blowup/ablation_diverged.txt");
  run = RunCli(cmd, dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["ablations"][0]["diverged"], blowup["diverged"]);
  EXPECT_EQ(fs::last_write_time(dir / "A/blowup/ablation_diverged.txt"), mark);
}

TEST(AblateTest, BadConfigIsRefusedBeforeAnyTraining) {
  TempDir dir;
  ASSERT_EQ(RunCli(kTiny + "generate --count 4 --out D.h5 -q", dir.path().string()).exit_code, 0);
  Write(dir / "abl/01-all.yaml", "{}\n");
  Write(dir / "abl/02-typo.yaml", "model:\n  modalitys: [audio]\n");
  auto run =
      RunCli(kTiny + "ablate --data D.h5 --test D.h5 --out A --configs abl", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("02-typo.yaml"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("modalitys"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "A/all/model.json"));
  // an unknown --only name and an empty directory are refused too
  run = RunCli("ablate --data D.h5 --test D.h5 --out A --configs abl --only nothing",
               dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("nothing"), std::string::npos) << run.err;
  fs::create_directories(dir / "empty");
  run = RunCli("ablate --data D.h5 --test D.h5 --out A --configs empty", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("no ablation"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace sonicboom
