#pragma once
/// Config structs <-> JSON objects through their Serialize visitor, for the run-directory
/// files (model.json, checkpoint.json). Reading is strict: a missing, mistyped, out-of-range
/// or unknown key throws SchemaError naming the file and the dotted key.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "sonicboom/core/archive.h"

namespace sonicboom::learning::internal {

/// Writes every visited field into a JSON object (nested groups become nested objects).
class JsonWriteArchive final : public Archive {
 public:
  JsonWriteArchive();

  void Visit(std::string_view name, double* value, Bounds bounds) override;
  void Visit(std::string_view name, int64_t* value, Bounds bounds) override;
  void Visit(std::string_view name, bool* value) override;
  void Visit(std::string_view name, std::string* value) override;
  void Visit(std::string_view name, std::vector<double>* value, Bounds bounds) override;
  void Visit(std::string_view name, std::vector<std::string>* value) override;
  void VisitChoice(std::string_view name, std::string* value,
                   const std::vector<std::string>& choices) override;
  using Archive::Visit;

  const nlohmann::json& result() const { return root_; }

 protected:
  void BeginGroup(std::string_view name) override;
  void EndGroup() override;
  std::optional<size_t> BeginList(std::string_view name) override;
  void BeginItem(size_t index) override;
  void EndItem() override;
  void EndList() override;

 private:
  nlohmann::json root_;
  // open groups, lists and items, innermost last; object members and the open (last) array
  // item keep their addresses while open
  std::vector<nlohmann::json*> stack_;
};

/// Reads every visited field from a JSON object; `origin` (a file name) prefixes errors.
class JsonReadArchive final : public Archive {
 public:
  JsonReadArchive(const nlohmann::json& object, std::string origin);

  void Visit(std::string_view name, double* value, Bounds bounds) override;
  void Visit(std::string_view name, int64_t* value, Bounds bounds) override;
  void Visit(std::string_view name, bool* value) override;
  void Visit(std::string_view name, std::string* value) override;
  void Visit(std::string_view name, std::vector<double>* value, Bounds bounds) override;
  void Visit(std::string_view name, std::vector<std::string>* value) override;
  void VisitChoice(std::string_view name, std::string* value,
                   const std::vector<std::string>& choices) override;
  using Archive::Visit;

  /// Throws SchemaError when the object holds keys that no Visit asked for.
  void CheckNoUnknownKeys() const;

 protected:
  void BeginGroup(std::string_view name) override;
  void EndGroup() override;
  std::optional<size_t> BeginList(std::string_view name) override;
  void BeginItem(size_t index) override;
  void EndItem() override;
  void EndList() override;

 private:
  // The JSON value of `name` in the current group; throws when absent.
  const nlohmann::json& Get(std::string_view name);
  std::string Key(std::string_view name) const;
  [[noreturn]] void Fail(std::string_view name, const std::string& why) const;
  void CheckBounds(std::string_view name, double value, const Bounds& bounds) const;

  std::vector<const nlohmann::json*> stack_;
  std::vector<std::string> path_;     // keys of the open groups and lists, indices of open items
  std::vector<std::string> visited_;  // dotted keys read so far
  std::string origin_;
};

/// JSON object of a config struct.
template <typename T>
nlohmann::json ConfigToJson(const T& config) {
  JsonWriteArchive archive;
  T copy = config;
  copy.Serialize(&archive);
  return archive.result();
}

/// Config struct from a JSON object written by ConfigToJson; `origin` names the file.
template <typename T>
T ConfigFromJson(const nlohmann::json& object, const std::string& origin) {
  T config;
  JsonReadArchive archive(object, origin);
  config.Serialize(&archive);
  archive.CheckNoUnknownKeys();
  return config;
}

}  // namespace sonicboom::learning::internal
