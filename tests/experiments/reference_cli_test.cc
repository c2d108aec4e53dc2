// `sonicboom rerender` and `sonicboom reference` end to end: a dataset's strikes rendered again by
// the reference solid keep their labels, get new audio that does not depend on the thread count,
// and bad requests are refused naming the option.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom {
namespace {

using testing::RunCli;
using testing::TempDir;

const std::string kCoarse = " --max-frequency 3000 --element-m 0.04 -q";

TEST(ReferenceCliTest, RerenderKeepsLabelsAndRendersNewAudioDeterministically) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  ASSERT_EQ(RunCli(testing::kShortRecordArgs + "generate --count 6 --out D.h5 -q", cwd).exit_code,
            0);
  auto run = RunCli("rerender --in D.h5 --out R.h5" + kCoarse, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("rerender --in D.h5 --out R1.h5 --threads 1" + kCoarse, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("rerender --ideal --in D.h5 --out RI.h5" + kCoarse, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const DatasetReader base(cwd + "/D.h5"), ref(cwd + "/R.h5"), ref1(cwd + "/R1.h5"),
      ideal(cwd + "/RI.h5");
  // the uniform tube is another structure: other audio, and its config says how it was made
  EXPECT_NE(ideal.info().config_yaml.find("--ideal"), std::string::npos);
  EXPECT_GT((ideal.Read(0).audio - ref.Read(0).audio).cwiseAbs().maxCoeff(), 1e-3f);
  ASSERT_EQ(ref.size(), base.size());
  EXPECT_EQ(ref.info().variation_names.size(), 8u);
  const double fs = ref.info().sample_rate_hz;
  int rendered = 0;
  for (int64_t i = 0; i < base.size(); ++i) {
    const StrikeSample b = base.Read(i), r = ref.Read(i), r1 = ref1.Read(i);
    EXPECT_EQ(r.label.z_m, b.label.z_m);
    EXPECT_EQ(r.label.theta_rad, b.label.theta_rad);
    EXPECT_EQ(r.label.time_s, b.label.time_s);
    EXPECT_EQ(r.audio, r1.audio) << "sample " << i << " depends on the thread count";
    if (!b.valid) continue;
    // noise before the onset (a 3 kHz band leaves the strike 10-40 dB above it), the strike
    // after it, and not the shell model's audio
    const Eigen::Index onset = static_cast<Eigen::Index>(r.label.time_s * fs);
    const float before = r.audio.leftCols(onset - 10).cwiseAbs().maxCoeff();
    const float after = r.audio.rightCols(r.audio.cols() - onset).cwiseAbs().maxCoeff();
    EXPECT_GT(after, 5.0f * before) << "sample " << i;
    EXPECT_GT((r.audio - b.audio).cwiseAbs().maxCoeff(), 0.01f);
    ++rendered;
  }
  EXPECT_GT(rendered, 0);
}

TEST(ReferenceCliTest, RefusesItsInputAsOutputAndABandAboveNyquist) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  ASSERT_EQ(RunCli(testing::kShortRecordArgs + "generate --count 2 --out D.h5 -q", cwd).exit_code,
            0);
  auto run = RunCli("rerender --in D.h5 --out D.h5 --force" + kCoarse, cwd);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--in"), std::string::npos) << run.err;
  run = RunCli("rerender --in D.h5 --out R.h5 --max-frequency 30000 -q", cwd);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("Nyquist"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "R.h5"));
  run = RunCli("reference --levels 2", cwd);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--levels"), std::string::npos) << run.err;
  // a mesh that cannot be built is refused before any work, naming the option and the limit
  for (const char* cmd :
       {"reference --element-m 0", "rerender --in D.h5 --out R.h5 --element-m 0"}) {
    run = RunCli(std::string(cmd) + " -q", cwd);
    EXPECT_EQ(run.exit_code, 1) << cmd;
    EXPECT_NE(run.err.find("--element-m 0"), std::string::npos) << run.err;
    EXPECT_NE(run.err.find("0.004"), std::string::npos) << run.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "R.h5"));
}

