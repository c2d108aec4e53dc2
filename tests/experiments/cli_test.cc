// End-to-end CLI: the acceptance checks of the foundation and its error paths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "common/workspace.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/files.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using testing::RunCli;
using testing::TempDir;

// a short record keeps the end-to-end tests fast
const std::string kShort = testing::kShortRecordArgs;

TEST(CliTest, HelpListsEverySubcommand) {
  TempDir dir;
  const auto run = RunCli("--help", dir.path().string());
  EXPECT_EQ(run.exit_code, 0);
  for (const char* sub : {"demo", "generate", "synth", "modes", "features", "train", "eval",
                          "localize", "fk", "inspect", "fidelity", "calibrate", "reference"}) {
    EXPECT_NE(run.out.find(sub), std::string::npos) << sub;
  }
}

// Every generated block of docs/*.md equals what its command prints now (the defaults as the
// config structs serialize them); scripts/update_docs_defaults.py rewrites a stale one.
TEST(CliTest, DocsDefaultsTablesAreCurrent) {
  TempDir dir;
  const std::string begin = "<!-- generated: sonicboom config --markdown ",
                    end = "<!-- end generated -->";
  int blocks = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::string(SONICBOOM_SOURCE_DIR) + "/docs")) {
    if (entry.path().extension() != ".md") continue;
    std::ifstream in(entry.path());
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    for (size_t at = text.find(begin); at != std::string::npos; at = text.find(begin, at + 1)) {
      const size_t open_end = text.find(" -->\n", at);
      const size_t close = text.find(end, at);
      ASSERT_NE(open_end, std::string::npos) << entry.path();
      ASSERT_NE(close, std::string::npos) << entry.path() << ": block without its end marker";
      const std::string sections = text.substr(at + begin.size(), open_end - at - begin.size());
      const std::string body = text.substr(open_end + 5, close - open_end - 5);
      const auto run = RunCli("config --markdown " + sections, dir.path().string());
      ASSERT_EQ(run.exit_code, 0) << run.err;
      EXPECT_EQ(body, run.out)
          << entry.path() << " (" << sections
          << ") is stale: run /usr/bin/python3 scripts/update_docs_defaults.py";
      ++blocks;
    }
  }
  EXPECT_GE(blocks, 2);
  // a section that does not exist is named, with the ones that do
  const auto bad = RunCli("config --markdown tube,tubes", dir.path().string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("no config section 'tubes' (sections: tube, material"), std::string::npos)
      << bad.err;
}

