// Config layers: defaults, files merged in order, --set overrides, strict reading.
#include <gtest/gtest.h>

#include <fstream>

#include "common/test_util.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"

namespace sonicboom {
namespace {

struct Root {
  TubeConfig tube;
  MaterialConfig material;
  AudioConfig audio;
  void Serialize(Archive* a) {
    a->Visit("tube", &tube);
    a->Visit("material", &material);
    a->Visit("audio", &audio);
  }
};

void WriteFile(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::string ErrorOf(const ConfigLayers& layers) {
  Root root;
  try {
    layers.ReadInto(&root);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ConfigTest, DefaultsAreTheConventions) {
  Root root;
  ConfigLayers().ReadInto(&root);
  EXPECT_DOUBLE_EQ(root.tube.outer_radius_m, 0.05355);
  EXPECT_DOUBLE_EQ(root.tube.wall_thickness_m, 0.00305);
  EXPECT_DOUBLE_EQ(root.tube.length_m, 0.3048);
  EXPECT_DOUBLE_EQ(root.material.youngs_modulus_pa, 3.0e9);
  EXPECT_DOUBLE_EQ(root.material.poisson_ratio, 0.38);
  EXPECT_DOUBLE_EQ(root.material.density_kg_m3, 1400.0);
  EXPECT_DOUBLE_EQ(root.audio.sample_rate_hz, 44100.0);
}

TEST(ConfigTest, FilesMergeInOrderAndSetWins) {
  testing::TempDir dir;
  WriteFile(dir / "a.yaml", "tube:\n  length_m: 0.5\n  wall_thickness_m: 0.004\n");
  WriteFile(dir / "b.yaml", "tube:\n  length_m: 0.4\n");
  ConfigLayers layers;
  layers.AddFile(dir / "a.yaml");
  layers.AddFile(dir / "b.yaml");
  layers.AddOverride("audio.sample_rate_hz=48000");
  Root root;
  layers.ReadInto(&root);
  EXPECT_DOUBLE_EQ(root.tube.length_m, 0.4);
  EXPECT_DOUBLE_EQ(root.tube.wall_thickness_m, 0.004);
  EXPECT_DOUBLE_EQ(root.audio.sample_rate_hz, 48000.0);
  EXPECT_DOUBLE_EQ(root.tube.outer_radius_m, 0.05355);  // untouched default
}

TEST(ConfigTest, UnknownKeyNamesKeyAndFile) {
  testing::TempDir dir;
  WriteFile(dir / "bad.yaml", "tube:\n  lenght_m: 0.5\n");
  ConfigLayers layers;
  layers.AddFile(dir / "bad.yaml");
  const std::string err = ErrorOf(layers);
  EXPECT_NE(err.find("tube.lenght_m"), std::string::npos) << err;
  EXPECT_NE(err.find("bad.yaml"), std::string::npos) << err;
}

TEST(ConfigTest, UnknownTopLevelKeyFromSet) {
  ConfigLayers layers;
  layers.AddOverride("nonsense.key=3");
  const std::string err = ErrorOf(layers);
  EXPECT_NE(err.find("nonsense"), std::string::npos) << err;
  EXPECT_NE(err.find("--set nonsense.key=3"), std::string::npos) << err;
}

TEST(ConfigTest, OutOfRangeAndWrongTypeNameKeyAndValue) {
  ConfigLayers negative;
  negative.AddOverride("tube.wall_thickness_m=-1");
  std::string err = ErrorOf(negative);
  EXPECT_NE(err.find("tube.wall_thickness_m"), std::string::npos) << err;
  EXPECT_NE(err.find("-1"), std::string::npos) << err;
  ConfigLayers text;
  text.AddOverride("material.poisson_ratio=abc");
  err = ErrorOf(text);
  EXPECT_NE(err.find("material.poisson_ratio"), std::string::npos) << err;
  EXPECT_NE(err.find("abc"), std::string::npos) << err;
  ConfigLayers poisson;
  poisson.AddOverride("material.poisson_ratio=0.5");  // incompressible limit excluded
  EXPECT_NE(ErrorOf(poisson).find("material.poisson_ratio"), std::string::npos);
}

TEST(ConfigTest, BadYamlAndMissingFile) {
  testing::TempDir dir;
  WriteFile(dir / "broken.yaml", "tube: [1, 2\n");
  ConfigLayers layers;
  try {
    layers.AddFile(dir / "broken.yaml");
    FAIL() << "broken YAML accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.yaml"), std::string::npos);
  }
  EXPECT_THROW(layers.AddFile(dir / "missing.yaml"), IoError);
  EXPECT_THROW(layers.AddOverride("=3"), ConfigError);
  EXPECT_THROW(layers.AddOverride("tube..length_m=3"), ConfigError);
}

TEST(ConfigTest, WrittenYamlReadsBackIdentically) {
  Root root;
  root.tube.length_m = 0.123456789012345;
  root.material.loss_factor = 1e-4;
  const std::string yaml = ToYaml(root);
  const Root back = FromYaml<Root>(yaml, "round trip");
  EXPECT_EQ(back.tube.length_m, root.tube.length_m);
  EXPECT_EQ(back.material.loss_factor, root.material.loss_factor);
  EXPECT_EQ(ToYaml(const_cast<Root&>(back)), yaml);
}

TEST(ConfigTest, CrossFieldChecks) {
  TubeConfig tube;
  tube.wall_thickness_m = 0.06;
  EXPECT_THROW(tube.Validate(), ConfigError);
  tube = TubeConfig{};
  tube.contact_z_max_m = 0.2;  // beyond the tube end at 0.1524
  try {
    tube.Validate();
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("contact_z"), std::string::npos);
  }
  MicArrayConfig mics;
  mics.z_m.pop_back();
  EXPECT_THROW(mics.Validate(TubeConfig{}), ConfigError);
}

}  // namespace
}  // namespace sonicboom
