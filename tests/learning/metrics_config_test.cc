// ComputeMetrics on hand-computed cases; config serialization keys and validation errors;
// lists of structs in the JSON archive; parameter counts of the audio encoders.

#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "internal/json_archive.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

using ::testing::HasSubstr;

using sonicboom::kPi;

// Truth labels only.
FeatureSet Truth(const std::vector<double>& z_m, const std::vector<double>& theta_rad) {
  FeatureSet f;
  f.z_m = z_m;
  f.theta_rad = theta_rad;
  return f;
}

TEST(ComputeMetricsTest, OppositeSidesOfTheTubeAreOneDiameterApart) {
  // Same height, angles differ by pi on r = 5 cm: chord = 10 cm.
  const Metrics m = ComputeMetrics({{0.02, kPi}}, Truth({0.02}, {0.0}), 0.05);
  EXPECT_EQ(m.n, 1);
  EXPECT_NEAR(m.med_cm, 10.0, 1e-12);
  EXPECT_NEAR(m.height_err_cm, 0.0, 1e-12);
  EXPECT_NEAR(m.angle_err_deg, 180.0, 1e-9);
  // Reference variant: radius 0.06 "cm" => 2 * 0.06.
  EXPECT_NEAR(m.reference_med_cm, 0.12, 1e-12);
}

TEST(ComputeMetricsTest, AngleErrorWrapsAcrossPi) {
  // 3.1 and -3.1 rad are 2 pi - 6.2 rad apart the short way.
  const Metrics m = ComputeMetrics({{0.0, -3.1}}, Truth({0.0}, {3.1}), 0.05);
  EXPECT_NEAR(m.angle_err_deg, (2.0 * kPi - 6.2) * 180.0 / kPi, 1e-9);
  const double chord_cm = 100.0 * 2.0 * 0.05 * std::sin((2.0 * kPi - 6.2) / 2.0);
  EXPECT_NEAR(m.med_cm, chord_cm, 1e-9);
}

TEST(ComputeMetricsTest, HeightAndAngleCombine) {
  // dz = 3 cm, dtheta = pi/2 on r = 4 cm: chord = 4 sqrt(2) cm.
  const Metrics m = ComputeMetrics({{0.03, kPi / 2.0}}, Truth({0.0}, {0.0}), 0.04);
  EXPECT_NEAR(m.med_cm, std::sqrt(9.0 + 32.0), 1e-9);
  EXPECT_NEAR(m.height_err_cm, 3.0, 1e-12);
  EXPECT_NEAR(m.angle_err_deg, 90.0, 1e-9);
  // Reference: sqrt(3^2 + (0.06 sqrt(2))^2) with the height in cm and the radius in m.
  EXPECT_NEAR(m.reference_med_cm, std::sqrt(9.0 + 2.0 * 0.06 * 0.06), 1e-12);
}

TEST(ComputeMetricsTest, AveragesAndSkipsUnlabelledRecords) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Metrics m = ComputeMetrics({{0.01, 0.0}, {0.5, 1.0}, {-0.02, 0.0}},
                                   Truth({0.0, nan, 0.0}, {0.0, 0.0, 0.0}), 0.05);
  EXPECT_EQ(m.n, 2);
  EXPECT_NEAR(m.height_err_cm, 1.5, 1e-12);
  EXPECT_NEAR(m.med_cm, 1.5, 1e-12);
  EXPECT_NEAR(m.angle_err_deg, 0.0, 1e-12);
}

TEST(ComputeMetricsTest, NoLabelledRecordsGiveNaN) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Metrics m = ComputeMetrics({{0.0, 0.0}}, Truth({nan}, {0.0}), 0.05);
  EXPECT_EQ(m.n, 0);
  EXPECT_TRUE(std::isnan(m.med_cm));
}

TEST(ComputeMetricsTest, CountMismatchThrows) {
  EXPECT_THROW(ComputeMetrics({{0.0, 0.0}}, Truth({0.0, 0.1}, {0.0, 0.0}), 0.05), SchemaError);
}

