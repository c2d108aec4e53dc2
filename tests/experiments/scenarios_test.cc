// The shipped scenario configs (configs/*.yaml) generate small datasets through the CLI.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/test_util.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using testing::RunCli;
using testing::TempDir;

struct Scenario {
  const char* config;                        // under configs/
  std::vector<std::string> object_prefixes;  // every contact's object starts with one of these
  const char* extra;                         // more CLI options
  bool brushes{false};                       // valid samples include foliage brushes
};

// readable test names in gtest and ctest output
void PrintTo(const Scenario& s, std::ostream* os) {
  *os << s.config;
}

std::string ConfigPath(const char* name) {
  return std::string(SONICBOOM_SOURCE_DIR) + "/configs/" + name;
}

bool StartsWithAny(const std::string& name, const std::vector<std::string>& prefixes) {
  for (const std::string& p : prefixes) {
    if (name.rfind(p, 0) == 0) return true;
  }
  return false;
}

class ScenarioTest : public ::testing::TestWithParam<Scenario> {};

TEST_P(ScenarioTest, GeneratesEightSamplesWithContacts) {
  const Scenario& s = GetParam();
  const std::string config = ConfigPath(s.config);
  ASSERT_TRUE(fs::exists(config)) << config;
  TempDir dir;
  const std::string out = dir / "D.h5";
  auto run = RunCli(
      "--config '" + config + "' " + s.extra + " generate --count 8 --out '" + out + "' -q --json",
      dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json generated = json::parse(run.out);
  EXPECT_EQ(generated["written"], 8);
  ASSERT_TRUE(fs::exists(out));
  EXPECT_TRUE(fs::exists(out + ".config.yaml"));

  run = RunCli("inspect '" + out + "' --json", dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json summary = json::parse(run.out);
  EXPECT_EQ(summary["num_samples"], 8);
  EXPECT_EQ(summary["complete"], true);
  ASSERT_TRUE(summary.contains("contacts"));
  const json& contacts = summary["contacts"];
  ASSERT_TRUE(contacts.is_object());
  EXPECT_EQ(contacts["recorded"], true);
  const int valid = summary["valid"].get<int>();
  std::cout << s.config << ": " << valid << " / 8 valid; invalid reasons "
            << summary["invalid_reasons"].dump() << "; objects " << contacts["objects"].dump()
            << "\n";
  EXPECT_GE(valid, 1);
  // every contact of a valid sample names an object of the scenario
  ASSERT_TRUE(contacts["objects"].is_object());
  if (valid > 0) {
    EXPECT_FALSE(contacts["objects"].empty());
  }
  for (const auto& [name, count] : contacts["objects"].items()) {
    EXPECT_TRUE(StartsWithAny(name, s.object_prefixes)) << s.config << ": " << name;
    EXPECT_GT(count.get<int>(), 0);
  }
  // every valid sample has a first hard contact; foliage only brushes
  EXPECT_GE(contacts["kinds"]["impact"].get<int>(), valid);
  if (s.brushes) {
    EXPECT_GT(contacts["kinds"]["brush"].get<int>(), 0);
  } else {
    EXPECT_EQ(contacts["kinds"]["brush"].get<int>(), 0);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Configs, ScenarioTest,
    ::testing::Values(
        Scenario{"ts1.yaml", {"rod T12L42", "rod T22L42", "rod T25L42", "rod T32L42"}, ""},
        Scenario{"ts2.yaml", {"rod ", "cross "}, ""},
        // guided: the last grid points lie in the canopy (131 points; 4 taps each)
        Scenario{"ts3.yaml", {"branch ", "leaves"}, "--set dataset.first_index=504", true},
        Scenario{"ts4.yaml", {"striker wood T"}, ""},
        Scenario{"materials.yaml",
                 {"striker wood T22L40", "striker aluminium T25L40", "striker pvc T21L40"},
                 ""}),
    [](const ::testing::TestParamInfo<Scenario>& info) {
      std::string name = info.param.config;
      return name.substr(0, name.find('.'));
    });

// The randomized preset layered over a scenario: every sample stores its draws, inside the
// preset's ranges, and differs in structure from its neighbours; a bad range writes nothing.
TEST(RandomizedPresetTest, LayersOverTs4AndStoresTheDraws) {
  TempDir dir;
  const std::string out = dir / "R.h5";
  auto run = RunCli(
      "--config '" + ConfigPath("ts4.yaml") + "' --config '" + ConfigPath("randomized.yaml") +
          "' --set randomize.structure_variants=2 generate --count 6 --out '" + out + "' -q --json",
      dir.path().string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  DatasetReader reader(out);
  const std::vector<std::string>& names = reader.info().variation_names;
  // 14 scalar ranges, 3 per-channel ones and 3 placement ones over 6 channels, the structure
  // variant and its 5 stored draws (bolt count, bolt stiffness, two mounts, Poisson's ratio)
  ASSERT_EQ(names.size(), 14u + 3u * 6u + 3u * 6u + 6u);
  const auto column = [&](const std::string& name) {
    const auto it = std::find(names.begin(), names.end(), name);
    EXPECT_NE(it, names.end()) << name;
    return static_cast<size_t>(it - names.begin());
  };
  std::vector<double> moduli;
  for (int64_t row = 0; row < reader.size(); ++row) {
    const StrikeSample s = reader.ReadMeta(row);
    ASSERT_EQ(s.variation.size(), names.size());
    const double t = s.variation[column("temperature_c")];
    EXPECT_GE(t, 10.0);
    EXPECT_LE(t, 35.0);
    // the stored modulus factor includes the temperature shift
    const double e = s.variation[column("youngs_modulus_scale")];
    EXPECT_GE(e, 0.85 * (1 - 0.004 * 15) - 1e-12);
    EXPECT_LE(e, 1.15 * (1 + 0.004 * 10) + 1e-12);
    moduli.push_back(e);
    // the structure variant of the two-variant pool, its bolts, the discs' placement
    const double variant = s.variation[column("structure_variant")];
    EXPECT_TRUE(variant == 0.0 || variant == 1.0) << variant;
    EXPECT_GE(s.variation[column("bolt_count")], 2.0);
    EXPECT_LE(s.variation[column("bolt_count")], 5.0);
    EXPECT_LE(std::abs(s.variation[column("mic_z_offset_m_3")]), 0.002);
    EXPECT_GE(s.variation[column("disc_diameter_m_1")], 0.015);
    EXPECT_GE(s.variation[column("highpass_hz_5")], 5.0);
    EXPECT_LE(s.variation[column("highpass_hz_5")], 150.0);
    // the first contact lies in 0.5 +- 0.25 s
    EXPECT_GE(s.label.time_s, 0.25);
    EXPECT_LE(s.label.time_s, 0.75 + 0.01);
  }
  std::sort(moduli.begin(), moduli.end());
  EXPECT_EQ(std::unique(moduli.begin(), moduli.end()), moduli.end());

  // min above max: refused naming the key, nothing written
  const std::string bad = dir / "bad.h5";
  run = RunCli("--config '" + ConfigPath("ts4.yaml") +
                   "' --set 'randomize.density_scale=[1.1, 0.9]' "
                   "generate --count 2 --out '" +
                   bad + "' -q",
               dir.path().string());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("randomize.density_scale"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(bad));
}

// Each range `layer` sets widens `preset`'s range of that key to 1.5x its width about its
// centre, in log for the log-uniform scales (integer bolt counts rounded outwards); returns how
// many ranges the layer sets
int ExpectRangesWidenedOneAndAHalfTimes(const std::string& preset_file,
                                        const std::string& layer_file) {
  const YAML::Node preset = YAML::LoadFile(ConfigPath(preset_file.c_str()))["randomize"];
  const YAML::Node layer = YAML::LoadFile(ConfigPath(layer_file.c_str()))["randomize"];
  const std::set<std::string> log_uniform = {"bolt_stiffness_scale", "flange_mount_scale",
                                             "tool_mount_scale"};
  int ranges = 0;
  for (const auto& entry : layer) {
    const std::string key = entry.first.as<std::string>();
    if (!entry.second.IsSequence()) continue;
    EXPECT_TRUE(preset[key]) << key << " is not a range of configs/" << preset_file;
    if (!preset[key]) continue;
    const bool log = log_uniform.count(key) > 0;
    const auto at = [&](const YAML::Node& range, int k) {
      return log ? std::log(range[k].as<double>()) : range[k].as<double>();
    };
    const double lo = at(preset[key], 0), hi = at(preset[key], 1);
    const double wide_lo = at(entry.second, 0), wide_hi = at(entry.second, 1);
    const double centre = 0.5 * (lo + hi), half = 0.75 * (hi - lo);
    if (key == "bolt_count") {
      EXPECT_EQ(wide_lo, std::floor(centre - half)) << layer_file << ": " << key;
      EXPECT_EQ(wide_hi, std::ceil(centre + half)) << layer_file << ": " << key;
    } else {
      // the file's values carry 3-4 significant digits
      EXPECT_NEAR(wide_lo, centre - half, 0.002 * (hi - lo) + (log ? 1e-3 : 0.0))
          << layer_file << ": " << key;
      EXPECT_NEAR(wide_hi, centre + half, 0.002 * (hi - lo) + (log ? 1e-3 : 0.0))
          << layer_file << ": " << key;
    }
    ++ranges;
  }
  return ranges;
}

// configs/beyond.yaml (calibration structures beyond the pool) widens every range of the
// preset it names to 1.5x, and resolves over ts4 and the preset.
TEST(BeyondPresetTest, WidensEachPresetRangeOneAndAHalfTimes) {
  EXPECT_EQ(ExpectRangesWidenedOneAndAHalfTimes("randomized.yaml", "beyond.yaml"), 11);
  EXPECT_EQ(YAML::LoadFile(ConfigPath("beyond.yaml"))["randomize"]["structure_variants"].as<int>(),
            48);
  TempDir dir;
  const auto run = RunCli("--config '" + ConfigPath("ts4.yaml") + "' --config '" +
                              ConfigPath("randomized.yaml") + "' --config '" +
                              ConfigPath("beyond.yaml") + "' config",
                          dir.path().string());
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("0.0894"), std::string::npos) << run.out;
}

// configs/built_beyond.yaml (pretrain's calibration tubes) widens each structure and placement
// range of configs/built.yaml to 1.5x, every one of them, and sets no other key
TEST(BeyondPresetTest, BuiltBeyondWidensEachAsBuiltStructureRangeOneAndAHalfTimes) {
  const YAML::Node built = YAML::LoadFile(ConfigPath("built.yaml"))["randomize"];
  const std::set<std::string> structure = {"youngs_modulus_scale", "mic_z_offset_m",
                                           "mic_theta_offset_deg", "flange_mount_scale",
                                           "tool_mount_scale", "bolt_stiffness_scale"};
  for (const std::string& key : structure) EXPECT_TRUE(built[key]) << key;
  EXPECT_EQ(ExpectRangesWidenedOneAndAHalfTimes("built.yaml", "built_beyond.yaml"),
            static_cast<int>(structure.size()));
  EXPECT_EQ(YAML::LoadFile(ConfigPath("built_beyond.yaml"))["randomize"].size(), structure.size());
}

// configs/two_theories.yaml (the recommended pretraining set) resolves over ts4 and the preset,
// changes nothing of the preset but the share of strikes the reference solid renders
TEST(BeyondPresetTest, TwoTheoriesLayerSetsTheReferenceFractionAlone) {
  TempDir dir;
  const std::string base =
      "--config '" + ConfigPath("ts4.yaml") + "' --config '" + ConfigPath("randomized.yaml") + "' ";
  const auto plain = RunCli(base + "config", dir.path().string());
  const auto layered = RunCli(base + "--config '" + ConfigPath("two_theories.yaml") + "' config",
                              dir.path().string());
  ASSERT_EQ(layered.exit_code, 0) << layered.err;
  const YAML::Node a = YAML::Load(plain.out);
  YAML::Node b = YAML::Load(layered.out);
  EXPECT_EQ(a["randomize"]["reference_fraction"].as<double>(), 0.0);
  EXPECT_EQ(b["randomize"]["reference_fraction"].as<double>(), 0.3);
  b["randomize"]["reference_fraction"] = 0.0;
  EXPECT_EQ(YAML::Dump(a), YAML::Dump(b));
}

// configs/attached_masses.yaml resolves over ts4, the preset and the as-built layer, and sets
// the three attached-mass ranges and nothing else
TEST(BeyondPresetTest, AttachedMassesLayerSetsItsThreeRangesAlone) {
  TempDir dir;
  const std::string base = "--config '" + ConfigPath("ts4.yaml") + "' --config '" +
                           ConfigPath("randomized.yaml") + "' --config '" +
                           ConfigPath("built.yaml") + "' ";
  const auto plain = RunCli(base + "config", dir.path().string());
  const auto layered = RunCli(
      base + "--config '" + ConfigPath("attached_masses.yaml") + "' config", dir.path().string());
  ASSERT_EQ(layered.exit_code, 0) << layered.err;
  const YAML::Node a = YAML::Load(plain.out);
  YAML::Node b = YAML::Load(layered.out);
  EXPECT_EQ(a["randomize"]["attached_mass_count"].size(), 0u);
  EXPECT_EQ(b["randomize"]["attached_mass_count"][1].as<double>(), 3.0);
  EXPECT_EQ(b["randomize"]["attached_mass_kg"][1].as<double>(), 0.03);
  EXPECT_EQ(b["randomize"]["disc_mass_kg"][0].as<double>(), 0.0005);
  for (const char* key : {"attached_mass_count", "attached_mass_kg", "disc_mass_kg"})
    b["randomize"][key] = a["randomize"][key];
  EXPECT_EQ(YAML::Dump(a), YAML::Dump(b));
}

}  // namespace
}  // namespace sonicboom
