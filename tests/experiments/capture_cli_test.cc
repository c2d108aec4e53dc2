// import / export through the CLI: an imported dataset works with every command that reads
// datasets, and a simulated set exported and imported again gives the same features and answers.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/hardware/geometry.h"
#include "sonicboom/hardware/npy.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using testing::RunCli;
using testing::TempDir;

const std::string kTiny =
    testing::kShortRecordArgs + testing::kTinyModelArgs + "--set train.epochs=2 ";

TEST(CaptureCliTest, ExportImportRoundTripServesEveryDatasetCommand) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  auto run = RunCli(kTiny + "generate --count 24 --out D.h5 -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("export --layout trial --in D.h5 --out trials --json -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["trials"], 24);
  // (the seed's 24 strikes have none clipped, so every one is a good capture)
  run = RunCli(
      kTiny + "import --layout trial --in trials --out B.h5 --min-duration-s 0.5 --json -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["imported"], 24);

  // inspect says what it is; the commands that read datasets run on it unchanged
  run = RunCli("inspect B.h5 --json", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["source"], "hardware");
  run = RunCli(kTiny + "train --data B.h5 --out RUN -q --json", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const std::string& cmd :
       {kTiny + "features --in B.h5 --out F.h5 -q",
        std::string("baseline --method arrival --data B.h5 -q"),
        kTiny + "baseline --method constant --train B.h5 --data B.h5 -q",
        std::string("localize --model RUN --wav trials/trial0/mic2.wav -q")}) {
    run = RunCli(cmd, cwd);
    EXPECT_EQ(run.exit_code, 0) << cmd << ": " << run.err;
  }

  // the same strikes give the same answers: the model on the original and on the imported set
  const auto a = RunCli("eval --model RUN --data D.h5 --json -q", cwd);
  const auto b = RunCli("eval --model RUN --data B.h5 --json -q", cwd);
  ASSERT_EQ(a.exit_code, 0) << a.err;
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_EQ(json::parse(a.out), json::parse(b.out));

  // a session: three strikes in one stream are heard at their onsets, localized and saved in
  // the capture layout, which imports once the measured labels are filled in
  Eigen::MatrixXf stream(6, 0);
  for (int k = 0; k < 3; ++k) {
    const AudioClip clip = ReadWav(dir / ("trials/trial" + std::to_string(k) + "/mic2.wav"));
    stream.conservativeResize(Eigen::NoChange, stream.cols() + clip.frames());
    stream.rightCols(clip.frames()) = clip.samples;
  }
  WriteWav(dir / "stream.wav", AudioClip{stream, 44100.0});
  run = RunCli("listen --model RUN --wav stream.wav --save sess --json -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::vector<json> lines;
  std::istringstream out(run.out);
  for (std::string line; std::getline(out, line);) lines.push_back(json::parse(line));
  ASSERT_EQ(lines.size(), 4u) << run.out;
  EXPECT_EQ(lines[3]["events"], 3);
  DatasetReader original(dir / "D.h5");
  std::ofstream labels(dir / "sess/labels.csv");
  labels << "file,z_m,theta_rad\n";
  for (int k = 0; k < 3; ++k) {
    const ContactLabel truth = original.ReadMeta(k).label;
    EXPECT_NEAR(lines[k]["onset_s"].get<double>(), 0.6 * k + truth.time_s, 0.002) << k;
    EXPECT_GT(lines[k]["latency_ms"].get<double>(), 0.0);
    labels << lines[k]["file"].get<std::string>() << "," << truth.z_m << "," << truth.theta_rad
           << "\n";
  }
  labels.close();
  run = RunCli("import --layout capture --in sess --out S.h5 --min-duration-s 0.5 --json -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["imported"], 3);
  // the saved session is a listener's own record: saving into it again is refused
  run = RunCli("listen --model RUN --wav stream.wav --save sess -q", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("already holds a session"), std::string::npos) << run.err;
}

TEST(CaptureCliTest, RefusesToOverwriteAndNamesBadInput) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  std::ofstream(dir / "B.h5") << "keep";
  fs::create_directory(dir / "cap");
  auto run = RunCli("import --layout capture --in cap --out B.h5", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("B.h5: exists; --force"), std::string::npos) << run.err;
  run = RunCli("import --layout capture --in cap --out C.h5", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("capture.yaml: missing"), std::string::npos) << run.err;
  // a value outside a choice is a usage error naming the option and the names it takes
  run = RunCli("import --layout tape --in cap --out C.h5", cwd);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--layout: 'tape' is not one of: trial, capture"), std::string::npos)
      << run.err;
  run = RunCli("export --in B.h5 --out T --angle-convention j8", cwd);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--angle-convention: 'j8' is not one of: tube, j7"), std::string::npos)
      << run.err;
  run = RunCli("baseline --method nearest --data B.h5", cwd);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--method: 'nearest' is not one of: knn, tdoa, arrival, constant"),
            std::string::npos)
      << run.err;
  std::ifstream kept(dir / "B.h5");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(kept), {}), "keep");
  EXPECT_FALSE(fs::exists(dir / "C.h5"));
  EXPECT_FALSE(fs::exists(dir / "T"));
}

