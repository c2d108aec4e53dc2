// The baselines on dataset files: one kNN fit shared by several test sets scores them exactly as
// a fit of its own would, a changed setting fits again and the worker count is no setting.
#include <gtest/gtest.h>

#include <memory>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/commands.h"

namespace sonicboom {
namespace {

using nlohmann::json;
using testing::RunCli;
using testing::TempDir;

TEST(KnnFitsTest, OneFitScoresEveryTestSetAsItsOwnFitWould) {
  TempDir dir;
  const std::string gen = testing::kShortRecordArgs + "generate -q ";
  ASSERT_EQ(RunCli(gen + "--count 12 --out D.h5", dir.path().string()).exit_code, 0);
  ASSERT_EQ(RunCli(gen + "--count 6 --first-index 100 --out T.h5", dir.path().string()).exit_code,
            0);
  experiments::GlobalOptions g;
  g.threads = 1;
  g.quiet = true;
  experiments::BaselineOptions o;
  o.method = experiments::BaselineMethod::kKnn;
  o.k = 1;
  o.knn_gcc_lags = 20;
  o.train = dir / "D.h5";
  auto fits = std::make_shared<experiments::KnnFits>();

  // its own training strikes, then held-out ones, with one fit
  o.data = o.train;
  o.knn_fits = fits;
  EXPECT_LT(json::parse(experiments::RunBaseline(g, o).json)["med_cm"].get<double>(), 1e-6);
  o.data = dir / "T.h5";
  const json shared = json::parse(experiments::RunBaseline(g, o).json);
  EXPECT_EQ(fits->fitted(), 1);
  EXPECT_EQ(shared["n"], 6);
  EXPECT_GT(shared["med_cm"].get<double>(), 0.0);
  // the same figures as a fit made for T.h5 alone
  o.knn_fits = nullptr;
  EXPECT_EQ(json::parse(experiments::RunBaseline(g, o).json).dump(), shared.dump());

  // another neighbourhood fits again
  o.knn_fits = fits;
  o.k = 3;
  const json k3 = json::parse(experiments::RunBaseline(g, o).json);
  EXPECT_EQ(fits->fitted(), 2);
  EXPECT_EQ(k3["k"], 3);
  // another worker count changes nothing in the fit; other GCC lags do
  g.threads = 2;
  EXPECT_EQ(json::parse(experiments::RunBaseline(g, o).json).dump(), k3.dump());
  EXPECT_EQ(fits->fitted(), 2);
  o.knn_gcc_lags = 10;
  experiments::RunBaseline(g, o);
  EXPECT_EQ(fits->fitted(), 3);
}

}  // namespace
}  // namespace sonicboom
