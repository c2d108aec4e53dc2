// Import and export of recorded strikes: round trips, bad captures, the capture layout.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "common/test_util.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/hardware/import.h"
#include "sonicboom/hardware/npy.h"

namespace sonicboom::hardware {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::TempDir;
using sonicboom::testing::ThrownMessage;
using ::testing::HasSubstr;

using sonicboom::kPi;
constexpr int64_t kFrames = 88200;

// A ringing strike: decaying tones from 0.5 s on each channel plus a little noise, peak < 0.5.
Eigen::MatrixXf StrikeAudio(uint64_t i) {
  std::mt19937 rng(static_cast<unsigned>(i) + 7);
  std::normal_distribution<float> noise(0.0f, 1e-3f);
  Eigen::MatrixXf a(6, kFrames);
  for (int c = 0; c < 6; ++c) {
    for (int64_t t = 0; t < kFrames; ++t) {
      const double s = t / 44100.0 - 0.5;
      const double tone =
          s < 0 ? 0.0 : 0.4 * std::exp(-s / 0.1) * std::sin(2 * kPi * (800 + 100 * c + i) * s);
      a(c, t) = static_cast<float>(tone) + noise(rng);
    }
  }
  return a;
}

// A dataset of n strikes with labels and moving poses, as `generate` would write it.
void MakeDataset(const std::string& path, int n) {
  DatasetInfo info;
  info.audio_frames = kFrames;
  info.proprio_rows = 50;
  DatasetWriter writer(path, info);
  for (int i = 0; i < n; ++i) {
    StrikeSample s;
    s.index = static_cast<uint64_t>(i);
    s.label.z_m = -0.09 + 0.04 * i;
    s.label.theta_rad = -3.0 + 1.1 * i;
    s.audio = StrikeAudio(s.index);
    s.proprio.resize(50, kProprioFeatures);
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d(1, 2, 3).normalized()));
    for (int r = 0; r < 50; ++r) {
      s.proprio.row(r) << 0.3f + 0.001f * r, 0.1f * i, 0.5f, q.w(), q.x(), q.y(), q.z(), 0.01f * r,
          0, -0.02f;
    }
    writer.Append(s);
  }
  writer.Finish();
}

ImportSettings Trials() {
  ImportSettings s;
  s.threads = 2;
  return s;
}

TEST(ImportTest, ExportThenImportReproducesAudioLabelsAndPoses) {
  TempDir dir;
  MakeDataset(dir / "d.h5", 4);
  ASSERT_EQ(ExportTrials(dir / "d.h5", dir / "trials", AngleConvention::kTube), 4);
  EXPECT_TRUE(fs::exists(dir / "trials/trial3/x_t.npy"));
  EXPECT_FALSE(fs::exists(dir / "trials.partial"));
  const ImportReport report =
      ImportCaptures(dir / "trials", dir / "back.h5", Trials(), DatasetInfo{});
  EXPECT_EQ(report.imported, 4);
  EXPECT_TRUE(report.bad.empty());
  DatasetReader a(dir / "d.h5"), b(dir / "back.h5");
  EXPECT_EQ(b.info().source, "hardware");
  for (int64_t i = 0; i < 4; ++i) {
    const StrikeSample x = a.Read(i), y = b.Read(i);
    EXPECT_EQ(y.index, x.index);
    // one 16-bit step at most (the WAV and the dataset scale int16 by 32768 and 32767)
    EXPECT_LE((x.audio - y.audio).cwiseAbs().maxCoeff(), 1.0f / 32767.0f);
    EXPECT_NEAR(y.label.z_m, x.label.z_m, 1e-12);
    EXPECT_NEAR(y.label.theta_rad, x.label.theta_rad, 1e-12);
    EXPECT_NEAR(y.label.point_m.x(), 0.05355 * std::cos(x.label.theta_rad), 1e-12);
    EXPECT_LE((x.proprio - y.proprio).cwiseAbs().maxCoeff(), 1e-6f);
    EXPECT_EQ(y.provenance,
              (fs::path(dir / "trials") / ("trial" + std::to_string(i)) / "mic2.wav").string());
  }
  // inverted on import: every channel negated exactly, labels untouched
  ImportSettings inverted = Trials();
  inverted.invert_polarity = true;
  ASSERT_EQ(ImportCaptures(dir / "trials", dir / "inv.h5", inverted, DatasetInfo{}).imported, 4);
  DatasetReader c(dir / "inv.h5");
  for (int64_t i = 0; i < 4; ++i) {
    const StrikeSample y = b.Read(i), z = c.Read(i);
    EXPECT_EQ(z.audio, (-y.audio).eval());
    EXPECT_EQ(z.label.theta_rad, y.label.theta_rad);
  }
  // the output directory is never overwritten
  EXPECT_THAT(ThrownMessage<IoError>(
                  [&] { ExportTrials(dir / "d.h5", dir / "trials", AngleConvention::kTube); }),
              HasSubstr("already exists"));
}