TEST(FeatureSetTest, SelectRowsKeepsUnusedArraysEmpty) {
  FeatureSet f;
  f.channels = 1;
  f.mels = 1;
  f.frames = 2;
  f.z_m = {0.0, 0.1, 0.2};
  f.theta_rad = {0.0, 1.0, 2.0};
  f.mel = {0, 1, 10, 11, 20, 21};  // gcc and proprio left empty
  const FeatureSet picked = f.SelectRows({2, 0});
  EXPECT_EQ(picked.mel, (std::vector<float>{20, 21, 0, 1}));
  EXPECT_TRUE(picked.gcc.empty());
  EXPECT_TRUE(picked.proprio.empty());
  EXPECT_EQ(picked.z_m, (std::vector<double>{0.2, 0.0}));
  EXPECT_EQ(picked.theta_rad, (std::vector<double>{2.0, 0.0}));
  // an array of the wrong size is an error, not a read past its end
  f.mel.pop_back();
  EXPECT_THROW(f.SelectRows({0}), SchemaError);
}

// KeepRows packs the chosen rows in place: the same rows SelectRows copies, in the same arrays
// (no reallocation), unused arrays left empty, a wrong-sized array refused
TEST(FeatureSetTest, KeepRowsPacksTheChosenRowsInPlace) {
  FeatureSet f;
  f.channels = 1;
  f.mels = 1;
  f.frames = 2;
  f.proprio_rows = 1;
  f.proprio_features = 1;
  f.z_m = {0.0, 0.1, 0.2, 0.3};
  f.theta_rad = {0.0, 1.0, 2.0, 3.0};
  f.mel = {0, 1, 10, 11, 20, 21, 30, 31};
  f.proprio = {5, 6, 7, 8};  // gcc left empty
  const FeatureSet copied = f.SelectRows({1, 3});
  const float* mel_data = f.mel.data();
  f.KeepRows({1, 3});
  EXPECT_EQ(f.mel, copied.mel);
  EXPECT_EQ(f.mel, (std::vector<float>{10, 11, 30, 31}));
  EXPECT_EQ(f.proprio, (std::vector<float>{6, 8}));
  EXPECT_TRUE(f.gcc.empty());
  EXPECT_EQ(f.z_m, copied.z_m);
  EXPECT_EQ(f.theta_rad, (std::vector<double>{1.0, 3.0}));
  EXPECT_EQ(f.size(), 2);
  EXPECT_EQ(f.mel.data(), mel_data);
  f.proprio.pop_back();
  EXPECT_THROW(f.KeepRows({0}), SchemaError);
}

// Records the names and kinds an Archive is asked to visit.
class RecordingArchive : public Archive {
 public:
  void Visit(std::string_view name, double*, Bounds b) override { Add(name, "double", b); }
  void Visit(std::string_view name, int64_t*, Bounds b) override { Add(name, "int", b); }
  void Visit(std::string_view name, bool*) override { Add(name, "bool", {}); }
  void Visit(std::string_view name, std::string*) override { Add(name, "string", {}); }
  void Visit(std::string_view name, std::vector<double>*, Bounds b) override {
    Add(name, "doubles", b);
  }
  void Visit(std::string_view name, std::vector<std::string>*) override {
    Add(name, "strings", {});
  }
  void VisitChoice(std::string_view name, std::string*,
                   const std::vector<std::string>& allowed) override {
    Add(name, "choice", {});
    choices = allowed;
  }
  using Archive::Visit;

  std::vector<std::string> names, kinds;
  std::vector<Bounds> bounds;
  std::vector<std::string> choices;

 protected:
  void BeginGroup(std::string_view) override {}
  void EndGroup() override {}
  // lists: record the fields of the existing items
  std::optional<size_t> BeginList(std::string_view) override { return std::nullopt; }
  void BeginItem(size_t) override {}
  void EndItem() override {}
  void EndList() override {}

 private:
  void Add(std::string_view name, const char* kind, Bounds b) {
    names.emplace_back(name);
    kinds.emplace_back(kind);
    bounds.push_back(b);
  }
};

TEST(ConfigTest, ModelConfigKeysAreMemberNames) {
  ModelConfig config;
  RecordingArchive archive;
  config.Serialize(&archive);
  EXPECT_THAT(archive.names,
              ::testing::ElementsAre("audio_encoder", "width", "blocks", "heads", "dropout",
                                     "modalities", "crop_frames", "gcc_encoder", "arrival_picks",
                                     "turn_average", "mirror_average"));
  EXPECT_EQ(archive.kinds[0], "choice");
  EXPECT_EQ(archive.kinds[7], "choice");
  EXPECT_EQ(archive.kinds[8], "choice");
  // the last choice visited
  EXPECT_THAT(archive.choices, ::testing::ElementsAre("none", "token", "only"));
  EXPECT_EQ(archive.kinds[5], "strings");
  // width must be positive
  EXPECT_FALSE(archive.bounds[1].Contains(0.0));
  EXPECT_TRUE(archive.bounds[1].Contains(1.0));
  // dropout in [0, 1)
  EXPECT_FALSE(archive.bounds[4].Contains(1.0));
  EXPECT_TRUE(archive.bounds[4].Contains(0.0));
}

