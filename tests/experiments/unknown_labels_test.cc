// Unknown is NaN: what a capture does not record is NaN in an imported dataset, and every
// command that needs a value (map, rerender, export, eval) refuses or skips a strike without it,
// naming the file, the sample row and the column. Also the capture checks of issue 58: trials
// numbered twice, captures longer than the record.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "common/workspace.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sonicboom::testing::CliRun;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// the reference solid at its coarsest (tests/experiments/reference_cli_test.cc)
const std::string kCoarse = " --max-frequency 3000 --element-m 0.04 -q";

// A copy of dataset `from` with `edit` applied to every sample (its row, the sample) and `info`
// to the metadata: datasets damaged as a hand-edited or older file would be.
void CopyDataset(const fs::path& from, const fs::path& to,
                 const std::function<void(int64_t, StrikeSample*)>& edit,
                 const std::function<void(DatasetInfo*)>& info_edit = {}) {
  const DatasetReader reader(from.string());
  DatasetInfo info = reader.info();
  info.num_samples = 0;
  if (info_edit) info_edit(&info);
  DatasetWriter writer(to.string(), info);
  for (int64_t r = 0; r < reader.size(); ++r) {
    StrikeSample s = reader.Read(r);
    edit(r, &s);
    writer.Append(s);
  }
  writer.Finish();
}

// The names of the entries of `dir` (what a refused command may have left).
std::vector<std::string> Entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// The rows of dataset `path` that hold a valid strike.
std::vector<int64_t> ValidRows(const fs::path& path) {
  const DatasetReader d(path.string());
  std::vector<int64_t> valid;
  for (int64_t r = 0; r < d.size(); ++r) {
    if (d.ReadMeta(r).valid) valid.push_back(r);
  }
  return valid;
}

// Copies of D.h5 (in `dir`) with one change to the valid row valid[k] (or to every sample).
void MakeDamagedCopies(const fs::path& dir, const std::vector<int64_t>& valid) {
  auto at = [&](size_t k, std::function<void(StrikeSample*)> f) {
    return [row = valid[k], f](int64_t r, StrikeSample* s) {
      if (r == row) f(s);
    };
  };
  const fs::path d = dir / "D.h5";
  CopyDataset(d, dir / "TNAN.h5", at(3, [](StrikeSample* s) { s->label.time_s = kNaN; }));
  CopyDataset(d, dir / "TNEG.h5", at(2, [](StrikeSample* s) { s->label.time_s = -0.1; }));
  CopyDataset(d, dir / "QUAT.h5",
              at(4, [](StrikeSample* s) { s->proprio.middleCols(3, 4).setZero(); }));
  CopyDataset(d, dir / "ZNAN.h5", at(5, [](StrikeSample* s) {
                s->label.z_m = kNaN;
                s->label.point_m.z() = kNaN;
              }));
  CopyDataset(d, dir / "THETA.h5", at(2, [](StrikeSample* s) { s->label.theta_rad = kNaN; }));
  CopyDataset(d, dir / "SPEED.h5",
              at(1, [](StrikeSample* s) { s->label.normal_speed_m_s = kNaN; }));
  CopyDataset(d, dir / "MASS.h5", at(6, [](StrikeSample* s) {
                ASSERT_FALSE(s->contacts.empty());
                s->contacts[0].effective_mass_kg = kNaN;
              }));
  CopyDataset(d, dir / "ALLNAN.h5", [](int64_t, StrikeSample* s) { s->label.z_m = kNaN; });
  // an import of before this fix: 0 for what the capture did not record
  CopyDataset(
      d, dir / "OLD.h5",
      [](int64_t, StrikeSample* s) { s->label.time_s = s->label.normal_speed_m_s = 0.0; },
      [](DatasetInfo* info) { info->source = "hardware"; });
}

// The suite's workspace: 16 short strikes, a tiny run, their export as trials, its import, and
// copies of the strikes with one value of one valid row made unknown or impossible.
void BuildWorkspace(const fs::path& dir) {
  const std::string args = kShortRecordArgs + "-q --threads 1 ";
  sonicboom::testing::RunEach(
      {args + "generate --count 16 --out D.h5",
       args + kTinyModelArgs + "--set train.epochs=1 train --data D.h5 --out RUN",
       "-q export --layout trial --in D.h5 --out TR",
       args + "import --layout trial --min-duration-s 0.5 --in TR --out I.h5"},
      dir);
  if (::testing::Test::HasFatalFailure()) return;
  const std::vector<int64_t> valid = ValidRows(dir / "D.h5");
  ASSERT_GE(valid.size(), 8u);
  MakeDamagedCopies(dir, valid);
}

constexpr sonicboom::testing::Workspace kWorkspace{"unknown_labels", BuildWorkspace};

// Built once per ctest run (the suite's fixture) for its tests to copy
TEST(UnknownLabelsWorkspace, IsBuilt) {
  sonicboom::testing::PublishWorkspace(kWorkspace);
}