TEST(ImportTest, J7AngleConventionMapsThetaBothWays) {
  EXPECT_NEAR(TubeAngleFrom(0.0, AngleConvention::kJ7), -50.0 * kPi / 180.0, 1e-12);
  EXPECT_NEAR(TubeAngleFrom(-2.7, AngleConvention::kJ7), 2.7 - 50.0 * kPi / 180.0, 1e-12);
  for (double t : {-3.1, -1.0, 0.0, 2.0, 3.1}) {
    EXPECT_NEAR(TubeAngleFrom(StoredAngleFrom(t, AngleConvention::kJ7), AngleConvention::kJ7), t,
                1e-12);
  }
  TempDir dir;
  MakeDataset(dir / "d.h5", 2);
  ExportTrials(dir / "d.h5", dir / "j7", AngleConvention::kJ7);
  const double stored = ReadNpy(dir / "j7/trial1/gt_label.npy").data[1];
  EXPECT_NEAR(stored, StoredAngleFrom(-1.9, AngleConvention::kJ7), 1e-12);
  ImportSettings s = Trials();
  s.angle = AngleConvention::kJ7;
  ImportCaptures(dir / "j7", dir / "back.h5", s, DatasetInfo{});
  EXPECT_NEAR(DatasetReader(dir / "back.h5").ReadMeta(1).label.theta_rad, -1.9, 1e-12);
}

// Six trials: 0 good, 1 at 48 kHz, 2 labelled off the tube, 3 without x_t, 4 clipped, 5 pickled.
void MakeBadTrials(const TempDir& dir) {
  MakeDataset(dir / "d.h5", 6);
  ExportTrials(dir / "d.h5", dir / "trials", AngleConvention::kTube);
  AudioClip clip = ReadWav(dir / "trials/trial1/mic2.wav");
  clip.sample_rate_hz = 48000;
  WriteWav(dir / "trials/trial1/mic2.wav", clip);
  WriteNpy(dir / "trials/trial2/gt_label.npy", {2}, {0.5, 0.0});
  fs::remove(dir / "trials/trial3/x_t.npy");
  clip = ReadWav(dir / "trials/trial4/mic2.wav");
  clip.samples(2, 30000) = 1.2f;
  WriteWav(dir / "trials/trial4/mic2.wav", clip);
  std::ofstream pickle(dir / "trials/trial5/gt_label.npy", std::ios::binary);
  pickle.write("\x93NUMPY\x01\x00\x36\x00", 10);
  pickle << "{'descr': '|O', 'fortran_order': False, 'shape': (2,), }              \n";
}

TEST(ImportTest, BadTrialsFailTheWholeImportAndListEveryFile) {
  TempDir dir;
  MakeBadTrials(dir);
  const std::string message = ThrownMessage<IoError>(
      [&] { ImportCaptures(dir / "trials", dir / "out.h5", Trials(), DatasetInfo{}); });
  EXPECT_THAT(message, HasSubstr("5 of 6 captures are bad, nothing written"));
  EXPECT_THAT(message, HasSubstr("trial1/mic2.wav: sample rate 48000 Hz"));
  EXPECT_THAT(message, HasSubstr("trial2/gt_label.npy: label z = 0.5 m is off the tube"));
  EXPECT_THAT(message, HasSubstr("trial3/x_t.npy: no such file"));
  EXPECT_THAT(message, HasSubstr("trial4/mic2.wav: clipped"));
  EXPECT_THAT(message, HasSubstr("trial5/gt_label.npy: .npy holds Python objects"));
  EXPECT_FALSE(fs::exists(dir / "out.h5"));
  EXPECT_FALSE(fs::exists(dir / "out.h5.partial"));
}