TEST(ConfigTest, TrainConfigKeysAreMemberNames) {
  TrainConfig config;
  RecordingArchive archive;
  config.Serialize(&archive);
  EXPECT_THAT(archive.names,
              ::testing::ElementsAre(
                  "epochs", "batch_size", "learning_rate", "lr_step_epochs", "lr_gamma",
                  "val_fraction", "loss_weight_z", "loss_weight_cos", "loss_weight_sin",
                  "uncertainty_weight", "augment", "time_shift_frames", "time_mask_frames",
                  "freq_mask_bands", "polarity_flip", "time_stretch", "rotate_rings",
                  "mirror_rings", "normalize", "keep_best", "ensemble_members", "threads"));
  EXPECT_FALSE(archive.bounds[1].Contains(0.0));  // batch_size
  EXPECT_FALSE(archive.bounds[2].Contains(0.0));  // learning_rate
  EXPECT_TRUE(archive.bounds[9].Contains(0.0));   // uncertainty_weight: 0 disables
  EXPECT_FALSE(archive.bounds[9].Contains(-0.1));
  EXPECT_TRUE(archive.bounds[15].Contains(0.0));   // time_stretch: 0 is off
  EXPECT_TRUE(archive.bounds[15].Contains(0.5));
  EXPECT_FALSE(archive.bounds[15].Contains(0.51));
  EXPECT_FALSE(archive.bounds[20].Contains(0.0));  // ensemble_members: at least one
  EXPECT_TRUE(archive.bounds[21].Contains(0.0));   // threads
}

// Runs `f` and returns the ConfigError message ("" when nothing was thrown).
template <typename F>
std::string ConfigErrorOf(F f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ConfigTest, DefaultsAreValid) {
  EXPECT_NO_THROW(ModelConfig().Validate());
  EXPECT_NO_THROW(TrainConfig().Validate());
}

TEST(ConfigTest, ModalitiesMustBeAKnownNonEmptySet) {
  ModelConfig config;
  config.modalities = {};
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.modalities"));
  config.modalities = {"audio", "video"};
  const std::string message = ConfigErrorOf([&] { config.Validate(); });
  EXPECT_THAT(message, HasSubstr("model.modalities"));
  EXPECT_THAT(message, HasSubstr("video"));
  config.modalities = {"gcc", "gcc"};
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.modalities"));
  config.modalities = {"proprio"};
  EXPECT_NO_THROW(config.Validate());
  // arrival picks are read off the audio features
  config.arrival_picks = ArrivalPicks::kToken;
  const std::string no_audio = ConfigErrorOf([&] { config.Validate(); });
  EXPECT_THAT(no_audio, HasSubstr("model.arrival_picks"));
  EXPECT_THAT(no_audio, HasSubstr("[proprio]"));
  config.modalities = {"audio", "proprio"};
  EXPECT_NO_THROW(config.Validate());
  // turning a strike moves its audio alone
  config.turn_average = true;
  const std::string turned = ConfigErrorOf([&] { config.Validate(); });
  EXPECT_THAT(turned, HasSubstr("model.turn_average"));
  EXPECT_THAT(turned, HasSubstr("[audio, proprio]"));
  config.modalities = {"audio"};
  EXPECT_NO_THROW(config.Validate());
  // the mirror images are taken of each turn
  config.turn_average = false;
  config.mirror_average = true;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.turn_average = true"));
}

TEST(ConfigTest, HeadsMustDivideWidth) {
  ModelConfig config;
  config.width = 32;
  config.heads = 3;
  const std::string message = ConfigErrorOf([&] { config.Validate(); });
  EXPECT_THAT(message, HasSubstr("model.heads"));
  EXPECT_THAT(message, HasSubstr("32"));
  config.heads = 4;
  EXPECT_NO_THROW(config.Validate());
}