// Each test process works in its own copy of the workspace
class UnknownLabelsTest : public sonicboom::testing::WorkspaceTest<kWorkspace> {
 protected:
  static void SetUpTestSuite() {
    WorkspaceTest::SetUpTestSuite();
    valid_ = ValidRows(Path("D.h5"));
    ASSERT_GE(valid_.size(), 8u);
  }

  // Runs `args`; expects exit 1 and every substring in stderr.
  static void ExpectRefused(const std::string& args, const std::vector<std::string>& substrings) {
    const CliRun run = RunCli(args, dir_->path().string());
    EXPECT_EQ(run.exit_code, 1) << args << "\n" << run.err;
    for (const std::string& s : substrings) EXPECT_THAT(run.err, HasSubstr(s)) << args;
    EXPECT_THAT(run.err, ::testing::Not(HasSubstr("internal error"))) << args;
  }

  // "FILE: sample row R (index R)" of the valid row valid_[k] of a copy of D.h5.
  static std::string RowOf(const std::string& file, size_t k) {
    return file + ": sample row " + std::to_string(valid_[k]) + " (index " +
           std::to_string(valid_[k]) + ")";
  }

  static fs::path Path(const std::string& name) { return dir_->path() / name; }
  static std::vector<int64_t> valid_;
};
std::vector<int64_t> UnknownLabelsTest::valid_;

