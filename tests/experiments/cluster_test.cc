// Generation on a cluster: shards from launcher variables, resumed shards, merged copies and
// virtual merges, and a real `mpirun -np 3` against one process, bit for bit.
#include "sonicboom/experiments/cluster.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "common/test_util.h"
#include "experiments/dataset_expect.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/pipeline.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::CliRun;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;
using sonicboom::testing::ThrownMessage;
using ::testing::HasSubstr;

// An environment of the given variables only.
EnvironmentLookup Env(std::map<std::string, std::string> vars) {
  return [vars = std::move(vars)](const char* name) -> const char* {
    const auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  };
}

TEST(ClusterTest, ShardsComeFromSlurmArraysAndMpiLaunchers) {
  // a 1-based Slurm array (--array=1-4): task 3 is shard 2 of 4
  ShardAssignment s = ShardFromEnvironment(Env({{"SLURM_ARRAY_TASK_ID", "3"},
                                                {"SLURM_ARRAY_TASK_MIN", "1"},
                                                {"SLURM_ARRAY_TASK_MAX", "4"},
                                                {"SLURM_ARRAY_TASK_COUNT", "4"}}));
  EXPECT_EQ(s.shard, 2);
  EXPECT_EQ(s.num_shards, 4);
  // Open MPI, PMI (MPICH, Intel MPI), PMIx, srun tasks
  s = ShardFromEnvironment(Env({{"OMPI_COMM_WORLD_RANK", "1"}, {"OMPI_COMM_WORLD_SIZE", "3"}}));
  EXPECT_EQ(s.shard, 1);
  EXPECT_EQ(s.num_shards, 3);
  s = ShardFromEnvironment(Env({{"PMI_RANK", "0"}, {"PMI_SIZE", "2"}}));
  EXPECT_EQ(s.num_shards, 2);
  s = ShardFromEnvironment(Env({{"PMIX_RANK", "5"}, {"PMI_SIZE", "8"}}));
  EXPECT_EQ(s.shard, 5);
  s = ShardFromEnvironment(Env({{"SLURM_PROCID", "7"}, {"SLURM_NTASKS", "8"}}));
  EXPECT_EQ(s.shard, 7);
  // an array job wins over the MPI variables of its step
  s = ShardFromEnvironment(Env({{"SLURM_ARRAY_TASK_ID", "0"},
                                {"SLURM_ARRAY_TASK_MIN", "0"},
                                {"SLURM_ARRAY_TASK_MAX", "9"},
                                {"SLURM_PROCID", "0"},
                                {"SLURM_NTASKS", "1"}}));
  EXPECT_EQ(s.num_shards, 10);
}

TEST(ClusterTest, BadLauncherVariablesAreRefusedNamingThem) {
  EXPECT_THAT(ThrownMessage<ConfigError>([] { ShardFromEnvironment(Env({})); }),
              HasSubstr("no launcher variables"));
  EXPECT_THAT(
      ThrownMessage<ConfigError>([] {
        ShardFromEnvironment(Env({{"OMPI_COMM_WORLD_RANK", "one"}, {"OMPI_COMM_WORLD_SIZE", "3"}}));
      }),
      HasSubstr("OMPI_COMM_WORLD_RANK='one'"));
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                ShardFromEnvironment(Env({{"PMI_RANK", "3"}, {"PMI_SIZE", "3"}}));
              }),
              HasSubstr("shard 3 of 3"));
  // a stepped array (--array=0-8:2) has gaps no shard numbering covers
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                ShardFromEnvironment(Env({{"SLURM_ARRAY_TASK_ID", "2"},
                                          {"SLURM_ARRAY_TASK_MIN", "0"},
                                          {"SLURM_ARRAY_TASK_MAX", "8"},
                                          {"SLURM_ARRAY_TASK_COUNT", "5"}}));
              }),
              HasSubstr("SLURM_ARRAY_TASK_COUNT = 5"));
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                ShardFromEnvironment(Env({{"SLURM_ARRAY_TASK_ID", "2"}}));
              }),
              HasSubstr("SLURM_ARRAY_TASK_MIN"));
}

