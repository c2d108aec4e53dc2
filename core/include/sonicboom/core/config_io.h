#pragma once
/// Resolving a config from defaults, YAML files (merged in order) and --set key=value overrides,
/// and writing it back. YAML details stay in config_io.cc.

#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"

namespace sonicboom {

/// An ordered stack of config layers: embedded defaults, then files, then --set overrides.
/// Each leaf remembers which layer set it, so errors can name the file or the override.
class ConfigLayers {
 public:
  ConfigLayers();
  ~ConfigLayers();
  ConfigLayers(ConfigLayers&&) noexcept;
  ConfigLayers& operator=(ConfigLayers&&) noexcept;

  /// Merges a YAML file; throws IoError (missing/unreadable) or ConfigError (bad YAML).
  void AddFile(const std::string& path);
  /// Merges YAML text; `origin` names it in error messages.
  void AddText(const std::string& yaml_text, const std::string& origin);
  /// Applies "a.b.c=value"; the value is parsed as a YAML scalar or flow sequence.
  void AddOverride(const std::string& assignment);

  /// Reads the merged layers into `root` (whose fields hold the defaults). Unknown keys,
  /// wrong types and out-of-range values throw ConfigError naming the dotted key and its origin.
  template <typename T>
  void ReadInto(T* root) const {
    auto archive = MakeReadArchive();
    root->Serialize(archive.get());
    FinishRead(archive.get());
  }

 private:
  std::unique_ptr<Archive> MakeReadArchive() const;
  void FinishRead(Archive* archive) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Writes a config as YAML text (block style, stable key order = Serialize order).
template <typename T>
std::string ToYaml(T& config);

namespace internal {
std::unique_ptr<Archive> MakeYamlWriteArchive();
std::string FinishYamlWrite(Archive* archive);
}  // namespace internal

template <typename T>
std::string ToYaml(T& config) {
  auto archive = internal::MakeYamlWriteArchive();
  config.Serialize(archive.get());
  return internal::FinishYamlWrite(archive.get());
}

/// Reads a config from YAML text alone (no defaults layer): used for configs stored in files.
template <typename T>
T FromYaml(const std::string& yaml_text, const std::string& origin) {
  T config;
  ConfigLayers layers;
  layers.AddText(yaml_text, origin);
  layers.ReadInto(&config);
  return config;
}

}  // namespace sonicboom