// randomize.reference_fraction: the strikes its draw picks are the reference solid's, bit for bit
// what `rerender` makes of the same strikes, the others the shell's; a flag column says which;
// a reference band above Nyquist is refused naming the key, before anything is written
TEST(ReferenceCliTest, GenerateRendersTheDrawnFractionWithTheReference) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string mixed =
      "--set randomize.reference_fraction=0.5 --set randomize.reference_max_frequency_hz=3000 "
      "--set randomize.reference_element_m=0.04 ";
  auto run = RunCli(testing::kShortRecordArgs + "generate --count 12 --out D.h5 -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli(testing::kShortRecordArgs + mixed + "generate --count 12 --out M.h5 -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("rerender --in D.h5 --out R.h5" + kCoarse, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const DatasetReader shell(cwd + "/D.h5"), mix(cwd + "/M.h5"), ref(cwd + "/R.h5");
  const std::vector<std::string>& names = mix.info().variation_names;
  ASSERT_EQ(names.size(), 9u);
  EXPECT_EQ(names.back(), "ref_rendered");
  EXPECT_EQ(names.front(), "ref_striker_modulus_pa");
  int rendered = 0, valid = 0;
  for (int64_t i = 0; i < mix.size(); ++i) {
    const StrikeSample m = mix.Read(i), s = shell.Read(i), r = ref.Read(i);
    EXPECT_EQ(m.label.z_m, s.label.z_m);
    if (!m.valid) continue;
    ++valid;
    if (m.variation.back() == 1.0) {
      ++rendered;
      EXPECT_EQ(m.audio, r.audio) << "sample " << i;
      EXPECT_EQ(m.variation[2], r.variation[2]) << "sample " << i;  // its loss factor draw
    } else {
      EXPECT_EQ(m.variation.back(), 0.0);
      EXPECT_EQ(m.audio, s.audio) << "sample " << i;
    }
  }
  EXPECT_GT(rendered, 0);
  EXPECT_LT(rendered, valid);
  run = RunCli(testing::kShortRecordArgs +
                   "--set randomize.reference_fraction=0.2 --set "
                   "randomize.reference_max_frequency_hz=30000 generate --count 2 --out N.h5 -q",
               cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("randomize.reference_max_frequency_hz"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "N.h5"));
}

// apps/reference_levels solves, without the CLI, exactly the levels `sonicboom reference` keys:
// the report reads every one of them back instead of solving (ConvergenceLevelTest checks that
// another input is not read back)
TEST(ReferenceCliTest, LevelsSolvedApartAreReadBackByTheReport) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  // apps/reference_levels on the meshes of `args`, into cache directory `cache`: its exit status
  auto solve_apart = [&](const std::string& args, const std::string& cache) {
    std::vector<std::string> argv = {SONICBOOM_REFERENCE_LEVELS};
    for (std::string& word : sonicboom::testing::SplitArgs(args)) argv.push_back(word);
    argv.insert(argv.end(), {"--cache-dir", cache});
    return sonicboom::testing::RunProgram(argv, cwd).exit_code;
  };
  // meshes as coarse as the tube allows keep the solves to seconds: what is read back does not
  // depend on the element size
  const std::string mesh = " --ideal --element-m 0.06 --max-frequency 1000 --levels 3 --ratio 1.2";
  ASSERT_EQ(solve_apart(mesh, "L"), 0) << mesh;
  const auto run = RunCli("reference" + mesh + " --cache-dir L --json -q", cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  ASSERT_EQ(j["levels"].size(), 3u);
  for (const auto& level : j["levels"]) EXPECT_TRUE(level["from_cache"].get<bool>());
  // a self-similar family the same way: its h falls as 1 / subdivisions exactly
  const std::string family = " --ideal --element-m 0.12 --max-frequency 1000 --subdivisions 2,3,4";
  ASSERT_EQ(solve_apart(family, "S"), 0) << family;
  const auto self_similar = RunCli("reference" + family + " --cache-dir S --json -q", cwd);
  ASSERT_EQ(self_similar.exit_code, 0) << self_similar.err;
  const auto js = nlohmann::json::parse(self_similar.out);
  ASSERT_EQ(js["levels"].size(), 3u);
  for (int l = 0; l < 3; ++l) {
    EXPECT_TRUE(js["levels"][l]["from_cache"].get<bool>());
    EXPECT_NEAR(js["levels"][l]["h_m"].get<double>(), 0.12 / (2 + l), 1e-15);
  }
  // subdivisions that do not ascend, and beside --ratio
  auto bad = RunCli("reference --ideal --element-m 0.08 --subdivisions 2,2,3 -q", cwd);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("--subdivisions 2,2,3"), std::string::npos) << bad.err;
  bad = RunCli("reference --ideal --element-m 0.08 --subdivisions 2,3,4 --ratio 1.2 -q", cwd);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--ratio"), std::string::npos) << bad.err;
  bad = RunCli("reference --ideal --element-m 0.08 --fixed-interval-m 0 -q", cwd);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--subdivisions"), std::string::npos) << bad.err;
}