TEST(ClusterTest, LauncherShardsNeedTheirOwnFiles) {
  EXPECT_EQ(ShardOutputPath("d-{shard}-of-{num_shards}.h5", {2, 4, "PMI_RANK/PMI_SIZE"}),
            "d-2-of-4.h5");
  EXPECT_THAT(ThrownMessage<ConfigError>([] {
                ShardOutputPath("d.h5", {1, 3, "OMPI_COMM_WORLD_RANK/SIZE"});
              }),
              HasSubstr("{shard}"));
  // a shard numbered by hand names its own file; one process of one shard needs no pattern
  EXPECT_EQ(ShardOutputPath("d1.h5", {1, 3, "--shard"}), "d1.h5");
  EXPECT_EQ(ShardOutputPath("d.h5", {0, 1, "PMI_RANK/PMI_SIZE"}), "d.h5");
}

// A writer killed after flushing leaves a partial file: the next run keeps its samples and
// writes the same dataset an uninterrupted run writes.
TEST(ClusterTest, AnInterruptedShardResumesFromItsPartialFile) {
  TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  GenerateDataset(config, dir / "whole.h5", {.count = 10, .threads = 2});
  {
    // the first 4 strikes of the same dataset, flushed, never finished
    const StrikePipeline pipeline(config);
    DatasetWriter killed(dir / "d.h5", GeneratedDatasetInfo(config, 0, 10, 0, 1));
    for (uint64_t i = 0; i < 4; ++i) killed.Append(pipeline.Simulate(i));
    killed.Flush();
    killed.Append(pipeline.Simulate(4));  // not flushed: not trusted
  }
  ASSERT_TRUE(fs::exists(dir / "d.h5.partial"));
  const GenerateResult r = GenerateDataset(config, dir / "d.h5", {.count = 10, .threads = 2});
  EXPECT_EQ(r.resumed, 4);
  EXPECT_EQ(r.written, 10);
  EXPECT_FALSE(fs::exists(dir / "d.h5.partial"));
  EXPECT_FALSE(fs::exists(dir / "d.h5.resume"));
  ExpectSameSamples(dir / "whole.h5", dir / "d.h5");

  // a partial of another dataset (another seed) is not resumed but replaced
  SonicBoomConfig other = config;
  other.seed = 12;
  {
    const StrikePipeline pipeline(other);
    DatasetWriter killed(dir / "e.h5", GeneratedDatasetInfo(other, 0, 10, 0, 1));
    for (uint64_t i = 0; i < 3; ++i) killed.Append(pipeline.Simulate(i));
    killed.Flush();
  }
  EXPECT_EQ(GenerateDataset(config, dir / "e.h5", {.count = 10, .threads = 2}).resumed, 0);
  ExpectSameSamples(dir / "whole.h5", dir / "e.h5");
}

// Two writers of one output: the second refuses (a lock) and leaves the first's work alone
// (it used to delete the first's .partial and start over).
TEST(ClusterTest, ASecondWriterOfAnOutputRefusesAndLeavesTheFirstsWork) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  std::ofstream(dir / "G.h5.partial") << "the first writer's samples";
  const OutputLock first(dir / "G.h5");  // this test process is the first writer
  const std::string pid = "pid " + std::to_string(::getpid());
  for (const char* command :
       {"generate --count 2 --out G.h5", "generate --count 2 --out G.h5 --force"}) {
    const auto run = RunCli(sonicboom::testing::kShortRecordArgs + command, cwd);
    EXPECT_EQ(run.exit_code, 1) << command << "\n" << run.err;
    EXPECT_THAT(run.err, HasSubstr("G.h5: another process (" + pid + ") is writing it")) << command;
  }
  std::ifstream partial(dir / "G.h5.partial");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(partial), {}), "the first writer's samples");
  EXPECT_FALSE(fs::exists(dir / "G.h5"));
  // a run being trained: a second trainer refuses and leaves its R.partial
  ASSERT_EQ(RunCli(sonicboom::testing::kShortRecordArgs + "-q generate --count 8 --out D.h5", cwd)
                .exit_code,
            0);
  fs::create_directories(dir / "R.partial");
  std::ofstream(dir.path() / "R.partial" / "checkpoint.pt") << "the first trainer's checkpoint";
  const OutputLock trainer(dir / "R");
  const auto run =
      RunCli(sonicboom::testing::kShortRecordArgs + sonicboom::testing::kTinyModelArgs +
                 "--set train.epochs=1 train --data D.h5 --out R",
             cwd);
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_THAT(run.err, HasSubstr("R: another process (" + pid + ") is writing it"));
  EXPECT_TRUE(fs::exists(dir.path() / "R.partial" / "checkpoint.pt"));
}

