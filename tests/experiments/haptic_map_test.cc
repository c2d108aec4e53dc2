// Haptic mapping: the Chamfer distance on sets with known answers, and `map` against `eval` on
// the same strikes (a rigid placement keeps every distance).
#include "sonicboom/experiments/haptic_map.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include <nlohmann/json.hpp>

#include "common/test_util.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;

TEST(HapticMapTest, ChamferAndScoresOnSetsWithKnownAnswers) {
  // four points a metre apart, and the same shifted 1 cm along x: every nearest point is its
  // own partner, so both directions and the MED are 1 cm
  Eigen::Matrix3Xd a(3, 4);
  a << 0, 1, 0, 0,  //
      0, 0, 1, 0,   //
      0, 0, 0, 1;
  const Eigen::Matrix3Xd b = a.colwise() + Eigen::Vector3d(0.01, 0, 0);
  EXPECT_NEAR(RmsChamfer(a, b), 0.01, 1e-15);
  const MapScores s = ScoreMap(a, b);
  EXPECT_EQ(s.taps, 4);
  EXPECT_NEAR(s.med_cm, 1.0, 1e-12);
  EXPECT_NEAR(s.chamfer_cm, 1.0, 1e-12);
  EXPECT_NEAR(s.reverse_chamfer_cm, 1.0, 1e-12);
  // a subset lies on its superset (0 one way), not the other way: the RMS over the two points
  // left out, each 1 m from the nearest of the subset, over all four
  EXPECT_EQ(RmsChamfer(a.leftCols(2), a), 0.0);
  EXPECT_NEAR(RmsChamfer(a, a.leftCols(2)), std::sqrt(2.0 / 4.0), 1e-15);
  // a tap at the wrong place of the right set is no Chamfer error but a MED one
  Eigen::Matrix3Xd swapped = a;
  swapped.col(0).swap(swapped.col(1));
  const MapScores t = ScoreMap(swapped, a);
  EXPECT_EQ(t.chamfer_cm, 0.0);
  EXPECT_NEAR(t.med_cm, 100.0 * 2.0 / 4.0, 1e-12);
  EXPECT_TRUE(std::isnan(RmsChamfer(Eigen::Matrix3Xd(3, 0), a)));
  // a surface point: radius R from the axis at height z, moved with the pose
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() << 1, 2, 3;
  pose.linear() = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()).matrix();
  const Eigen::Vector3d p = TubeSurfacePoint(pose, 0.1, 0.0, 0.05);
  EXPECT_TRUE(p.isApprox(Eigen::Vector3d(1.05, 2.0 - 0.1, 3.0), 1e-12)) << p.transpose();
}

// distances to an object of capsules: beside the axis, past an end (to the cap), inside (the
// depth), the nearest of two; the surface scores of a map whose true points lie on the object,
// and none without an object
TEST(HapticMapTest, SurfaceDistanceOfCapsulesAndTheMapsSurfaceScores) {
  sim::ObjectSegment along_x;  // a 2 cm thick rod from the origin to x = 1 m
  along_x.p1 = Eigen::Vector3d(1, 0, 0);
  along_x.radius_m = 0.01;
  const std::vector<sim::ObjectSegment> rod{along_x};
  EXPECT_NEAR(SurfaceDistance(rod, {0.5, 0.03, 0}), 0.02, 1e-12);
  EXPECT_NEAR(SurfaceDistance(rod, {1.05, 0, 0}), 0.04, 1e-12);
  EXPECT_NEAR(SurfaceDistance(rod, {0.5, 0, 0.004}), 0.006, 1e-12);
  sim::ObjectSegment along_y = along_x;  // a second rod 10 cm above
  along_y.p0 = Eigen::Vector3d(0, 0, 0.1);
  along_y.p1 = Eigen::Vector3d(0, 1, 0.1);
  const std::vector<sim::ObjectSegment> two{along_x, along_y};
  EXPECT_NEAR(SurfaceDistance(two, {0, 0.5, 0.085}), 0.005, 1e-12);
  EXPECT_TRUE(std::isnan(SurfaceDistance({}, {0, 0, 0})));
  // true points on the rod's surface, predictions 1 cm off it
  Eigen::Matrix3Xd truth(3, 2), predicted(3, 2);
  truth << 0.2, 0.7,  //
      0.01, 0,        //
      0, -0.01;
  predicted << 0.2, 0.7,  //
      0.02, 0,            //
      0, -0.02;
  const MapScores s = ScoreMap(predicted, truth, rod);
  EXPECT_NEAR(s.true_surface_cm, 0.0, 1e-12);
  EXPECT_NEAR(s.surface_cm, 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(ScoreMap(predicted, truth).surface_cm));
}