TEST(ConfigTest, OtherModelFieldsAreChecked) {
  ModelConfig config;
  // an encoder outside the enum is refused where the config is read, naming the key and the names
  const std::string unknown =
      ConfigErrorOf([] { FromYaml<ModelConfig>("audio_encoder: vgg\n", "test.yaml"); });
  EXPECT_THAT(unknown, HasSubstr("audio_encoder"));
  EXPECT_THAT(unknown, HasSubstr("compact, resnet18, resnet50"));
  EXPECT_EQ(FromYaml<ModelConfig>("audio_encoder: resnet18\n", "test.yaml").audio_encoder,
            AudioEncoderKind::kResnet18);
  config.dropout = 1.0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.dropout"));
  config = ModelConfig();
  config.blocks = 0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.blocks"));
  config = ModelConfig();
  config.crop_frames = 0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("model.crop_frames"));
}

TEST(ConfigTest, TrainFieldsAreChecked) {
  TrainConfig config;
  config.batch_size = 0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.batch_size"));
  config = TrainConfig();
  config.learning_rate = -1.0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.learning_rate"));
  config = TrainConfig();
  config.val_fraction = 1.0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.val_fraction"));
  config = TrainConfig();
  config.loss_weight_z = config.loss_weight_cos = config.loss_weight_sin = 0.0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.loss_weight"));
  config = TrainConfig();
  config.time_shift_frames = -1;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.time_shift_frames"));
  config = TrainConfig();
  EXPECT_EQ(config.uncertainty_weight, 1.0);
  config.uncertainty_weight = -1.0;
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.uncertainty_weight"));
  config.uncertainty_weight = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ConfigErrorOf([&] { config.Validate(); }), HasSubstr("train.uncertainty_weight"));
  config.uncertainty_weight = 0.0;
  EXPECT_NO_THROW(config.Validate());
}

// A config with a list of nested structs, each with a nested group.
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

struct ListConfig {
  int64_t count{1};
  std::vector<Item> objects{{"cube", 0.05, {0.1}}};  // not Item{}
  void Serialize(Archive* a) {
    a->Visit("count", &count);
    a->VisitList("objects", &objects);
  }
};

// Runs `f` and returns the SchemaError message ("" when nothing was thrown).
template <typename F>
std::string SchemaErrorOf(F f) {
  try {
    f();
  } catch (const SchemaError& e) {
    return e.what();
  }
  return "";
}

TEST(JsonArchiveTest, ListsRoundTripAsArraysOfObjects) {
  ListConfig config;
  config.objects = {{"rod", 0.123456789012345, {0.25}}, {"sphere", 0.03, {}}};
  const nlohmann::json j = internal::ConfigToJson(config);
  ASSERT_TRUE(j["objects"].is_array());
  ASSERT_EQ(j["objects"].size(), 2u);
  EXPECT_EQ(j["objects"][0]["kind"], "rod");
  EXPECT_EQ(j["objects"][0]["pose"]["z_m"], 0.25);
  EXPECT_EQ(internal::ConfigFromJson<ListConfig>(j, "model.json").objects, config.objects);
  EXPECT_EQ(internal::ConfigToJson(internal::ConfigFromJson<ListConfig>(j, "model.json")), j);
  // the read list replaces the defaults, also when empty
  config.objects.clear();
  EXPECT_TRUE(internal::ConfigFromJson<ListConfig>(internal::ConfigToJson(config), "model.json")
                  .objects.empty());
}

TEST(JsonArchiveTest, ListErrorsNameFileAndIndexedKey) {
  const nlohmann::json good = internal::ConfigToJson(ListConfig());
  const auto error_of = [](const nlohmann::json& j) {
    return SchemaErrorOf([&] { internal::ConfigFromJson<ListConfig>(j, "model.json"); });
  };
  nlohmann::json j = good;
  j["objects"][0]["extra"] = 1;
  EXPECT_THAT(error_of(j), HasSubstr("model.json: unknown key 'objects.0.extra'"));
  j = good;
  j["objects"][0]["pose"]["extra"] = 1;
  EXPECT_THAT(error_of(j), HasSubstr("unknown key 'objects.0.pose.extra'"));
  j = good;
  j["objects"][0].erase("diameter_m");
  EXPECT_THAT(error_of(j), HasSubstr("key 'objects.0.diameter_m' is missing"));
  j = good;
  j["objects"][0]["diameter_m"] = -1.0;
  EXPECT_THAT(error_of(j), HasSubstr("key 'objects.0.diameter_m' = -1"));
  for (const nlohmann::json& bad :
       {nlohmann::json(3), nlohmann::json::object(), nlohmann::json::array({1, 2})}) {
    j = good;
    j["objects"] = bad;
    EXPECT_THAT(error_of(j), HasSubstr("model.json: key 'objects' must be a list of objects"))
        << bad;
  }
  j = good;
  j.erase("objects");
  EXPECT_THAT(error_of(j), HasSubstr("key 'objects' is missing"));
}