TEST(ClusterTest, VirtualMergeReadsTheShardsInPlace) {
  TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  fs::create_directories(dir.path() / "shards");
  GenerateDataset(config, dir / "whole.h5", {.count = 9, .threads = 2});
  for (int s = 0; s < 3; ++s) {
    GenerateDataset(config, dir / ("shards/s" + std::to_string(s) + ".h5"),
                    {.count = 9, .shard = s, .num_shards = 3});
  }
  const std::vector<std::string> shards = {dir / "shards/s2.h5", dir / "shards/s0.h5",
                                           dir / "shards/s1.h5"};
  MergeDatasets(shards, dir / "virtual.h5", /*virtual_audio=*/true);
  ExpectSameSamples(dir / "whole.h5", dir / "virtual.h5");
  // no audio copied: the virtual file is a small fraction of the copy
  MergeDatasets(shards, dir / "copy.h5");
  EXPECT_LT(fs::file_size(dir / "virtual.h5"), fs::file_size(dir / "copy.h5") / 3);
  // moved together, the files still find each other (sources are relative to the merged file)
  const fs::path moved = dir.path().string() + "-moved";
  fs::copy(dir.path(), moved, fs::copy_options::recursive);
  fs::rename(dir.path() / "shards", dir.path() / "shards-away");  // not read by the copy
  ExpectSameSamples((moved / "whole.h5").string(), (moved / "virtual.h5").string());
  fs::rename(dir.path() / "shards-away", dir.path() / "shards");
  fs::remove_all(moved);
  // a shard rendered again from the same seed and range is the same shard
  fs::remove(dir / "shards/s1.h5");
  GenerateDataset(config, dir / "shards/s1.h5", {.count = 9, .shard = 1, .num_shards = 3});
  ExpectSameSamples(dir / "whole.h5", dir / "virtual.h5");
  // a shard of another seed under the same name: refused, never read under these labels
  SonicBoomConfig other = config;
  other.seed = config.seed + 1;
  fs::remove(dir / "shards/s1.h5");
  GenerateDataset(other, dir / "shards/s1.h5", {.count = 9, .shard = 1, .num_shards = 3});
  EXPECT_THAT(ThrownMessage<SchemaError>([&] { DatasetReader reader(dir / "virtual.h5"); }),
              HasSubstr("s1.h5 changed since the merge"));
  // garbage under its name: refused naming the shard (libhdf5 would read silence)
  std::ofstream(dir / "shards/s1.h5", std::ios::trunc) << "not a dataset";
  EXPECT_THAT(ThrownMessage<SchemaError>([&] { DatasetReader reader(dir / "virtual.h5"); }),
              HasSubstr("s1.h5 (merge --virtual reads it in place) cannot be read"));
  // a virtual merge over a virtual merge: refused when made
  EXPECT_THAT(ThrownMessage<SchemaError>([&] {
                MergeDatasets({dir / "virtual.h5"}, dir / "chain.h5", /*virtual_audio=*/true);
              }),
              HasSubstr("s1.h5"));
  fs::remove(dir / "shards/s1.h5");
  GenerateDataset(config, dir / "shards/s1.h5", {.count = 9, .shard = 1, .num_shards = 3});
  EXPECT_THAT(ThrownMessage<SchemaError>([&] {
                MergeDatasets({dir / "virtual.h5"}, dir / "chain.h5", /*virtual_audio=*/true);
              }),
              HasSubstr("is itself a virtual merge"));
  // a shard gone: refused by name, never read as silence
  fs::remove(dir / "shards/s1.h5");
  EXPECT_THAT(ThrownMessage<SchemaError>([&] { DatasetReader reader(dir / "virtual.h5"); }),
              HasSubstr("s1.h5, which is missing"));
}