// A closed 24-sided rod mesh as binary STL: radius r, length l, along unit u through c.
void WriteRodStl(const std::string& path, const Eigen::Vector3d& c, const Eigen::Vector3d& u,
                 double r, double l) {
  hardware::ObjectGeometry rod;
  hardware::AppendCylinder(c - 0.5 * l * u, c + 0.5 * l * u, r, 24, &rod);
  std::ofstream out(path, std::ios::binary);
  out << std::string(80, ' ');
  const auto n = static_cast<uint32_t>(rod.triangles.cols());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (Eigen::Index t = 0; t < rod.triangles.cols(); ++t) {
    const float normal[3] = {0, 0, 0};  // readers recompute it
    out.write(reinterpret_cast<const char*>(normal), 12);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f v = rod.vertices.col(rod.triangles(k, t));
      out.write(reinterpret_cast<const char*>(v.data()), 12);
    }
    out.write("\0\0", 2);
  }
}

TEST(CaptureCliTest, ImportLabelsTrialsFromTheJointLogAndAnObjectMesh) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  ASSERT_EQ(RunCli(kTiny + "generate --count 2 --out D.h5 -q", cwd).exit_code, 0);
  ASSERT_EQ(RunCli("export --in D.h5 --out trials -q", cwd).exit_code, 0);
  // the arm holds still at q; a rod touches the tube at (z0, theta0) = (0.04 m, 1.0 rad) in
  // trial 0; in trial 1 the base is turned and the tube never comes near it
  const double q[7] = {0.1, -0.3, 0.05, -2.0, 0.02, 1.9, 0.7};
  const Eigen::Isometry3d tube = sim::PandaForwardKinematics(sim::JointVector(q), 0.155).tube;
  const Eigen::Vector3d n(std::cos(1.0), std::sin(1.0), 0.0), t(-std::sin(1.0), std::cos(1.0), 0.0);
  WriteRodStl(dir / "rod.stl", tube * ((0.05355 + 0.011) * n + Eigen::Vector3d(0, 0, 0.04)),
              tube.linear() * (0.8 * t + 0.6 * Eigen::Vector3d::UnitZ()), 0.011, 0.4);
  std::vector<double> log;
  for (int r = 0; r < 200; ++r) log.insert(log.end(), q, q + 7);
  hardware::WriteNpy(dir / "trials/trial0/q_t.npy", {200, 7}, log);
  for (int r = 0; r < 200; ++r) log[r * 7] = 1.6;  // the base turned: the tube far from the rod
  hardware::WriteNpy(dir / "trials/trial1/q_t.npy", {200, 7}, log);
  auto run = RunCli(kTiny +
                        "import --layout trial --in trials --out G.h5 --object rod.stl "
                        "--min-duration-s 0.5 --skip-bad --json -q",
                    cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json report = json::parse(run.out);
  EXPECT_EQ(report["imported"], 1);
  ASSERT_EQ(report["bad"].size(), 1u);
  EXPECT_NE(report["bad"][0]["reason"].get<std::string>().find("trial1/q_t.npy: no contact"),
            std::string::npos)
      << run.out;
  const ContactLabel label = DatasetReader(dir / "G.h5").ReadMeta(0).label;
  EXPECT_NEAR(label.z_m, 0.04, 5e-4);
  EXPECT_NEAR(label.theta_rad, 1.0, 5e-4 / 0.05355);
}

TEST(CaptureCliTest, GeometryLabelsAgreeWithTheSimulatorOnMuJoCoStrikes) {
  TempDir dir;
  const auto run =
      RunCli("geometry-check --count 12 --scenes scenes --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  EXPECT_GE(j["labelled"].get<int>(), 10);
  EXPECT_EQ(j["failures"], 0);
  EXPECT_LT(j["median_mm"].get<double>(), 1.0);
  EXPECT_LT(j["worst_mm"].get<double>(), 3.0);
  // each strike's scene is on disk as a trial would bring it: a mesh and a 7-column joint log
  // whose forward kinematics is the pose MuJoCo logged
  EXPECT_LT(j["kinematics_gap_max_mm"].get<double>(), 0.01);
  int64_t scenes = 0;
  for (const auto& e : fs::directory_iterator(dir / "scenes")) {
    ++scenes;
    EXPECT_GT(hardware::ReadObjectGeometry((e.path() / "object.ply").string()).triangles.cols(), 0);
    const hardware::NpyArray q = hardware::ReadNpy((e.path() / "q_t.npy").string());
    EXPECT_EQ(q.cols(), 7);
    EXPECT_EQ(q.rows(), 200);  // the 2 s record at 100 Hz
  }
  EXPECT_EQ(scenes, j["strikes"].get<int64_t>());
  // a used scene directory is not written into
  const auto again = RunCli("geometry-check --count 1 --scenes scenes", dir.path().string());
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("scenes: exists and is not an empty directory (--scenes)"),
            std::string::npos)
      << again.err;
  const auto bad = RunCli("--config " + std::string(SONICBOOM_SOURCE_DIR) +
                              "/configs/ts4.yaml geometry-check --count 2",
                          dir.path().string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("needs scene.mode strike or guided"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace sonicboom