// contact time, impulse, speed, duration, striker mass and peak force are NaN, not 0; the
// summary's ranges are over known values (null here)
TEST_F(UnknownLabelsTest, ImportWritesWhatACaptureDoesNotRecordAsNaN) {
  const DatasetReader d(Path("D.h5").string()), imported(Path("I.h5").string());
  ASSERT_EQ(imported.size(), static_cast<int64_t>(valid_.size()));
  for (int64_t r = 0; r < imported.size(); ++r) {
    const StrikeSample s = imported.ReadMeta(r);
    EXPECT_EQ(s.label.z_m, d.ReadMeta(valid_[r]).label.z_m);
    for (double v :
         {s.label.time_s, s.label.impulse_Ns, s.label.normal_speed_m_s, s.label.duration_s}) {
      EXPECT_TRUE(std::isnan(v)) << "row " << r << ": " << v;
    }
    ASSERT_EQ(s.contacts.size(), 1u);
    const ContactEpisode& c = s.contacts[0];
    for (double v : {c.time_s, c.duration_s, c.normal_speed_m_s, c.effective_mass_kg, c.impulse_Ns,
                     c.peak_force_N}) {
      EXPECT_TRUE(std::isnan(v)) << "row " << r << ": " << v;
    }
  }
  const CliRun run = RunCli("inspect I.h5 --json", dir_->path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json summary = json::parse(run.out);
  EXPECT_TRUE(summary["impulse_Ns"]["min"].is_null()) << summary["impulse_Ns"];
  EXPECT_TRUE(summary["normal_speed_m_s"]["max"].is_null()) << summary["normal_speed_m_s"];
  // one unknown impulse among known ones: the range is over the known ones
  CopyDataset(Path("D.h5"), Path("IMP.h5"), [](int64_t r, StrikeSample* s) {
    if (r == valid_[0]) s->label.impulse_Ns = kNaN;
  });
  const CliRun mixed = RunCli("inspect IMP.h5 --json", dir_->path().string());
  ASSERT_EQ(mixed.exit_code, 0) << mixed.err;
  EXPECT_TRUE(json::parse(mixed.out)["impulse_Ns"]["min"].is_number()) << mixed.out;
}

// no tap placed at t = 0 for an unknown contact time, none before the record, none turned by a
// zero quaternion, none scored against a NaN point
TEST_F(UnknownLabelsTest, MapRefusesTapsItCannotPlaceNamingFileRowAndColumn) {
  const std::string map = "map --model RUN --out M --plot '' --data ";
  ExpectRefused(map + "I.h5", {"I.h5: sample row 0 (index 0): label/time_s is NaN (not known)",
                               "labels.csv's time_s column"});
  ExpectRefused(map + "TNAN.h5", {RowOf("TNAN.h5", 3) + ": label/time_s is NaN (not known)"});
  ExpectRefused(map + "TNEG.h5",
                {RowOf("TNEG.h5", 2) + ": label/time_s is -0.1 s, before the record starts"});
  ExpectRefused(map + "QUAT.h5", {RowOf("QUAT.h5", 4) + ": /proprio row",
                                  "holds the quaternion (w, x, y, z) = (0, 0, 0, 0)"});
  ExpectRefused(map + "ZNAN.h5", {RowOf("ZNAN.h5", 5) + ": label/z_m is NaN (not known)"});
  ExpectRefused(map + "OLD.h5", {"OLD.h5: sample row 0 (index 0): label/time_s is 0 in an "
                                 "imported dataset (not known"});
  EXPECT_FALSE(fs::exists(Path("M/map.json")));
}

// refused before the reference tube is solved; nothing written
TEST_F(UnknownLabelsTest, RerenderRefusesStrikesWithoutWhatItRendersFrom) {
  const std::string rerender = "rerender --out R.h5" + kCoarse + " --in ";
  ExpectRefused(rerender + "I.h5", {"I.h5: sample row 0 (index 0): label/time_s is NaN"});
  ExpectRefused(rerender + "ZNAN.h5", {RowOf("ZNAN.h5", 5) + ": label/z_m is NaN"});
  ExpectRefused(rerender + "SPEED.h5", {RowOf("SPEED.h5", 1) + ": label/normal_speed_m_s is NaN"});
  ExpectRefused(rerender + "MASS.h5",
                {RowOf("MASS.h5", 6) + ": contacts/effective_mass_kg is NaN"});
  ExpectRefused(rerender + "OLD.h5", {"OLD.h5: sample row 0 (index 0): label/time_s is 0 in an "
                                      "imported dataset"});
  for (const std::string& name : Entries(dir_->path())) {
    EXPECT_FALSE(name.starts_with("R.h5")) << name;
  }
}

// gt_label.npy = [nan, nan] is never written (our own import refuses it); nothing is left
TEST_F(UnknownLabelsTest, ExportRefusesAStrikeWithAnUnknownLabel) {
  ExpectRefused("export --layout trial --in THETA.h5 --out TX",
                {RowOf("THETA.h5", 2) + ": label/theta_rad is NaN (not known)", "gt_label.npy"});
  EXPECT_FALSE(fs::exists(Path("TX")));
  EXPECT_FALSE(fs::exists(Path("TX.partial")));
}

// unlabelled strikes are left out of the scores and named; none labelled is refused
TEST_F(UnknownLabelsTest, EvalScoresLabelledStrikesOnlyAndSaysWhichItLeftOut) {
  const CliRun run = RunCli("eval --model RUN --data ZNAN.h5 --json", dir_->path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  EXPECT_EQ(j["n"], valid_.size() - 1);
  EXPECT_EQ(j["unlabelled"], 1);
  EXPECT_THAT(run.err, HasSubstr("ZNAN.h5: 1 of " + std::to_string(valid_.size()) +
                                 " valid strikes not scored"));
  EXPECT_THAT(run.err, HasSubstr("sample row " + std::to_string(valid_[5]) + " (index " +
                                 std::to_string(valid_[5]) + "): label/z_m is NaN"));
  ExpectRefused("eval --model RUN --data ALLNAN.h5",
                {"ALLNAN.h5: no valid strike has a known label", "label/z_m is NaN"});
}

// trial0 and trial00 are both sample 0: refused naming both, before anything is written
TEST_F(UnknownLabelsTest, TrialsNumberedTwiceAreRefusedNamingBoth) {
  fs::create_directory(Path("TT"));
  fs::copy(Path("TR/trial0"), Path("TT/trial0"));
  fs::copy(Path("TR/trial0"), Path("TT/trial00"));
  fs::copy(Path("TR/trial1"), Path("TT/trial1"));
  const std::vector<std::string> before = Entries(dir_->path());
  ExpectRefused(kShortRecordArgs + "import --layout trial --min-duration-s 0.5 --in TT --out T2.h5",
                {"TT/trial0 and TT/trial00: both are trial 0"});
  EXPECT_EQ(Entries(dir_->path()), before);
}

// a capture longer than the record is imported as its first record, and said with both lengths
TEST_F(UnknownLabelsTest, ACaptureLongerThanTheRecordIsSaidWithBothLengths) {
  fs::create_directory(Path("TL"));
  fs::copy(Path("TR/trial0"), Path("TL/trial0"));
  fs::copy(Path("TR/trial1"), Path("TL/trial1"));
  const fs::path wav = Path("TL/trial1/mic2.wav");
  AudioClip clip = ReadWav(wav.string());
  const Eigen::MatrixXf once = clip.samples;
  clip.samples.resize(once.rows(), 2 * once.cols());
  clip.samples << once, once;
  WriteWav(wav.string(), clip, /*pcm16=*/true);
  const CliRun run = RunCli(
      kShortRecordArgs + "-q import --layout trial --min-duration-s 0.5 --in TL --out L.h5 --json",
      dir_->path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.err, HasSubstr("TL/trial1/mic2.wav: 1.200 s long, longer than the record "
                                 "(audio.record_duration_s = 0.600 s): imported "
                                 "as its first 0.600 s"));
  const json j = json::parse(run.out);
  ASSERT_EQ(j["trimmed"].size(), 1u);
  EXPECT_EQ(j["trimmed"][0]["file"], "TL/trial1/mic2.wav");
  EXPECT_NEAR(j["trimmed"][0]["captured_s"].get<double>(), 1.2, 1e-9);
}

}  // namespace
}  // namespace sonicboom::experiments