// the convergence report on coarse meshes, with the shell model's arrivals beside the reference's:
// every rung is reported, and the shell, a model of the same tube, times the discs' arrivals
// within a tenth of a millisecond of the solid's (a unit or sign error would not)
TEST(ReferenceCliTest, ConvergenceReportComparesTheShellWithTheSolid) {
  TempDir dir;
  const auto run = RunCli(
      "reference --compare-shell --ideal --element-m 0.04 --max-frequency 1500 --levels 3 "
      "--ratio 1.3 --out R.md --json -q",
      dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  // two coarser meshes and the shell's default grid (2.5 x 2.5 mm: its axial spacing is the arc's)
  ASSERT_EQ(j["rungs"].size(), 3u);
  for (const auto& rung : j["rungs"]) {
    const double arrival = rung["arrival_error_s"][0], delay = rung["delay_error_s"][0];
    EXPECT_LT(arrival, 1e-4) << rung["rung"];
    EXPECT_LT(delay, 1e-4) << rung["rung"];
  }
  EXPECT_GT(j["levels"][2]["dofs"].get<int64_t>(), j["levels"][0]["dofs"].get<int64_t>());
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "R.md"));
  // the ideal tube's modes come in degenerate pairs that each mesh turns freely: followed by shape
  // against their pair's span, most are followed (24 of 27; against single shapes, 5); the rest
  // move more than 5 % on the coarsest mesh
  const int64_t followed = j["followed_by_shape"];
  int64_t by_rank = 0;
  for (const auto& band : j["bands"]) by_rank += band["modes"].get<int64_t>();
  EXPECT_GE(followed, 3 * by_rank / 4);
  ASSERT_FALSE(j["bands_by_shape"].empty());
}


// `exact`: a coarse solid to 1.5 kHz against exact 3-D elasticity, every exact mode matched in
// its family, the table written; an out-of-range option refused naming it
TEST(ReferenceCliTest, ExactTablesACoarseSolidAgainstExactElasticity) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  auto run = RunCli("exact --no-shell --solid-element 0.05 --max-frequency 1500 --out E.md --json -q",
                    cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["exact_count_high"].get<int64_t>(), 19);  // 9 pairs and the (1, 0) torsion below it
  const auto& solid = j["rows"][0];
  EXPECT_EQ(solid["by_family_high"]["matched"].get<int64_t>(), 19);
  // 50 mm elements: the mesh's own error (solid_test checks a finer mesh to 0.3 %)
  EXPECT_LT(solid["by_family_high"]["max_abs"].get<double>(), 0.1);
  EXPECT_TRUE(std::filesystem::is_regular_file(cwd + "/E.md"));
  run = RunCli("exact --no-shell --radial-degree 40", cwd);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--radial-degree"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace sonicboom
