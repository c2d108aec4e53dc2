// YAML config reader (core ConfigLayers and the Serialize visitor) on arbitrary text: a config
// of core sections (numbers with bounds, lists, nested groups, an enum) read strictly.
#include <cstdint>
#include <string>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"

namespace {

struct FuzzRoot {
  sonicboom::TubeConfig tube;
  sonicboom::MaterialConfig material;
  sonicboom::MicArrayConfig mics;
  sonicboom::AudioConfig audio;
  sonicboom::TubeEnds ends{sonicboom::TubeEnds::kFree};
  std::vector<std::string> names;
  void Serialize(sonicboom::Archive* a) {
    a->Visit("tube", &tube);
    a->Visit("material", &material);
    a->Visit("mics", &mics);
    a->Visit("audio", &audio);
    a->Visit("ends", &ends);
    a->Visit("names", &names);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    sonicboom::ConfigLayers layers;
    layers.AddText(text, "fuzz.yaml");
    FuzzRoot root;
    layers.ReadInto(&root);
    root.tube.Validate();
    sonicboom::ToYaml(root);
  } catch (const sonicboom::Error&) {
  }
  return 0;
}