// The unchanged command under `mpirun -np 3` (Debian's Open MPI) writes three shards that merge
// into the file one process writes, bit for bit.
TEST(ClusterTest, MpirunShardsMergeToTheSingleProcessDataset) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string args = sonicboom::testing::kShortRecordArgs + "-q --threads 1 --seed 11 ";
  ASSERT_EQ(RunCli(args + "generate --count 12 --out single.h5", cwd).exit_code, 0);
  std::vector<std::string> mpirun = {"mpirun", "--allow-run-as-root", "--oversubscribe", "-np",
                                     "3", SONICBOOM_CLI};
  for (std::string& word : sonicboom::testing::SplitArgs(args)) mpirun.push_back(word);
  mpirun.insert(mpirun.end(), {"generate", "--count", "12", "--shard", "auto", "--out",
                               "m-{shard}.h5"});
  // an empty rsh agent: Open MPI starts the ranks on this machine without ssh
  const sonicboom::testing::ProcessEnv env = {{"OMPI_MCA_plm_rsh_agent", std::string()}};
  auto run_mpirun = [&] {
    const CliRun run = sonicboom::testing::RunProgram(mpirun, cwd, env);
    return run.exit_code == 0 ? std::string() : run.err;
  };
  ASSERT_EQ(run_mpirun(), "");
  for (int s = 0; s < 3; ++s) {
    const DatasetReader shard(dir / ("m-" + std::to_string(s) + ".h5"));
    EXPECT_EQ(shard.info().shard, s);
    EXPECT_EQ(shard.info().num_shards, 3);
    EXPECT_EQ(shard.size(), 4);
  }
  ASSERT_EQ(RunCli("-q merge --out merged.h5 m-0.h5 m-1.h5 m-2.h5", cwd).exit_code, 0);
  ExpectSameSamples(dir / "single.h5", dir / "merged.h5");
  // a rerun of the finished job changes nothing: every shard is skipped
  const auto before = fs::last_write_time(dir / "m-1.h5");
  ASSERT_EQ(run_mpirun(), "");
  EXPECT_EQ(fs::last_write_time(dir / "m-1.h5"), before);
}

// Per-epoch training losses of a run (metrics.jsonl).
std::vector<double> TrainLosses(const fs::path& run) {
  std::vector<double> losses;
  std::ifstream in(run / "metrics.jsonl");
  for (std::string line; std::getline(in, line);) {
    const size_t at = line.find("\"train_loss\":");
    if (at != std::string::npos) losses.push_back(std::stod(line.substr(at + 13)));
  }
  return losses;
}

// Two processes through scripts/cluster/train_ddp.sh (c10d over Gloo, RANK/WORLD_SIZE/MASTER_*)
// train the model one process trains on the same global batch: with no BatchNorm and no dropout
// in the model (GCC-PHAT through its MLP encoder) the per-epoch losses agree to 1e-3 (summation
// order only); rank 1 writes nothing.
TEST(ClusterTest, TwoProcessTrainingFollowsTheOneProcessLossCurve) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  ASSERT_EQ(RunCli(sonicboom::testing::kShortRecordArgs + "-q generate --count 60 --out D.h5", cwd)
                .exit_code,
            0);
  const std::string model =
      sonicboom::testing::kShortRecordArgs +
      "-q --set model.width=16 --set model.blocks=1 --set model.heads=2 --set model.dropout=0 "
      "--set model.modalities=[gcc] --set train.batch_size=16 --set train.epochs=4 ";
  ASSERT_EQ(RunCli("--threads 1 " + model + "train --data D.h5 --out ONE", cwd).exit_code, 0);
  std::vector<std::string> ddp = {
      "bash", std::string(SONICBOOM_SOURCE_DIR) + "/scripts/cluster/train_ddp.sh", "2", "D.h5",
      "TWO"};
  for (std::string& word : sonicboom::testing::SplitArgs(model)) ddp.push_back(word);
  const CliRun two_process = sonicboom::testing::RunProgram(
      ddp, cwd,
      {{"SONICBOOM_BIN", SONICBOOM_CLI},
       {"MASTER_PORT", std::to_string(29500 + getpid() % 2000)},
       {"THREADS", "1"}});
  ASSERT_EQ(two_process.exit_code, 0) << two_process.err;
  const std::vector<double> one = TrainLosses(dir.path() / "ONE"),
                            two = TrainLosses(dir.path() / "TWO");
  ASSERT_EQ(one.size(), 4u);
  ASSERT_EQ(two.size(), 4u);
  for (size_t e = 0; e < one.size(); ++e) {
    EXPECT_NEAR(two[e] / one[e], 1.0, 1e-3) << "epoch " << e + 1;
  }
  EXPECT_LT(one.back(), one.front());  // it did learn
  EXPECT_TRUE(fs::exists(dir.path() / "TWO" / "model.pt"));
  EXPECT_FALSE(fs::exists(dir.path() / "TWO.partial"));
}

}  // namespace
}  // namespace sonicboom::experiments
