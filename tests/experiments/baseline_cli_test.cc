// `sonicboom baseline`: the metrics JSON of every method on a tiny dataset, and its error paths;
// `localize --method arrival`, the same training-free locator on one WAV.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/audio_io.h"

namespace sonicboom {
namespace {

using nlohmann::json;
using testing::RunCli;
using testing::TempDir;

// short records keep the end-to-end test fast
const std::string kShort = testing::kShortRecordArgs;

void ExpectMetricsKeys(const json& j) {
  for (const char* key :
       {"n", "med_cm", "height_err_cm", "angle_err_deg", "reference_med_cm", "method"}) {
    EXPECT_TRUE(j.contains(key)) << key << " in " << j.dump();
  }
}

TEST(BaselineCliTest, KnnTdoaAndConstantOnATinyDataset) {
  TempDir dir;
  auto run = RunCli(kShort + "generate --count 12 --out D.h5 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;

  // kNN with one neighbour on its own training set recovers every label
  run =
      RunCli("baseline --method knn --k 1 --train D.h5 --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  json j = json::parse(run.out);
  ExpectMetricsKeys(j);
  EXPECT_EQ(j["method"], "knn");
  EXPECT_EQ(j["n"], 12);
  EXPECT_LT(j["med_cm"].get<double>(), 1e-6);

  // with five neighbours and GCC lags in the vector, an exact match still takes all the weight
  run = RunCli("baseline --method knn --gcc-lags 20 --train D.h5 --data D.h5 --json -q",
               dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  j = json::parse(run.out);
  EXPECT_EQ(j["dimensions"], 6 * 50 * 23 + 15 * 41);
  EXPECT_LT(j["med_cm"].get<double>(), 1e-6);

  // the constant predictor
  run =
      RunCli("baseline --method constant --train D.h5 --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  j = json::parse(run.out);
  ExpectMetricsKeys(j);
  EXPECT_GT(j["med_cm"].get<double>(), 0.5);

  // analytic TDOA without training data: a finite error, scale 1
  run = RunCli("baseline --method tdoa --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  j = json::parse(run.out);
  ExpectMetricsKeys(j);
  EXPECT_EQ(j["n"], 12);
  EXPECT_TRUE(std::isfinite(j["med_cm"].get<double>()));
  EXPECT_EQ(j["speed_scale"].get<double>(), 1.0);
  EXPECT_EQ(j["band_speeds_m_s"].size(), 4u);

  // the arrival locator without training: every strike located, a physical speed, and better
  // than the constant predictor on the same strikes
  run = RunCli("baseline --method arrival --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  j = json::parse(run.out);
  ExpectMetricsKeys(j);
  EXPECT_EQ(j["n"], 12);
  EXPECT_LT(j["med_cm"].get<double>(), 6.0);
  EXPECT_GE(j["median_speed_m_s"].get<double>(), 150.0);
  EXPECT_LE(j["median_speed_m_s"].get<double>(), 3000.0);
  run = RunCli("baseline --method arrival --set arrival.peak_fraction=1.5 --data D.h5 -q",
               dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("arrival.peak_fraction"), std::string::npos) << run.err;

  // the human-readable report names the method
  run = RunCli("baseline --method constant --train D.h5 --data D.h5 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("constant baseline, 12 strikes: MED"), std::string::npos) << run.out;
}

TEST(BaselineCliTest, ErrorPaths) {
  TempDir dir;
  // listed in the help
  auto help = RunCli("--help", dir.path().string());
  EXPECT_NE(help.out.find("baseline"), std::string::npos) << help.out;
  // kNN without training data, an unknown method, a missing dataset
  auto run = RunCli("baseline --method knn --data nothere.h5", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--train"), std::string::npos) << run.err;
  run = RunCli("baseline --method svm --train a.h5 --data b.h5", dir.path().string());
  EXPECT_EQ(run.exit_code, 2);  // a CLI usage error naming the method and the choices
  EXPECT_NE(run.err.find("'svm' is not one of: knn, tdoa, arrival, constant"), std::string::npos)
      << run.err;
  run = RunCli("baseline --method tdoa --data nothere.h5", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("nothere.h5"), std::string::npos) << run.err;
  run = RunCli("baseline --method knn --k 0 --train a.h5 --data b.h5", dir.path().string());
  EXPECT_EQ(run.exit_code, 2);  // a CLI usage error
}

TEST(LocalizeArrivalTest, OneWavWithoutAModelAndItsErrors) {
  TempDir dir;
  auto run = RunCli("synth --out s.wav --index 2 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("localize --method arrival --wav s.wav --repeat 3 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  EXPECT_EQ(j["method"], "arrival");
  // the per-strike path timed apart from the set-up; each stage's median within the total's
  // (every run's stage lies within that run's total)
  EXPECT_GT(j["setup_ms"].get<double>(), 0.0);
  for (const char* stage : {"read", "picks", "search"}) {
    EXPECT_LE(j["latency_breakdown_ms"][stage].get<double>(), j["latency_ms"].get<double>())
        << stage;
  }
  EXPECT_EQ(j["arrival_s"].size(), 6u);
  EXPECT_GE(j["speed_m_s"].get<double>(), 150.0);
  // the synthesized strike's label: the estimate is on the right part of the tube
  std::ifstream label_file(dir / "s.json");
  const json label = json::parse(label_file);
  EXPECT_LT(std::abs(j["z_m"].get<double>() - label["z_m"].get<double>()), 0.05);
  // a silent record is refused, naming the file; the method and --model must agree
  AudioClip silent;
  silent.sample_rate_hz = 44100;
  silent.samples = Eigen::MatrixXf::Zero(6, 88200);
  WriteWav(dir / "silent.wav", silent, false);
  run = RunCli("localize --method arrival --wav silent.wav -q", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("silent.wav"), std::string::npos) << run.err;
  run = RunCli("localize --method arrival --wav s.wav --repeat 0 -q", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--repeat"), std::string::npos) << run.err;
  run = RunCli("localize --method arrival --model run --wav s.wav -q", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--model"), std::string::npos) << run.err;
  run = RunCli("localize --wav s.wav -q", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--model RUN"), std::string::npos) << run.err;
  run = RunCli("localize --method psychic --wav s.wav -q", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("psychic"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace sonicboom
