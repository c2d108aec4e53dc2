// Config layers: defaults, files merged in order, --set overrides, strict reading.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

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

// A list of nested structs, as scene objects use: each item has a nested group too.
struct Item {
  struct Pose {
    double z_m{0.0};
    void Serialize(Archive* a) { a->Visit("z_m", &z_m); }
    bool operator==(const Pose&) const = default;
  };
  std::string kind{"sphere"};
  double diameter_m{0.01};
  Pose pose;
  void Serialize(Archive* a) {
    a->Visit("kind", &kind);
    a->Visit("diameter_m", &diameter_m, Bounds::Positive());
    a->Visit("pose", &pose);
  }
  bool operator==(const Item&) const = default;
};

struct ListRoot {
  struct Scene {
    std::vector<Item> objects{{"cube", 0.05, {0.1}}, {"rod", 0.02, {-0.1}}};  // not Item{}
    void Serialize(Archive* a) { a->VisitList("objects", &objects); }
  } scene;
  void Serialize(Archive* a) { a->Visit("scene", &scene); }
};

const std::vector<Item> kDefaultItems = ListRoot().scene.objects;

ListRoot ReadList(const ConfigLayers& layers) {
  ListRoot root;
  layers.ReadInto(&root);
  return root;
}

ConfigLayers TextLayer(const std::string& yaml) {
  ConfigLayers layers;
  layers.AddText(yaml, "list.yaml");
  return layers;
}

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