TEST(CountParametersTest, EncodersHaveTheirTextbookSizes) {
  FeatureSet shapes;  // default shapes: 6 x 50 x 517 mel, 15 x 883 GCC, 50 x 10 proprio
  ModelConfig config;
  config.width = 32;
  config.heads = 2;
  config.blocks = 1;
  // Compact CNN: convs 6-16-32-64-128 (3x3, no bias) + BN, then Linear(128, 32).
  const int64_t compact =
      9 * (6 * 16 + 16 * 32 + 32 * 64 + 64 * 128) + 2 * (16 + 32 + 64 + 128) + 128 * 32 + 32;
  EXPECT_EQ(CountParameters(config, shapes).at("audio_encoder"), compact);
  // ResNet-18 trunk with a 6-channel stem: 11 176 512 (3-channel, no fc) + 3 * 64 * 49.
  const int64_t projection18 = 512 * 128 + 128 + 2 * 128 + 128 * 32 + 32;
  config.audio_encoder = AudioEncoderKind::kResnet18;
  EXPECT_EQ(CountParameters(config, shapes).at("audio_encoder"),
            11176512 + 3 * 64 * 49 + projection18);
  // ResNet-50 trunk: 23 508 032 (3-channel, no fc) + 3 * 64 * 49.
  const int64_t projection50 = 2048 * 128 + 128 + 2 * 128 + 128 * 32 + 32;
  config.audio_encoder = AudioEncoderKind::kResnet50;
  EXPECT_EQ(CountParameters(config, shapes).at("audio_encoder"),
            23508032 + 3 * 64 * 49 + projection50);
}

TEST(CountParametersTest, OnlySelectedEncodersAreBuilt) {
  FeatureSet shapes;
  ModelConfig config;
  config.width = 32;
  config.heads = 2;
  config.blocks = 1;
  const auto all = CountParameters(config, shapes);
  EXPECT_EQ(all.size(), 4u);
  // GCC MLP: LN(13245), 13245 -> 128 -> LN -> 64 -> LN -> 32.
  const int64_t in = 15 * 883;
  EXPECT_EQ(all.at("gcc_encoder"),
            2 * in + in * 128 + 128 + 2 * 128 + 128 * 64 + 64 + 2 * 64 + 64 * 32 + 32);
  config.modalities = {"proprio"};
  const auto proprio = CountParameters(config, shapes);
  EXPECT_EQ(proprio.size(), 2u);
  EXPECT_TRUE(proprio.count("proprio_encoder"));
  EXPECT_EQ(proprio.at("proprio_encoder"), all.at("proprio_encoder"));
  // Fusion differs only by the two missing modality-embedding rows of width 32.
  EXPECT_EQ(proprio.at("fusion"), all.at("fusion") - 2 * 32);
  // The uncertainty head (LayerNorm, 32 -> 32 -> 2) is part of the fusion count.
  const auto point_only = CountParameters(config, shapes, /*uncertainty_head=*/false);
  EXPECT_EQ(proprio.at("fusion") - point_only.at("fusion"), 2 * 32 + 32 * 32 + 32 + 32 * 2 + 2);
  EXPECT_EQ(point_only.at("proprio_encoder"), proprio.at("proprio_encoder"));
  // Arrival picks only: no audio encoder; the picks' MLP reads 2 x 6 x 4 + 4 = 52 values:
  // Linear(52, 128), LayerNorm(128), Linear(128, 32).
  config.modalities = {"audio"};
  config.arrival_picks = ArrivalPicks::kOnly;
  const auto picks = CountParameters(config, shapes);
  EXPECT_EQ(picks.size(), 2u);
  EXPECT_EQ(picks.at("arrival_encoder"), 52 * 128 + 128 + 2 * 128 + 128 * 32 + 32);
  // beside the waveform's token: both encoders and one more modality embedding than audio alone
  config.arrival_picks = ArrivalPicks::kToken;
  const auto both = CountParameters(config, shapes);
  config.arrival_picks = ArrivalPicks::kNone;
  const auto audio = CountParameters(config, shapes);
  EXPECT_EQ(both.at("audio_encoder"), audio.at("audio_encoder"));
  EXPECT_EQ(both.at("arrival_encoder"), picks.at("arrival_encoder"));
  EXPECT_EQ(both.at("fusion"), audio.at("fusion") + 32);
}

}  // namespace
}  // namespace sonicboom::learning
