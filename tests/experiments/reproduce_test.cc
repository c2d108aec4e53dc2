// `reproduce --size smoke`: every stage runs into one report with its figures, a second run
// reuses every stage, a stage a stopped run left unfinished is run again and marked resumed, and a
// changed training key reruns the training and what reads it, not the data.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "internal/reproduce.h"
#include "sonicboom/core/files.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;

// stage -> whether a run of results.json reused it
std::map<std::string, bool> ReusedOf(const fs::path& results) {
  json r;
  std::ifstream(results) >> r;
  std::map<std::string, bool> reused;
  for (const json& s : r["wall_s"]) reused[s["stage"]] = s["reused"];
  return reused;
}

// the wall_s entry of one stage in results.json
json StageOf(const fs::path& results, const std::string& name) {
  json r;
  std::ifstream(results) >> r;
  for (const json& s : r["wall_s"]) {
    if (s["stage"] == name) return s;
  }
  return json();
}

TEST(ReproduceTest, SmokeWritesTheReportAndRerunsOnlyWhatAChangeTouches) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string source(SONICBOOM_SOURCE_DIR);
  // the configs with a pool of 4 structures instead of configs/randomized.yaml's (24 took 25 of
  // the first run's 60 s to set up): the same stages, files and checks at a sixth of the pool;
  // beside them, as in the checkout, the docs figure the report copies
  const fs::path checkout = dir.path() / "checkout", configs = checkout / "configs";
  fs::create_directories(checkout / "docs");
  fs::copy(source + "/configs", configs, fs::copy_options::recursive);
  fs::copy_file(source + "/docs/fidelity_pareto.png", checkout / "docs" / "fidelity_pareto.png");
  const std::string randomized = ReadText((configs / "randomized.yaml").string());
  const std::regex pool("\n  structure_variants: [0-9]+\n");
  ASSERT_TRUE(std::regex_search(randomized, pool)) << "configs/randomized.yaml sets no pool";
  WriteTextAtomic((configs / "randomized.yaml").string(),
                  std::regex_replace(randomized, pool, "\n  structure_variants: 4\n"));
  const std::string cmd = "--threads 2 -q reproduce --size smoke --out R --configs " +
                          configs.string() + " --plot " + source + "/scripts/plot.py";
  auto run = RunCli(cmd, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const fs::path out = dir.path() / "R";
  for (const char* file :
       {"report.md", "results.json", "errors.png", "ablation.png", "coverage_ts3.png",
        "map/map.png", "fidelity_pareto.png", "transfer.png"}) {
    EXPECT_TRUE(fs::is_regular_file(out / file)) << file;
  }
  json r;
  std::ifstream(out / "results.json") >> r;
  for (const char* ts : {"ts1", "ts2", "ts3", "ts4"}) {
    EXPECT_GT(r["scenarios"][ts]["n"].get<int64_t>(), 0) << ts;
    EXPECT_GT(r["scenarios"][ts]["med_cm"].get<double>(), 0.0) << ts;
  }
  EXPECT_EQ(r["scenarios"]["ts1"]["paper_med_cm"], 0.43);
  EXPECT_EQ(r["ablations"].size(), 2u);
  // the row of every modality is the scenario model's own run, copied; the others are trained
  EXPECT_EQ(fs::path(r["ablations"][0]["copied_from"].get<std::string>()).filename(), "model");
  EXPECT_TRUE(r["ablations"][1]["copied_from"].is_null());
  EXPECT_TRUE(r["preprocessing"][0]["copied_from"].is_null());
  // the preprocessing ablation: the lightweight network (configs/study_fast.yaml's) over the
  // scenario model's features, each layer's switch on top
  ASSERT_EQ(r["preprocessing"].size(), 2u);
  EXPECT_EQ(r["preprocessing"][0]["name"], "all");
  EXPECT_EQ(r["preprocessing"][0]["gating"], r["ablations"][0]["gating"]);
  EXPECT_EQ(r["preprocessing"][0]["gcc_span_s"], r["ablations"][0]["gcc_span_s"]);
  EXPECT_EQ(r["preprocessing"][1]["name"], "gcc_short");
  EXPECT_DOUBLE_EQ(r["preprocessing"][1]["gcc_span_s"].get<double>(), 0.1);
  EXPECT_GT(r["materials"]["n"].get<int64_t>(), 0);
  // the materials row broken down by the striker's material, which sum to it
  int64_t by_material = 0;
  for (const auto& [material, per] : r["materials"]["by_material"].items()) {
    EXPECT_TRUE(material == "wood" || material == "aluminium" || material == "pvc") << material;
    by_material += per["n"].get<int64_t>();
  }
  EXPECT_EQ(by_material, r["materials"]["n"].get<int64_t>());
  EXPECT_GT(r["map"]["chamfer_cm"].get<double>(), 0.0);
  // the true contact points, placed with the arm's pose at each contact, lie on the branch they
  // touched (0.6 mm RMS at quick size; 3.4 cm when the map used the last pose of a 0.5 s log)
  EXPECT_LT(r["map"]["true_surface_cm"].get<double>(), 0.3);
  EXPECT_GT(r["map"]["surface_cm"].get<double>(), 0.0);
  // the transfer study: the model and the arrival locator on both theories' render of ts4's
  // held-out strikes, the few-shot rows on the solid's
  const json& t = r["transfer"]["rows"];
  for (const char* row : {"zero_shot_shell", "zero_shot_solid", "arrival_shell", "arrival_solid"}) {
    EXPECT_EQ(t[row]["n"], r["scenarios"]["ts4"]["n"]) << row;
  }
  ASSERT_EQ(t["fewshot"].size(), 1u);
  EXPECT_GT(t["fewshot"][0]["tuned"]["med_cm"].get<double>(), 0.0);
  EXPECT_GT(t["fewshot"][0]["scratch"]["med_cm"].get<double>(), 0.0);
  std::ifstream report(out / "report.md");
  const std::string text((std::istreambuf_iterator<char>(report)), {});
  EXPECT_THAT(text, ::testing::HasSubstr("RMS Chamfer distance"));
  EXPECT_THAT(text, ::testing::HasSubstr("| ts4 |"));
  EXPECT_THAT(text, ::testing::HasSubstr("| fine-tuned on 12 solid strikes |"));
  EXPECT_THAT(text, ::testing::HasSubstr("## Preprocessing ablation (the lightweight model"));

  // the same command again: every stage reused
  run = RunCli(cmd, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const auto& [stage, reused] : ReusedOf(out / "results.json")) EXPECT_TRUE(reused) << stage;

  // the map's stage as a stopped process leaves it (begun, not stamped): run again and marked
  // resumed, since its wall time is the finishing process's share
  const fs::path stamps = out / "stamps";
  fs::copy_file(stamps / "map.key", stamps / "map.started");
  fs::remove(stamps / "map.key");
  run = RunCli(cmd, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_FALSE(StageOf(out / "results.json", "map")["reused"].get<bool>());
  EXPECT_TRUE(StageOf(out / "results.json", "map")["resumed"].get<bool>());
  EXPECT_FALSE(StageOf(out / "results.json", "train")["resumed"].get<bool>());
  EXPECT_FALSE(fs::exists(stamps / "map.started"));
  EXPECT_THAT(ReadText((out / "report.md").string()),
              ::testing::ContainsRegex("\\| map \\| [0-9.]+\\* \\| ran \\|"));

  // the model's stage as a process stopped in training leaves it: begun, not stamped, its run in
  // model.partial with a checkpoint (here after the last epoch). Run again, it resumes from the
  // checkpoint, so no epoch trains again and the epochs' log is the same to the byte (a fresh
  // training logs new epoch seconds); the model's key is the same, so what reads it is reused
  const std::string epochs_log = ReadText((out / "model" / "metrics.jsonl").string());
  fs::copy(out / "model", out / "model.partial", fs::copy_options::recursive);
  fs::copy_file(stamps / "train.key", stamps / "train.started");
  fs::remove(stamps / "train.key");
  run = RunCli(cmd, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(StageOf(out / "results.json", "train")["resumed"].get<bool>());
  EXPECT_EQ(ReadText((out / "model" / "metrics.jsonl").string()), epochs_log);
  EXPECT_FALSE(fs::exists(out / "model.partial"));
  EXPECT_TRUE(StageOf(out / "results.json", "eval_ts1")["reused"].get<bool>());

  // another learning rate: the data stay, the model and everything that reads it run again;
  // progress shown, the ETA from the cost model until enough has run to pace it (reused stages
  // take no time)
  std::string verbose = cmd;
  verbose.replace(verbose.find("-q "), 3, "");
  run = RunCli(verbose + " --set train.learning_rate=0.002", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out + run.err,
              ::testing::ContainsRegex("reproduce: [0-9]+ % of the work done, [0-9]+ s elapsed, "
                                       "ETA [0-9hms]+ \\(this project's 2-core machine's pace\\)"));
  const auto reused = ReusedOf(out / "results.json");
  // the user's layers reach the lightweight model's runs too
  std::ifstream light_config(out / "preprocessing" / "all" / "config.yaml");
  const std::string light((std::istreambuf_iterator<char>(light_config)), {});
  EXPECT_THAT(light, ::testing::HasSubstr("learning_rate: 0.002"));
  for (const char* stage : {"generate_train", "generate_ts1", "generate_ts3", "rerender_ts4"}) {
    EXPECT_TRUE(reused.at(stage)) << stage;
  }
  for (const char* stage :
       {"train", "eval_ts1", "eval_ts4", "eval_materials", "ablations", "preprocessing", "map",
        "train_transfer", "tune_shots12", "eval_tuned_shots12_ts4_solid"}) {
    EXPECT_FALSE(reused.at(stage)) << stage;
  }
  // rerun for a new key, the map is no longer a resumed stage
  EXPECT_FALSE(StageOf(out / "results.json", "map")["resumed"].get<bool>());
}

TEST(ReproduceTest, AnUnknownSizeOrMissingConfigsAreRefused) {
  TempDir dir;
  auto run = RunCli("reproduce --size huge --out R", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_THAT(run.err, ::testing::HasSubstr("--size huge"));
  run = RunCli("reproduce --size smoke --out R --configs nowhere", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_THAT(run.err, ::testing::HasSubstr("--configs nowhere"));
  EXPECT_FALSE(fs::exists(dir.path() / "R"));
}

TEST(ReproduceTest, CheckoutCommitReadsADetachedHeadALooseRefAndPackedRefs) {
  TempDir dir;
  const fs::path git = dir.path() / ".git";
  EXPECT_EQ(CheckoutCommit(dir.path()), "unknown");  // no checkout
  fs::create_directories(git / "refs" / "heads");
  const std::string a(40, 'a'), b(40, 'b');
  // a detached HEAD
  std::ofstream(git / "HEAD") << a << "\n";
  EXPECT_EQ(CheckoutCommit(dir.path()), a);
  // a branch whose ref is packed (after `git gc`), then one with a loose ref beside it
  std::ofstream(git / "HEAD") << "ref: refs/heads/main\n";
  std::ofstream(git / "packed-refs") << "# pack-refs with: peeled fully-peeled sorted\n"
                                     << b << " refs/heads/mainline\n"
                                     << a << " refs/heads/main\n";
  EXPECT_EQ(CheckoutCommit(dir.path()), a);
  std::ofstream(git / "refs" / "heads" / "main") << b << "\n";
  EXPECT_EQ(CheckoutCommit(dir.path()), b);
  // a branch with no commit yet
  std::ofstream(git / "HEAD") << "ref: refs/heads/other\n";
  EXPECT_EQ(CheckoutCommit(dir.path()), "unknown");
}

}  // namespace
}  // namespace sonicboom::experiments