TEST(ImportTest, SkipBadImportsTheRestAndReportsEachBadOne) {
  TempDir dir;
  MakeBadTrials(dir);
  ImportSettings s = Trials();
  s.skip_bad = true;
  const ImportReport report = ImportCaptures(dir / "trials", dir / "out.h5", s, DatasetInfo{});
  EXPECT_EQ(report.imported, 1);
  ASSERT_EQ(report.bad.size(), 5u);
  EXPECT_THAT(report.bad[0].file, HasSubstr("trial1/mic2.wav"));
  DatasetReader reader(dir / "out.h5");
  ASSERT_EQ(reader.size(), 1);
  EXPECT_EQ(reader.ReadMeta(0).index, 0u);
  // every capture bad: an error even with skip_bad, and nothing written
  for (const char* gone : {"trial0/mic2.wav"}) fs::remove(dir / (std::string("trials/") + gone));
  EXPECT_THAT(ThrownMessage<IoError>(
                  [&] { ImportCaptures(dir / "trials", dir / "none.h5", s, DatasetInfo{}); }),
              HasSubstr("every capture is bad"));
  EXPECT_FALSE(fs::exists(dir / "none.h5.partial"));
}

TEST(ImportTest, PositionOnlyPosesTakeTheirOrientationFromTheJointLog) {
  TempDir dir;
  MakeDataset(dir / "d.h5", 1);
  ExportTrials(dir / "d.h5", dir / "trials", AngleConvention::kTube);
  std::vector<double> x(200 * 3, 0.2), q(200 * 7, 0.0);
  for (int r = 0; r < 200; ++r) q[r * 7 + 6] = 0.01 * r;  // joint 7 turns
  WriteNpy(dir / "trials/trial0/x_t.npy", {200, 3}, x);
  ImportSettings s = Trials();
  EXPECT_THAT(ThrownMessage<IoError>(
                  [&] { ImportCaptures(dir / "trials", dir / "a.h5", s, DatasetInfo{}); }),
              HasSubstr("no orientation (3 columns) and there is no q_t.npy"));
  WriteNpy(dir / "trials/trial0/q_t.npy", {200, 7}, q);
  s.tube_pose_from_joints = [](const std::array<double, 7>& j) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = Eigen::AngleAxisd(j[6], Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return t;
  };
  ImportCaptures(dir / "trials", dir / "b.h5", s, DatasetInfo{});
  const StrikeSample back = DatasetReader(dir / "b.h5").ReadMeta(0);
  EXPECT_NEAR(back.proprio(40, 0), 0.2, 1e-6);            // x from x_t
  EXPECT_NEAR(back.proprio(40, 3), std::cos(0.2), 1e-6);  // w of a 0.4 rad turn
  EXPECT_NEAR(back.proprio(40, 6), std::sin(0.2), 1e-6);  // z
}

