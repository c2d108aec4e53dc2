#include "internal/json_archive.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::learning::internal {

using nlohmann::json;

JsonWriteArchive::JsonWriteArchive() : root_(json::object()) {}

json& JsonWriteArchive::Current() {
  json* node = &root_;
  for (const std::string& key : path_) node = &(*node)[key];
  return *node;
}

void JsonWriteArchive::Visit(std::string_view name, double* value, Bounds) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, int64_t* value, Bounds) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, bool* value) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::string* value) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::vector<double>* value, Bounds) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::vector<std::string>* value) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::VisitChoice(std::string_view name, std::string* value,
                                   const std::vector<std::string>&) {
  Current()[std::string(name)] = *value;
}
void JsonWriteArchive::BeginGroup(std::string_view name) {
  Current()[std::string(name)] = json::object();
  path_.emplace_back(name);
}
void JsonWriteArchive::EndGroup() { path_.pop_back(); }

JsonReadArchive::JsonReadArchive(const json& object, std::string origin)
    : origin_(std::move(origin)) {
  if (!object.is_object()) {
    throw SchemaError(fmt::format("{}: expected a JSON object", origin_));
  }
  stack_.push_back(&object);
}

std::string JsonReadArchive::Key(std::string_view name) const {
  std::string key;
  for (const std::string& part : path_) key += part + ".";
  return key + std::string(name);
}

void JsonReadArchive::Fail(std::string_view name, const std::string& why) const {
  throw SchemaError(fmt::format("{}: key '{}' {}", origin_, Key(name), why));
}

const json& JsonReadArchive::Get(std::string_view name) {
  const json& group = *stack_.back();
  auto it = group.find(std::string(name));
  if (it == group.end()) Fail(name, "is missing");
  visited_.push_back(Key(name));
  return *it;
}

void JsonReadArchive::CheckBounds(std::string_view name, double value,
                                  const Bounds& bounds) const {
  if (!bounds.Contains(value)) {
    Fail(name, fmt::format("= {} is outside {}", value, bounds.Describe()));
  }
}

void JsonReadArchive::Visit(std::string_view name, double* value, Bounds bounds) {
  const json& v = Get(name);
  if (!v.is_number()) Fail(name, "must be a number");
  *value = v.get<double>();
  CheckBounds(name, *value, bounds);
}

void JsonReadArchive::Visit(std::string_view name, int64_t* value, Bounds bounds) {
  const json& v = Get(name);
  if (!v.is_number_integer()) Fail(name, "must be an integer");
  *value = v.get<int64_t>();
  CheckBounds(name, static_cast<double>(*value), bounds);
}

void JsonReadArchive::Visit(std::string_view name, bool* value) {
  const json& v = Get(name);
  if (!v.is_boolean()) Fail(name, "must be true or false");
  *value = v.get<bool>();
}

void JsonReadArchive::Visit(std::string_view name, std::string* value) {
  const json& v = Get(name);
  if (!v.is_string()) Fail(name, "must be a string");
  *value = v.get<std::string>();
}

void JsonReadArchive::Visit(std::string_view name, std::vector<double>* value, Bounds bounds) {
  const json& v = Get(name);
  if (!v.is_array()) Fail(name, "must be a list of numbers");
  value->clear();
  for (const json& item : v) {
    if (!item.is_number()) Fail(name, "must be a list of numbers");
    value->push_back(item.get<double>());
    CheckBounds(name, value->back(), bounds);
  }
}

void JsonReadArchive::Visit(std::string_view name, std::vector<std::string>* value) {
  const json& v = Get(name);
  if (!v.is_array()) Fail(name, "must be a list of strings");
  value->clear();
  for (const json& item : v) {
    if (!item.is_string()) Fail(name, "must be a list of strings");
    value->push_back(item.get<std::string>());
  }
}

void JsonReadArchive::VisitChoice(std::string_view name, std::string* value,
                                  const std::vector<std::string>& choices) {
  Visit(name, value);
  if (std::find(choices.begin(), choices.end(), *value) == choices.end()) {
    Fail(name, fmt::format("= '{}' is not one of {}", *value, fmt::join(choices, ", ")));
  }
}

void JsonReadArchive::BeginGroup(std::string_view name) {
  const json& v = Get(name);
  if (!v.is_object()) Fail(name, "must be an object");
  stack_.push_back(&v);
  path_.emplace_back(name);
}

void JsonReadArchive::EndGroup() {
  stack_.pop_back();
  path_.pop_back();
}

void JsonReadArchive::CheckNoUnknownKeys() const {
  // Walk the object; every key must have been read (groups recurse into their members).
  std::function<void(const json&, const std::string&)> walk = [&](const json& node,
                                                                  const std::string& prefix) {
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = prefix + it.key();
      if (std::find(visited_.begin(), visited_.end(), key) == visited_.end()) {
        throw SchemaError(fmt::format("{}: unknown key '{}'", origin_, key));
      }
      if (it->is_object()) walk(*it, key + ".");
    }
  };
  walk(*stack_.front(), "");
}

}  // namespace sonicboom::learning::internal
