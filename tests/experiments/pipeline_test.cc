// Determinism of generated data across thread counts and shards.
#include <gtest/gtest.h>

#include "common/test_util.h"
#include "experiments/dataset_expect.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/experiments/pipeline.h"

namespace sonicboom::experiments {
namespace {

TEST(PipelineTest, BitIdenticalForOneAndTwoThreads) {
  testing::TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  GenerateDataset(config, dir / "t1.h5", {.count = 12});
  GenerateDataset(config, dir / "t2.h5", {.count = 12, .threads = 2});
  ExpectSameSamples(dir / "t1.h5", dir / "t2.h5");
}

TEST(PipelineTest, ShardsMergeToTheSingleFile) {
  testing::TempDir dir;
  const SonicBoomConfig config = ShortConfig();
  GenerateDataset(config, dir / "all.h5", {.count = 9, .threads = 2});
  GenerateDataset(config, dir / "s0.h5", {.count = 9, .num_shards = 2});
  GenerateDataset(config, dir / "s1.h5", {.count = 9, .shard = 1, .num_shards = 2, .threads = 2});
  MergeDatasets({dir / "s1.h5", dir / "s0.h5"}, dir / "merged.h5");
  ExpectSameSamples(dir / "all.h5", dir / "merged.h5");
}

TEST(PipelineTest, MujocoEngineHitsWhereTheKinematicStrikeAims) {
  // the default engine is the dynamic rollout; it lands within 1 mm of the kinematic target
  SonicBoomConfig dynamic = ShortConfig();
  ASSERT_EQ(dynamic.strike.engine, sim::StrikeEngine::kMujoco);
  SonicBoomConfig kinematic = dynamic;
  kinematic.strike.engine = sim::StrikeEngine::kKinematic;
  const StrikePipeline a(dynamic), b(kinematic);
  for (uint64_t i = 0; i < 4; ++i) {
    const StrikeSample sa = a.Simulate(i), sb = b.Simulate(i);
    ASSERT_TRUE(sa.valid) << sa.invalid_reason;
    EXPECT_NEAR(sa.label.z_m, sb.label.z_m, 1e-3);
    EXPECT_NE(sa.label.z_m, sb.label.z_m);  // a real contact, not the kinematic label
    EXPECT_GT(sa.label.impulse_Ns, 0.0);
    EXPECT_TRUE(sa.audio.allFinite());
    // the rollout keeps every contact; the first is the impact that acoustics played
    ASSERT_FALSE(sa.contacts.empty());
    EXPECT_EQ(sa.contacts.front().kind, ContactEpisode::Kind::kImpact);
    EXPECT_EQ(sa.contacts.front().z_m, sa.label.z_m);
    EXPECT_EQ(sa.contacts.front().object, "rod T22L42");
    ASSERT_EQ(sb.contacts.size(), 1u);
  }
}

TEST(PipelineTest, SplitDependsOnlyOnSampleIndex) {
  std::vector<uint64_t> idx(1000);
  for (uint64_t i = 0; i < idx.size(); ++i) idx[i] = i;
  const auto [train, val] = SplitRows(idx, 0.2, 3);
  EXPECT_NEAR(static_cast<double>(val.size()) / idx.size(), 0.2, 0.04);
  EXPECT_EQ(train.size() + val.size(), idx.size());
  // the same indices in another order land on the same side
  std::vector<uint64_t> rev(idx.rbegin(), idx.rend());
  const auto [train_r, val_r] = SplitRows(rev, 0.2, 3);
  ASSERT_EQ(val_r.size(), val.size());
  std::vector<uint64_t> a, b;
  for (auto r : val) a.push_back(idx[r]);
  for (auto r : val_r) b.push_back(rev[r]);
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace sonicboom::experiments