template <typename T = Root>
std::string ErrorOf(const ConfigLayers& layers) {
  T root;
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

// What a YAML parser accepts but a config cannot mean is refused, naming the file and the key:
// a key twice, an alias that refers to its own ancestor (once a stack overflow), a directory.
TEST(ConfigTest, DuplicateKeysSelfAliasesAndDirectoriesAreRefused) {
  testing::TempDir dir;
  auto message = [&](const std::string& file) {
    try {
      ConfigLayers().AddFile(dir / file);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  WriteFile(dir / "twice.yaml", "tube:\n  length_m: 0.3\n  length_m: 0.4\n");
  EXPECT_NE(message("twice.yaml").find("twice.yaml: key 'tube.length_m' appears twice"),
            std::string::npos)
      << message("twice.yaml");
  WriteFile(dir / "self.yaml", "tube: &t\n  length_m: 0.3\n  self: *t\n");
  EXPECT_NE(message("self.yaml").find("self.yaml: key 'tube.self.self."), std::string::npos)
      << message("self.yaml");
  EXPECT_NE(message("self.yaml").find("(an alias that refers to itself?)"), std::string::npos);
  std::filesystem::create_directory(dir / "configs.yaml");
  EXPECT_NE(message("configs.yaml").find("configs.yaml: is a directory, not a config file"),
            std::string::npos)
      << message("configs.yaml");
  // an alias to a sibling is plain YAML and stays accepted
  WriteFile(dir / "alias.yaml", "tube: &t\n  length_m: 0.3\ncopy: *t\n");
  EXPECT_EQ(message("alias.yaml"), "(accepted)");
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

TEST(ConfigListTest, WrittenYamlReadsBackIdentically) {
  ListRoot root;
  root.scene.objects = {{"rod", 0.123456789012345, {0.25}}, {"sphere", 0.03, {}}, {"cube", 1, {}}};
  const std::string yaml = ToYaml(root);
  EXPECT_NE(yaml.find("objects:\n    - kind: rod\n"), std::string::npos) << yaml;  // block style
  ListRoot back = FromYaml<ListRoot>(yaml, "round trip");
  EXPECT_EQ(back.scene.objects, root.scene.objects);
  EXPECT_EQ(ToYaml(back), yaml);
  // an empty list reads back empty, not as the defaults
  root.scene.objects.clear();
  EXPECT_TRUE(FromYaml<ListRoot>(ToYaml(root), "round trip").scene.objects.empty());
}

TEST(ConfigListTest, AbsentListKeepsDefaultsAndAnEmptyOneIsRefused) {
  EXPECT_EQ(ReadList(ConfigLayers()).scene.objects, kDefaultItems);
  EXPECT_EQ(ReadList(TextLayer("scene: {}\n")).scene.objects, kDefaultItems);
  // an empty value is not read as "keep the defaults": it is refused, naming the key
  EXPECT_NE(ErrorOf<ListRoot>(TextLayer("scene:\n  objects:\n")).find("scene.objects"),
            std::string::npos);
}

TEST(ConfigListTest, PresentListReplacesDefaultsWithDefaultItems) {
  const auto objects =
      ReadList(TextLayer("scene:\n  objects:\n    - diameter_m: 0.03\n    - kind: rod\n"))
          .scene.objects;
  ASSERT_EQ(objects.size(), 2u);
  // unset fields come from Item{}, not from the default list's items
  EXPECT_EQ(objects[0], (Item{"sphere", 0.03, {}}));
  EXPECT_EQ(objects[1], (Item{"rod", 0.01, {}}));
  EXPECT_TRUE(ReadList(TextLayer("scene:\n  objects: []\n")).scene.objects.empty());
}

TEST(ConfigListTest, ErrorsInsideAnItemNameIndexAndFile) {
  testing::TempDir dir;
  WriteFile(dir / "x.yaml",
            "scene:\n  objects:\n    - kind: rod\n    - kind: cube\n      diamter_m: 0.5\n");
  ConfigLayers unknown;
  unknown.AddFile(dir / "x.yaml");
  std::string err = ErrorOf<ListRoot>(unknown);
  EXPECT_NE(err.find("unknown config key 'scene.objects.1.diamter_m'"), std::string::npos) << err;
  EXPECT_NE(err.find("x.yaml"), std::string::npos) << err;
  WriteFile(dir / "y.yaml", "scene:\n  objects:\n    - pose: {z_m: abc}\n");
  ConfigLayers wrong_type;
  wrong_type.AddFile(dir / "y.yaml");
  err = ErrorOf<ListRoot>(wrong_type);
  EXPECT_NE(err.find("'scene.objects.0.pose.z_m'"), std::string::npos) << err;
  EXPECT_NE(err.find("y.yaml"), std::string::npos) << err;
  EXPECT_NE(err.find("abc"), std::string::npos) << err;
  err = ErrorOf<ListRoot>(TextLayer("scene:\n  objects:\n    - {}\n    - diameter_m: -1\n"));
  EXPECT_NE(err.find("'scene.objects.1.diameter_m' = -1 (from list.yaml)"), std::string::npos)
      << err;
}

TEST(ConfigListTest, ListMustHoldMappings) {
  for (const char* value : {"3", "[1, 2]", "{kind: rod}", "[{kind: rod}, 2]", "[[]]"}) {
    const std::string err =
        ErrorOf<ListRoot>(TextLayer(std::string("scene:\n  objects: ") + value + "\n"));
    EXPECT_NE(err.find("config key 'scene.objects' (from list.yaml): expected a list of mappings"),
              std::string::npos)
        << value << ": " << err;
  }
}

TEST(ConfigListTest, LaterLayerReplacesTheList) {
  testing::TempDir dir;
  WriteFile(dir / "a.yaml",
            "scene:\n  objects:\n    - {kind: rod, diameter_m: 0.5}\n    - {kind: cube}\n");
  WriteFile(dir / "b.yaml", "scene:\n  objects:\n    - {pose: {z_m: 0.2}}\n");
  ConfigLayers layers;
  layers.AddFile(dir / "a.yaml");
  layers.AddFile(dir / "b.yaml");
  const auto objects = ReadList(layers).scene.objects;
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0], (Item{"sphere", 0.01, {0.2}}));  // nothing merged from a.yaml's item 0
  // the origin of an item's key is the layer that set the list
  WriteFile(dir / "c.yaml", "scene:\n  objects:\n    - {bogus: 1}\n");
  layers.AddFile(dir / "c.yaml");
  const std::string err = ErrorOf<ListRoot>(layers);
  EXPECT_NE(err.find("'scene.objects.0.bogus' (from " + (dir / "c.yaml") + ")"), std::string::npos)
      << err;
}

TEST(ConfigListTest, SetTakesAFlowList) {
  ConfigLayers layers;
  layers.AddText("scene:\n  objects:\n    - {kind: cube}\n    - {kind: cube}\n", "list.yaml");
  layers.AddOverride("scene.objects=[{kind: rod, diameter_m: 0.03}]");
  const auto objects = ReadList(layers).scene.objects;
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0], (Item{"rod", 0.03, {}}));
  layers.AddOverride("scene.objects=[{kind: rod, diameter: 0.03}]");
  const std::string err = ErrorOf<ListRoot>(layers);
  EXPECT_NE(err.find("'scene.objects.0.diameter' (from --set scene.objects=[{kind: rod"),
            std::string::npos)
      << err;
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

namespace sonicboom {
namespace {

// Numbers and layers read as the user wrote them, or refused naming what went wrong: YAML 1.1's
// octal and hexadecimal integers, empty values and bare sections, a second document, and a
// billion-laughs expansion of nested aliases (issue 33).
// a root with an integer key, as train.epochs
struct IntRoot {
  TubeConfig tube;
  MaterialConfig material;
  struct Train {
    int64_t epochs{10};
    void Serialize(Archive* a) { a->Visit("epochs", &epochs, Bounds::Closed(1, 1000)); }
  } train;
  void Serialize(Archive* a) {
    a->Visit("tube", &tube);
    a->Visit("material", &material);
    a->Visit("train", &train);
  }
};

TEST(ConfigStrictTest, OctalEmptyValuesSecondDocumentsAndAliasBombsAreRefused) {
  const auto read_error = [](const std::string& yaml) {
    ConfigLayers layers;
    try {
      layers.AddText(yaml, "strict.yaml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return ErrorOf<IntRoot>(layers);
  };
  // 010 would read as 8, 0x10 as 16
  std::string err = read_error("train:\n  epochs: 010\n");
  EXPECT_NE(err.find("train.epochs"), std::string::npos) << err;
  EXPECT_NE(err.find("leading zero"), std::string::npos) << err;
  EXPECT_NE(read_error("train:\n  epochs: 0x10\n").find("leading zero"), std::string::npos);
  EXPECT_NE(read_error("train:\n  epochs: -012\n").find("leading zero"), std::string::npos);
  EXPECT_EQ(read_error("train:\n  epochs: 10\n"), "");
  EXPECT_NE(read_error("tube:\n  length_m: 00.3\n").find("tube.length_m"), std::string::npos);
  EXPECT_NE(read_error("tube:\n  length_m: .inf\n").find("finite"), std::string::npos);
  // what stays plain: 0.3, 1400.0, 2.5e-2
  EXPECT_EQ(read_error("tube:\n  length_m: 0.3\n"), "");
  EXPECT_EQ(read_error("material:\n  density_kg_m3: 1400.0\n  loss_factor: 2.5e-2\n"), "");
  // an empty value and a bare section
  err = read_error("tube:\n  length_m:\n");
  EXPECT_NE(err.find("tube.length_m"), std::string::npos) << err;
  EXPECT_NE(err.find("has no value"), std::string::npos) << err;
  EXPECT_NE(read_error("tube:\n").find("'tube'"), std::string::npos) << read_error("tube:\n");
  ConfigLayers empty;
  try {
    empty.AddOverride("tube.length_m=");
    ADD_FAILURE() << "--set with an empty value accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("empty value"), std::string::npos) << e.what();
  }
  // a second document is not silently dropped
  err = read_error("tube:\n  length_m: 0.3\n---\ntube:\n  length_m: 0.4\n");
  EXPECT_NE(err.find("more than one YAML document"), std::string::npos) << err;
  // ten levels of ten aliases: refused at once, not expanded
  std::string bomb = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int level = 1; level < 10; ++level) {
    bomb += fmt::format("a{}: &a{} [", level, level);
    for (int k = 0; k < 10; ++k) bomb += fmt::format("{}*a{}", k ? ", " : "", level - 1);
    bomb += "]\n";
  }
  const auto start = std::chrono::steady_clock::now();
  err = read_error(bomb);
  EXPECT_NE(err.find("expands to more than"), std::string::npos) << err;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
}

}  // namespace
}  // namespace sonicboom