TEST(CliTest, SynthWritesLabelledWav) {
  TempDir dir;
  const auto run = RunCli("synth --out s.wav --index 3 --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const AudioClip clip = ReadWav(dir / "s.wav", 6);
  EXPECT_EQ(clip.sample_rate_hz, 44100.0);
  EXPECT_TRUE(clip.samples.allFinite());
  EXPECT_GT(clip.samples.cwiseAbs().maxCoeff(), 1e-3);
  std::ifstream in(dir / "s.json");
  const json label = json::parse(in);
  const double z = label["z_m"], theta = label["theta_rad"];
  EXPECT_GE(z, -0.1015);
  EXPECT_LE(z, 0.1015);
  EXPECT_GT(theta, -M_PI);
  EXPECT_LE(theta, M_PI);
  // the raw MuJoCo contact point: on the surface to within 1 mm, never projected
  const double x = label["point_m"][0], y = label["point_m"][1];
  EXPECT_NEAR(std::hypot(x, y), 0.05355, 1e-3);
  EXPECT_NEAR(std::atan2(y, x), theta, 1e-9);
  EXPECT_TRUE(fs::exists(dir / "s.wav.config.yaml"));
}

TEST(CliTest, GenerateFiftyAndInspect) {
  TempDir dir;
  auto run = RunCli(kShort + "generate --count 50 --out D.h5 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("inspect D.h5 --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json summary = json::parse(run.out);
  EXPECT_EQ(summary["num_samples"], 50);
  EXPECT_EQ(summary["valid"], 50);
  EXPECT_EQ(summary["complete"], true);
  EXPECT_TRUE(fs::exists(dir / "D.h5.config.yaml"));
}

TEST(CliTest, ModesAndFkJson) {
  TempDir dir;
  auto run = RunCli("modes --json --boundary free --ideal --count 6", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json modes = json::parse(run.out);
  ASSERT_EQ(modes["frequencies_hz"].size(), 6u);
  EXPECT_NEAR(modes["frequencies_hz"][0].get<double>(), 220, 2);
  EXPECT_EQ(modes["rigid_body_modes"], 6);
  // --set reaches the tube keys: a thicker wall raises the ring modes
  run = RunCli("modes --json --boundary free --ideal --count 2 --set tube.wall_thickness_m=0.0061",
               dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_GT(json::parse(run.out)["frequencies_hz"][0].get<double>(), 400);
  run = RunCli("fk --joints 0,0,0,-0.1,0,0,0 --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json fk = json::parse(run.out);
  EXPECT_EQ(fk["flange_pos_m"].size(), 3u);
  EXPECT_EQ(fk["tube_quat_wxyz"].size(), 4u);
}

// inspect --png: a dataset's coverage and one strike's channels, drawn from PNG.json by the
// plotting script; anything but a dataset, or a row it lacks, is refused
TEST(CliTest, InspectDrawsADatasetFigure) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string plot = " --plot " + std::string(SONICBOOM_SOURCE_DIR) + "/scripts/plot.py";
  ASSERT_EQ(RunCli(kShort + "-q generate --count 4 --out D.h5", cwd).exit_code, 0);
  auto run = RunCli("--json inspect D.h5 --png I.png --strike 2" + plot, cwd);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["png"], "I.png");
  std::ifstream png(dir.path() / "I.png", std::ios::binary);
  std::string magic(8, '\0');
  png.read(magic.data(), 8);
  EXPECT_EQ(magic, "\x89PNG\r\n\x1a\n");
  EXPECT_GT(fs::file_size(dir.path() / "I.png"), 20000u);
  std::ifstream data(dir.path() / "I.png.json");
  const json figure = json::parse(data);
  EXPECT_EQ(figure["coverage"]["z_m"].size(), 4u);
  EXPECT_EQ(figure["strike"]["row"], 2);
  ASSERT_EQ(figure["strike"]["envelopes"].size(), 6u);
  EXPECT_EQ(figure["strike"]["frames"], 26460);  // 0.6 s at 44.1 kHz
  EXPECT_EQ(figure["strike"]["envelopes"][0]["max"].size(), 1500u);
  // an existing figure is replaced only with --force
  run = RunCli("inspect D.h5 --png I.png --strike 1" + plot, cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("I.png: exists; --force"), std::string::npos) << run.err;
  run = RunCli("inspect D.h5 --png I.png --strike 4 --force" + plot, cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--strike 4: D.h5 holds rows 0 to 3"), std::string::npos) << run.err;
  run = RunCli("inspect D.h5.config.yaml --png C.png" + plot, cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--png draws a dataset"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir.path() / "C.png"));
}

TEST(CliTest, FidelityQuickWritesItsTable) {
  // every rung renders against the reference solid, the yardstick is exact against itself, the
  // shell renders the solid's polarity, and the table, its JSON and its figure land where asked
  TempDir dir;
  const std::string plot = std::string(SONICBOOM_SOURCE_DIR) + "/scripts/plot.py";
  const auto run = RunCli(
      "fidelity --quick --strikes 1 --window-s 0.006 --out F.md --json -q --signals S "
      "--plot " +
          plot,
      dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  ASSERT_EQ(j["rungs"].size(), 25u);
  const json& rungs = j["rungs"];
  // the default rung (thick-plate) plays other frequencies than its thin twin on the same grid;
  // an FD rung's are those its grid solves, the thin modal rung's of that grid
  const auto find = [&](const std::string& name, const std::string& grid) {
    for (const json& r : rungs)
      if (r["rung"] == name && r["grid"] == grid) return r;
    ADD_FAILURE() << "no rung " << name << " on " << grid;
    return json();
  };
  json def;
  for (const json& r : rungs)
    if (r["rung"] == "modal, derived band (default)") def = r;
  ASSERT_FALSE(def.is_null());
  const std::string mark = ", thick-plate";
  std::string grid = def["grid"].get<std::string>();
  ASSERT_TRUE(grid.ends_with(mark)) << grid;
  grid.resize(grid.size() - mark.size());
  const json thin = find("modal, derived band", grid);
  EXPECT_NE(def["frequency_median_pct"], thin["frequency_median_pct"]);
  json fd;
  for (const json& r : rungs)
    if (r["rung"] == "FD" && fd.is_null()) fd = r;  // on the configured arc, twice the axial
  ASSERT_FALSE(fd.is_null());
  EXPECT_EQ(fd["frequency_median_pct"],
            find("modal, derived band", fd["grid"].get<std::string>())["frequency_median_pct"]);
  EXPECT_EQ(rungs[0]["kind"], "solid");
  EXPECT_EQ(rungs[0]["relative_error"].get<double>(), 0.0);
  for (const json& r : rungs) {
    EXPECT_TRUE(std::isfinite(r["relative_error"].get<double>())) << r.dump();
    EXPECT_TRUE(std::isfinite(r["delay_error_us"].get<double>())) << r.dump();
    EXPECT_GT(r["ms_per_strike"].get<double>(), 0.0) << r.dump();
  }
  // the default shell rung and the solid: one polarity (the opposite sign would be an error
  // near 2, measured 0.76 at the quick settings; 1.84 when the shell pushed the wall outward),
  // and one tube: as many modes below the compared band within 20 % (227 against 209)
  for (const json& r : rungs) {
    if (r["rung"] != "modal, derived band (default)") continue;
    EXPECT_LT(r["relative_error"].get<double>(), 1.0) << r.dump();
    const double ratio =
        r["frequency_modes"].get<double>() / r["frequency_reference_modes"].get<double>();
    EXPECT_NEAR(ratio, 1.0, 0.2) << r.dump();
  }
  // the FD rung that closes its own contact hears nearly the strike the modal wall's force
  // gives the FD grid, but not the same numbers (its force is its own)
  const auto row = [&](const std::string& name) {
    for (const json& r : rungs)
      if (r["rung"] == name) return r;
    ADD_FAILURE() << "no row " << name;
    return json{};
  };
  const json prescribed = row("FD"), own = row("FD, contact on its own wall");
  EXPECT_EQ(prescribed["grid"], own["grid"]);
  EXPECT_NE(prescribed["relative_error"], own["relative_error"]);
  EXPECT_NEAR(own["relative_error"].get<double>(), prescribed["relative_error"].get<double>(), 0.1);
  EXPECT_GT(j["whole_strike_ms"].get<double>(), 0.0);
  // a fixed band's scene: modes solved to 1.25 x the band on its derived grid, fewer DOFs and
  // modes as the band falls; its rung in the ladder plays that band
  const json& scenes = j["mode_band"];
  ASSERT_EQ(scenes.size(), 4u);
  const double solved[] = {20000.0, 12500.0, 6250.0, 2500.0};
  for (size_t k = 0; k < scenes.size(); ++k) {
    EXPECT_DOUBLE_EQ(scenes[k]["solved_band_hz"].get<double>(), solved[k]) << scenes[k].dump();
    if (k > 1) {
      EXPECT_LT(scenes[k]["dofs"].get<int64_t>(), scenes[k - 1]["dofs"].get<int64_t>());
      EXPECT_LT(scenes[k]["modes"].get<int64_t>(), scenes[k - 1]["modes"].get<int64_t>());
      EXPECT_GT(scenes[k]["arc_m"].get<double>(), scenes[k - 1]["arc_m"].get<double>());
    }
  }
  EXPECT_LT(row("modal, 2 kHz, derived grid")["modes"].get<double>(),
            row("modal, 5 kHz, derived grid")["modes"].get<double>());
  EXPECT_TRUE(std::filesystem::exists(dir / "F.md"));
  EXPECT_TRUE(std::filesystem::exists(dir / "F.json"));
  EXPECT_GT(std::filesystem::file_size(dir / "F_pareto.png"), 10000u);
  // --signals: one array per row (1 strike x 6 mics x the window's samples, float64) and an index
  std::ifstream index(dir / "S/index.json");
  ASSERT_TRUE(index) << "no S/index.json";
  const json signals = json::parse(index);
  ASSERT_EQ(signals.size(), 25u);
  EXPECT_EQ(signals[0]["rung"], rungs[0]["rung"]);
  // header (128 bytes for this shape) plus 1 x 6 x 309 doubles
  EXPECT_EQ(std::filesystem::file_size(dir / ("S/" + signals[3]["file"].get<std::string>())),
            128u + 8u * 6u * 309u);
  // bad options are refused before any work, naming them
  const auto bad = RunCli("fidelity --strikes 9 --out F.md", dir.path().string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("--strikes"), std::string::npos);
  const auto no_script = RunCli("fidelity --out F.md --plot nowhere.py", dir.path().string());
  EXPECT_NE(no_script.exit_code, 0);
  EXPECT_NE(no_script.err.find("--plot nowhere.py"), std::string::npos);
  const auto band = RunCli("fidelity --out F.md --reference-band 40000", dir.path().string());
  EXPECT_EQ(band.exit_code, 1);
  EXPECT_NE(band.err.find("--reference-band"), std::string::npos);
}

TEST(CliTest, FeaturesOfSynthWav) {
  TempDir dir;
  ASSERT_EQ(RunCli("synth --out s.wav -q", dir.path().string()).exit_code, 0);
  const auto run = RunCli("features --in s.wav --out F.h5 --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json j = json::parse(run.out);
  EXPECT_EQ(j["mel_shape"], json({6, 50, 517}));
  EXPECT_EQ(j["gcc_shape"], json({15, 883}));
  const auto inspect = RunCli("inspect F.h5 --json", dir.path().string());
  ASSERT_EQ(inspect.exit_code, 0) << inspect.err;
  EXPECT_EQ(json::parse(inspect.out)["complete"], true);
}

// train.rotate_rings turns records by 120 degrees: it refuses discs that are not rings of three
// 120 degrees apart before anything is trained, and trains on the configured layout
TEST(CliTest, RotateRingsNeedsRingsOfThreeDiscs) {
  TempDir dir;
  const std::string tiny = kShort + testing::kTinyModelArgs +
                           "--set train.epochs=1 --set strike.engine=kinematic "
                           "--set model.modalities=[audio] --set train.rotate_rings=true ";
  auto run = RunCli(tiny + "generate --count 12 --out D.h5 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli(tiny + "--set mics.theta_deg=[0,90,240,0,120,240] train --data D.h5 --out BAD -q",
               dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("train.rotate_rings"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("mics.theta_deg"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "BAD/model.pt"));
  // mirroring is about theta 0, where disc 0 must sit
  run = RunCli(tiny +
                   "--set train.mirror_rings=true --set mics.theta_deg=[30,150,270,30,150,270] "
                   "train --data D.h5 --out BAD -q",
               dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("train.mirror_rings"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("mics.theta_deg[0] = 0"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "BAD/model.pt"));
  run = RunCli(tiny + "train --data D.h5 --out RUN -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir / "RUN/model.pt"));
}

// 30 short strikes, the dataset of the tiny-model tests below
void BuildThirtyStrikes(const fs::path& dir) {
  testing::RunEach({kShort + "generate --count 30 --out D.h5 -q"}, dir);
}

constexpr testing::Workspace kThirtyStrikes{"cli_thirty_strikes", BuildThirtyStrikes};

// Built once per ctest run (the fixture of the tests below) for them to copy
TEST(CliStrikesWorkspace, IsBuilt) {
  testing::PublishWorkspace(kThirtyStrikes);
}

TEST(CliTest, TrainEvalLocalizeTinyModel) {
  TempDir dir;
  testing::UseWorkspace(kThirtyStrikes, dir.path());
  const std::string tiny = kShort + testing::kTinyModelArgs + "--set train.epochs=2 ";
  auto run = RunCli(tiny + "train --data D.h5 --out RUN -q --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir / "RUN/config.yaml"));
  EXPECT_TRUE(fs::exists(dir / "RUN/model.pt"));
  run = RunCli("eval --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json metrics = json::parse(run.out);
  for (const char* key :
       {"n", "med_cm", "height_err_cm", "angle_err_deg", "reference_med_cm", "z_coverage_50",
        "z_coverage_90", "theta_coverage_50", "theta_coverage_90", "nll"}) {
    EXPECT_TRUE(metrics.contains(key)) << key;
  }
  EXPECT_EQ(metrics["n"], 30);
  // coverage is a fraction, and the 90 % interval covers at least what the 50 % one does
  EXPECT_GE(metrics["z_coverage_90"].get<double>(), metrics["z_coverage_50"].get<double>());
  EXPECT_LE(metrics["z_coverage_90"].get<double>(), 1.0);
  EXPECT_GT(metrics["med_cm"].get<double>(), 0.0);
  // --predictions: one row per strike whose errors average to the MED; not replaced without
  // --force
  run = RunCli("eval --model RUN --data D.h5 -q --predictions P.csv", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  {
    std::ifstream csv(dir / "P.csv");
    std::string line;
    std::getline(csv, line);
    EXPECT_EQ(line, "index,z_m,theta_rad,z_pred_m,theta_pred_rad,z_std_m,theta_kappa,error_cm");
    double sum = 0.0;
    int rows = 0;
    while (std::getline(csv, line)) {
      sum += std::stod(line.substr(line.rfind(',') + 1));
      ++rows;
    }
    EXPECT_EQ(rows, 30);
    EXPECT_NEAR(sum / rows, metrics["med_cm"].get<double>(), 1e-4);
  }
  run = RunCli("eval --model RUN --data D.h5 -q --predictions P.csv", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("P.csv"), std::string::npos) << run.err;
  // calibrate: the refit scales multiply the stored ones, eval then reports the refit coverage,
  // and a second refit on the same strikes leaves sigma_z as it is (the kappa fit of so short a
  // training sits at its lower bound: a flat angle distribution fits best)
  run = RunCli("calibrate --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json first = json::parse(run.out);
  for (const char* key : {"z_std_scale", "kappa_scale"}) {
    EXPECT_NEAR(first["after"][key].get<double>(),
                first["before"][key].get<double>() * first["relative"][key].get<double>(),
                1e-12 * first["after"][key].get<double>())
        << key;
  }
  EXPECT_EQ(json::parse(ReadText(dir / "RUN/model.json"))["uncertainty"]["calibrated_on"], "D.h5");
  run = RunCli("eval --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NEAR(json::parse(run.out)["nll"].get<double>(),
              first["metrics_after"]["nll"].get<double>(), 1e-9);
  run = RunCli("calibrate --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json second = json::parse(run.out);
  EXPECT_NEAR(second["relative"]["z_std_scale"].get<double>(), 1.0, 1e-9);
  run = RunCli("calibrate --model RUN --data missing.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("missing.h5"), std::string::npos) << run.err;
  // localize a strike synthesized with the run's own config
  run = RunCli("--config RUN/config.yaml synth --out s.wav --index 100 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("localize --model RUN --wav s.wav --json -q --repeat 3", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json where = json::parse(run.out);
  EXPECT_GT(where["latency_ms"].get<double>(), 0.0);
  // each stage's median is positive and not above the whole's (with slack: medians of the
  // stages need not add up to the median of the sum)
  for (const char* stage : {"read", "features", "network"}) {
    const double ms = where["latency_breakdown_ms"][stage].get<double>();
    EXPECT_GT(ms, 0.0) << stage;
    EXPECT_LE(ms, where["latency_ms"].get<double>() * 1.5) << stage;
  }
  EXPECT_GT(where["z_std_m"].get<double>(), 0.0);
  const double z_lo = where["z_interval_90_m"][0], z_hi = where["z_interval_90_m"][1];
  EXPECT_LT(z_lo, where["z_m"].get<double>());
  EXPECT_GT(z_hi, where["z_m"].get<double>());
  const double x = where["point_m"][0], y = where["point_m"][1];
  EXPECT_NEAR(std::hypot(x, y), 0.05355, 1e-9);
  EXPECT_NEAR(where["point_m"][2].get<double>(), where["z_m"].get<double>(), 1e-12);
  // the run directory and its files are inspectable
  run = RunCli("inspect RUN --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json card = json::parse(run.out);
  EXPECT_EQ(card["epochs_logged"], 2);
  EXPECT_EQ(card["calibration"]["calibrated_on"], "D.h5");  // by calibrate, above
  // trainable parameters per part add up to the total
  int64_t sum = 0;
  for (const char* part : {"audio_encoder", "gcc_encoder", "proprio_encoder", "fusion"}) {
    sum += card["parameters"][part].get<int64_t>();
  }
  EXPECT_EQ(card["parameters"]["total"].get<int64_t>(), sum);
  EXPECT_GT(sum, 0);
  // --repeat must be positive
  run = RunCli("localize --model RUN --wav s.wav --repeat 0", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--repeat"), std::string::npos) << run.err;
  for (const char* file : {"RUN/metrics.jsonl", "RUN/model.json", "RUN/model.pt", "s.json"}) {
    run = RunCli(std::string("inspect ") + file + " --json", dir.path().string());
    EXPECT_EQ(run.exit_code, 0) << file << ": " << run.err;
  }
  // a model cannot localize a WAV of another channel count
  AudioClip stereo{Eigen::MatrixXf::Constant(2, 30000, 0.1f), 44100.0};
  WriteWav(dir / "stereo.wav", stereo);
  run = RunCli("localize --model RUN --wav stereo.wav", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("stereo.wav"), std::string::npos) << run.err;
}

// bad input: non-zero exit, a message naming the culprit, no complete-looking output
// `train --pseudo-labels F`: the pretrained run's surest answers (smallest predictive spread on
// the surface) become the labels of a fine-tune, and their error against the real labels is
// reported
TEST(CliTest, PseudoLabelsAreThePretrainedRunsSurestAnswers) {
  TempDir dir;
  testing::UseWorkspace(kThirtyStrikes, dir.path());
  const std::string tiny = kShort + testing::kTinyModelArgs + "--set train.epochs=2 ";
  auto run = RunCli(tiny + "train --data D.h5 --out RUN -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("eval --model RUN --data D.h5 -q --predictions P.csv", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  // (spread cm, row, error cm) of each answer, surest first (ties: lower row)
  std::vector<std::tuple<double, int, double>> answers;
  {
    std::ifstream csv(dir / "P.csv");
    std::string line;
    std::getline(csv, line);
    for (int row = 0; std::getline(csv, line); ++row) {
      std::vector<double> v;
      std::stringstream cells(line);
      for (std::string cell; std::getline(cells, cell, ',');) v.push_back(std::stod(cell));
      ASSERT_EQ(v.size(), 8u) << line;
      const double along_m = 0.05355 * learning::VonMisesCircularStd(v[6]);
      answers.emplace_back(100.0 * std::hypot(v[5], along_m), row, v[7]);
    }
  }
  ASSERT_EQ(answers.size(), 30u);
  std::sort(answers.begin(), answers.end());
  double med = 0.0;
  for (int k = 0; k < 15; ++k) med += std::get<2>(answers[k]) / 15.0;
  run = RunCli(tiny +
                   "train --init-from RUN --data D.h5 --out PL --pseudo-labels 0.5 --epochs 1 "
                   "-q --json",
               dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json pseudo = json::parse(run.out)["pseudo_labels"];
  EXPECT_EQ(pseudo["records"], 30);
  EXPECT_EQ(pseudo["kept"], 15);
  EXPECT_NEAR(pseudo["spread_limit_cm"].get<double>(), std::get<0>(answers[14]),
              1e-5 * std::get<0>(answers[14]));
  EXPECT_NEAR(pseudo["med_cm_against_labels"].get<double>(), med, 1e-4);
  EXPECT_EQ(json::parse(ReadText(dir / "PL/pseudo_labels.json")), pseudo);
  // a label source is needed, and the fraction lies in (0, 1]
  run = RunCli("train --data D.h5 --out PL2 --pseudo-labels 0.5", dir.path().string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--pseudo-labels labels strikes by a pretrained run"), std::string::npos)
      << run.err;
  run =
      RunCli("train --init-from RUN --data D.h5 --out PL2 --pseudo-labels 0", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--pseudo-labels"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "PL2"));
}

TEST(CliTest, EnsembleRunIsOneModelForEvalLocalizeAndInspect) {
  TempDir dir;
  testing::UseWorkspace(kThirtyStrikes, dir.path());
  const std::string tiny =
      kShort + testing::kTinyModelArgs + "--set train.epochs=1 --set train.ensemble_members=2 ";
  auto run = RunCli(tiny + "train --data D.h5 --out RUN -q --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const char* file : {"RUN/ensemble.json", "RUN/config.yaml", "RUN/member0/model.pt",
                           "RUN/member1/model.pt", "RUN/member1/config.yaml"}) {
    EXPECT_TRUE(fs::exists(dir / file)) << file;
  }
  EXPECT_FALSE(fs::exists(dir / "RUN.partial"));
  // eval, inspect and localize read the directory as one model
  run = RunCli("eval --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json::parse(run.out)["n"], 30);
  // and each member is a run of its own
  run = RunCli("eval --model RUN/member1 --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  // calibrate refits the combination's scales in ensemble.json, and eval reads them
  run = RunCli("calibrate --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json refit = json::parse(run.out);
  const json stored = json::parse(ReadText(dir / "RUN/ensemble.json"));
  EXPECT_EQ(stored["members"].size(), 2u);
  EXPECT_DOUBLE_EQ(stored["uncertainty"]["z_std_scale"].get<double>(),
                   refit["after"]["z_std_scale"].get<double>());
  run = RunCli("eval --model RUN --data D.h5 --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NEAR(json::parse(run.out)["nll"].get<double>(),
              refit["metrics_after"]["nll"].get<double>(), 1e-9);
  run = RunCli("inspect RUN --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json card = json::parse(run.out);
  EXPECT_EQ(card["ensemble_members"], 2);
  EXPECT_TRUE(card["complete"].get<bool>());
  EXPECT_EQ(card["calibration"]["calibrated_on"], "D.h5");
  run = RunCli("--config RUN/config.yaml synth --out s.wav --index 5 -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  run = RunCli("localize --model RUN --wav s.wav --json -q", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_GT(json::parse(run.out)["z_std_m"].get<double>(), 0.0);
}

TEST(CliErrorTest, MissingFile) {
  TempDir dir;
  const auto run = RunCli("features --in nothere.wav --out F.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("nothere.wav"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "F.h5"));
}

TEST(CliErrorTest, CorruptTruncatedAndWrongChannelWav) {
  TempDir dir;
  std::ofstream(dir / "corrupt.wav") << "RIFF this is not audio";
  auto run = RunCli("features --in corrupt.wav --out F.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("corrupt.wav"), std::string::npos) << run.err;
  // truncated: a valid WAV cut in half
  ASSERT_EQ(RunCli("synth --out t.wav -q", dir.path().string()).exit_code, 0);
  fs::resize_file(dir / "t.wav", fs::file_size(dir / "t.wav") / 2);
  run = RunCli("features --in t.wav --out F.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("t.wav"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("truncated"), std::string::npos) << run.err;
  // two channels where six are needed
  AudioClip stereo{Eigen::MatrixXf::Constant(2, 1000, 0.1f), 44100.0};
  WriteWav(dir / "stereo.wav", stereo);
  run = RunCli("features --in stereo.wav --out F.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("expected 6 channels, found 2"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "F.h5"));
}

TEST(CliErrorTest, UnknownKeyAndOutOfRangeValue) {
  TempDir dir;
  auto run =
      RunCli("generate --count 5 --out D.h5 --set tube.outer_radius=0.05", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("tube.outer_radius"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "D.h5"));
  std::ofstream(dir / "bad.yaml") << "material:\n  density_kg_m3: -5\n";
  run = RunCli("generate --count 5 --out D.h5 --config bad.yaml", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("material.density_kg_m3"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("bad.yaml"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "D.h5"));
  run = RunCli("fk --joints 0,0,0,0.5,0,0,0", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("joint 4"), std::string::npos) << run.err;
  run = RunCli("inspect missing.h5", dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("missing.h5"), std::string::npos) << run.err;
}

TEST(CliErrorTest, FailedRunKeepsThePreviousFile) {
  TempDir dir;
  ASSERT_EQ(RunCli(kShort + "generate --count 3 --out D.h5 -q", dir.path().string()).exit_code, 0);
  const auto size = fs::file_size(dir / "D.h5");
  // an invalid shard request fails before touching the finished file
  const auto run = RunCli(kShort + "generate --count 3 --out D.h5 --shard 4 --num-shards 2",
                          dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--shard"), std::string::npos) << run.err;
  EXPECT_EQ(fs::file_size(dir / "D.h5"), size);
  EXPECT_NO_THROW(DatasetReader(dir / "D.h5"));
}

// Counts and indices outside their limits are refused before anything is written (--first-index -1
// once wrote index 0, a huge --first-index overflowed, --repeat 1e12 ran for ever).
TEST(CliErrorTest, NumericOptionsAreFiniteNumbersInWords) {
  // NaN passed CLI11's positive check and was dropped (the run kept its old rate); 0 was refused
  // with the largest double in 309 digits
  TempDir dir;
  for (const auto& [args, said] : std::vector<std::pair<std::string, std::string>>{
           {"train --data D.h5 --out R --lr nan", "'nan' is not a number in (0, 1]"},
           {"train --data D.h5 --out R --lr 0", "'0' is not a number in (0, 1]"},
           {"train --data D.h5 --out R --lr 1e308", "is not a number in (0, 1]"},
           {"train --data D.h5 --out R --epochs 0", "is not a whole number in [1, 100000]"},
           {"train --data D.h5 --out R --epochs 2.5", "is not a whole number"},
           {"--threads -1 inspect D.h5", "is not a whole number in [0, 4096]"}}) {
    const auto run = RunCli(args, dir.path().string());
    EXPECT_EQ(run.exit_code, 2) << args << ": " << run.err;
    EXPECT_NE(run.err.find(said), std::string::npos) << args << ": " << run.err;
    EXPECT_EQ(run.err.find("1797693"), std::string::npos) << run.err;
  }
}

TEST(CliErrorTest, CountsAndIndicesOutsideTheirLimitsNameTheOption) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::pair<std::string, std::string> cases[] = {
      {"generate --count 2 --first-index -1 --out G.h5", "--first-index must be in [0, "},
      {"generate --count 3 --first-index 9223372036854775806 --out G.h5",
       "--first-index must be in [0, 1000000000000000], got 9223372036854775806"},
      {"generate --count -1 --out G.h5", "--count must be in [1, 1000000000], got -1"},
      {"generate --count 0 --out G.h5", "--count must be in [1, 1000000000], got 0"},
      {"localize --model RUN --wav S.wav --repeat 1000000000000",
       "--repeat must be in [1, 10000], got 1000000000000"},
  };
  for (const auto& [args, message] : cases) {
    const auto run = RunCli(kShort + args, cwd);
    EXPECT_EQ(run.exit_code, 1) << args;
    EXPECT_NE(run.err.find(message), std::string::npos) << args << ": " << run.err;
  }
  EXPECT_FALSE(fs::exists(dir / "G.h5"));
}

// A command never writes over its own input: features onto its dataset or WAV, merge onto one of
// its shards (each once destroyed the input and exited 0).
TEST(CliErrorTest, OutputThatIsAnInputIsRefusedAndTheInputKept) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  ASSERT_EQ(RunCli(kShort + "generate --count 2 --out D.h5 -q", cwd).exit_code, 0);
  ASSERT_EQ(RunCli(kShort + "generate --count 2 --first-index 2 --out E.h5 -q", cwd).exit_code, 0);
  ASSERT_EQ(RunCli("synth --out S.wav -q", cwd).exit_code, 0);
  auto bytes = [&](const char* name) {
    std::ifstream in(dir / name, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  const std::string d = bytes("D.h5"), w = bytes("S.wav");
  auto run = RunCli("features --in D.h5 --out ./D.h5", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("./D.h5: --out is an input (--in D.h5)"), std::string::npos) << run.err;
  run = RunCli("features --in S.wav --out S.wav", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("S.wav: --out is an input (--in S.wav)"), std::string::npos) << run.err;
  run = RunCli("merge --out D.h5 D.h5 E.h5", cwd);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("D.h5: --out is an input (shard D.h5)"), std::string::npos) << run.err;
  EXPECT_EQ(bytes("D.h5"), d);
  EXPECT_EQ(bytes("S.wav"), w);
  EXPECT_NO_THROW(DatasetReader(dir / "D.h5"));
  // a different output still works
  EXPECT_EQ(RunCli("merge --out M.h5 D.h5 E.h5 -q", cwd).exit_code, 0);
}

}  // namespace
}  // namespace sonicboom