TEST(ImportTest, CaptureLayoutReadsLabelsLogsAndNoiseAndFlagsUnlabelledFiles) {
  TempDir dir;
  fs::create_directory(dir / "cap");
  AudioClip clip{StrikeAudio(1), 44100.0};
  for (const char* name : {"a.wav", "b.wav", "c.wav", "d.wav"})
    WriteWav(dir / (std::string("cap/") + name), clip);
  clip.samples = StrikeAudio(2) * 0.01f;
  WriteWav(dir / "cap/noise.wav", clip);
  Eigen::MatrixXf log = Eigen::MatrixXf::Zero(60, kProprioFeatures);
  for (int r = 0; r < 60; ++r) log.row(r) << 0.1f * r, 0, 0, 1, 0, 0, 0, 0, 0, 0;
  WriteProprioCsv(dir / "cap/a.csv", log, 100.0);
  std::ofstream(dir / "cap/labels.csv") << "file,z_m,theta_rad,object,material,robot_log\n"
                                        << "a.wav,0.05,1.0,rod T22L42,wood,a.csv\n"
                                        << "b.wav,-0.02,-2.0,,,\n"
                                        << "c.wav,five,0.0,,,\n";
  ImportSettings s = Trials();
  s.layout = Layout::kCapture;
  s.skip_bad = true;
  const ImportReport report = ImportCaptures(dir / "cap", dir / "cap.h5", s, DatasetInfo{});
  EXPECT_EQ(report.imported, 2);
  ASSERT_EQ(report.bad.size(), 2u);
  EXPECT_THAT(report.bad[0].reason, HasSubstr("labels.csv:4: z_m 'five' is not a number"));
  EXPECT_THAT(report.bad[1].reason, HasSubstr("d.wav: no row in labels.csv"));
  EXPECT_EQ(report.noise_wav, dir / "cap.h5.noise.wav");
  EXPECT_TRUE(fs::exists(report.noise_wav));
  DatasetReader reader(dir / "cap.h5");
  const StrikeSample a = reader.ReadMeta(0), b = reader.ReadMeta(1);
  EXPECT_NEAR(a.label.z_m, 0.05, 1e-12);
  ASSERT_EQ(a.contacts.size(), 1u);
  EXPECT_EQ(a.contacts[0].object, "rod T22L42");
  EXPECT_EQ(a.contacts[0].material, "wood");
  EXPECT_NEAR(a.proprio(49, 0), 4.9, 1e-5);  // the log's row 49
  EXPECT_EQ(b.proprio(10, 3), 1.0f);         // no log: the held identity pose
  EXPECT_NEAR(b.label.theta_rad, -2.0, 1e-12);
  // a header with an unknown column is refused whole
  std::ofstream(dir / "cap/labels.csv") << "file,z_m,theta_rad,height\n";
  EXPECT_THAT(
      ThrownMessage<IoError>([&] { ImportCaptures(dir / "cap", dir / "x.h5", s, DatasetInfo{}); }),
      HasSubstr("column 'height' is unknown"));
}

// labels.csv numbers are decimal (strtod would read 0x10 as 16 and 0x1p-4 as 0.0625); a UTF-8
// byte order mark before the header is dropped; time_s, when given, is the contact's time (else
// NaN, like everything else a capture does not record)
TEST(ImportTest, CaptureLabelsAreDecimalNumbersAndMayFollowAByteOrderMark) {
  TempDir dir;
  fs::create_directory(dir / "cap");
  AudioClip clip{StrikeAudio(1), 44100.0};
  for (const char* name : {"a.wav", "b.wav", "c.wav", "d.wav", "e.wav"})
    WriteWav(dir / (std::string("cap/") + name), clip);
  std::ofstream(dir / "cap/labels.csv") << "\xEF\xBB\xBF"
                                        << "file,z_m,theta_rad,time_s\r\n"
                                        << "a.wav,0.05,1.0,0.5\r\n"
                                        << "b.wav,0x10,0.0,\r\n"
                                        << "c.wav,0.01,0x1p-4,\r\n"
                                        << "d.wav,0.01,0.0,2.5\r\n"
                                        << "e.wav, -2e-2 ,-3.0e0,\r\n";
  ImportSettings s = Trials();
  s.layout = Layout::kCapture;
  s.skip_bad = true;
  const ImportReport report = ImportCaptures(dir / "cap", dir / "cap.h5", s, DatasetInfo{});
  EXPECT_EQ(report.imported, 2);
  ASSERT_EQ(report.bad.size(), 3u);
  EXPECT_THAT(report.bad[0].reason,
              HasSubstr("labels.csv:3: z_m '0x10' is not a number (decimal notation only: "
                        "hexadecimal is refused)"));
  EXPECT_THAT(report.bad[1].reason, HasSubstr("labels.csv:4: theta_rad '0x1p-4' is not a number"));
  EXPECT_THAT(report.bad[2].reason,
              HasSubstr("labels.csv:5: time_s 2.5 s lies outside the record [0, 2 s)"));
  const DatasetReader reader(dir / "cap.h5");
  const StrikeSample a = reader.ReadMeta(0), e = reader.ReadMeta(1);
  EXPECT_EQ(a.label.time_s, 0.5);
  EXPECT_EQ(a.contacts[0].time_s, 0.5);
  EXPECT_TRUE(std::isnan(a.label.normal_speed_m_s));
  EXPECT_TRUE(std::isnan(a.contacts[0].effective_mass_kg));
  EXPECT_EQ(e.label.z_m, -0.02);  // blanks around a decimal number are fine
  EXPECT_TRUE(std::isnan(e.label.time_s));
}

}  // namespace
}  // namespace sonicboom::hardware