// the guided scene's object in the base frame: at object_position_m, turned by object_yaw_deg
// about base z, as the taps were planned around it; other modes have none
TEST(HapticMapTest, GuidedObjectIsPlacedWhereTheTapsWerePlanned) {
  sim::SceneConfig scene;
  scene.mode = sim::SceneMode::kGuided;
  scene.objects.resize(1);
  scene.objects[0].kind = sim::ObjectKind::kRod;
  scene.guided.object_position_m = {-0.4, 0.4, 0.31};
  scene.guided.object_yaw_deg = 90;
  const sim::ObjectGeometry local = sim::BuildObjectGeometry(scene.objects[0], 0);
  const std::vector<sim::ObjectSegment> base = sim::GuidedSegmentsInBase(scene);
  ASSERT_EQ(base.size(), local.segments.size());
  ASSERT_FALSE(base.empty());
  const Eigen::Vector3d at(-0.4, 0.4, 0.31);
  for (size_t k = 0; k < base.size(); ++k) {
    const Eigen::Vector3d& p = local.segments[k].p1;
    EXPECT_TRUE(base[k].p1.isApprox(at + Eigen::Vector3d(-p.y(), p.x(), p.z()), 1e-12));
    EXPECT_EQ(base[k].radius_m, local.segments[k].radius_m);
  }
  scene.mode = sim::SceneMode::kStrike;
  EXPECT_TRUE(sim::GuidedSegmentsInBase(scene).empty());
}

// map and eval of one model on one dataset: the map's MED (between points placed in the base
// frame with the logged pose) is eval's (on the tube surface), since a placement is rigid
TEST(HapticMapTest, MapScoresTheTapsEvalScores) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string args = kShortRecordArgs + "-q --threads 1 ";
  ASSERT_EQ(RunCli(args + "generate --count 16 --out T.h5", cwd).exit_code, 0);
  ASSERT_EQ(RunCli(args + kTinyModelArgs + "--set train.epochs=1 train --data T.h5 --out R", cwd)
                .exit_code,
            0);
  auto run = RunCli("--json -q eval --model R --data T.h5", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json eval = json::parse(run.out);
  const std::string plot = std::string(SONICBOOM_SOURCE_DIR) + "/scripts/plot.py";
  run = RunCli("--json -q map --model R --data T.h5 --out M --plot " + plot, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json map = json::parse(run.out);
  EXPECT_EQ(map["taps"], eval["n"]);
  // within 0.1 mm: the map's truth is the recorded contact point, eval's its (z, theta) on the
  // nominal surface (the soft contact's point lies a few micrometres inside it)
  EXPECT_NEAR(map["med_cm"].get<double>(), eval["med_cm"].get<double>(), 0.01);
  EXPECT_GT(map["chamfer_cm"].get<double>(), 0.0);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "M/map.png"));
  std::ifstream points(dir.path() / "M/map.json");
  EXPECT_EQ(json::parse(points)["points"].size(), map["taps"].get<size_t>());
  // a second map into the same directory needs --force
  run = RunCli("map --model R --data T.h5 --out M --plot ''", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("M: exists; --force"), std::string::npos) << run.err;
  // taps whose arm log ends before their contact (0.1 s of rows, contacts at 0.25 s) are refused
  // before any work, naming the key that logs longer
  ASSERT_EQ(RunCli(args + "--set strike.proprio_rows=10 generate --count 4 --out S.h5", cwd)
                .exit_code,
            0);
  run = RunCli("map --model R --data S.h5 --out M2 --plot ''", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("after its proprioception log ends (10 rows at 100 Hz"),
            std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("strike.proprio_rows"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "M2/map.json"));
}

}  // namespace
}  // namespace sonicboom::experiments
