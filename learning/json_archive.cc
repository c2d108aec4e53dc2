#include "internal/json_archive.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::learning::internal {

using nlohmann::json;

JsonWriteArchive::JsonWriteArchive() : root_(json::object()), stack_{&root_} {}

void JsonWriteArchive::Visit(std::string_view name, double* value, Bounds) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, int64_t* value, Bounds) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, bool* value) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::string* value) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::vector<double>* value, Bounds) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::Visit(std::string_view name, std::vector<std::string>* value) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::VisitChoice(std::string_view name, std::string* value,
                                   const std::vector<std::string>&) {
  (*stack_.back())[std::string(name)] = *value;
}
void JsonWriteArchive::BeginGroup(std::string_view name) {
  json& group = (*stack_.back())[std::string(name)] = json::object();
  stack_.push_back(&group);
}
void JsonWriteArchive::EndGroup() {
  stack_.pop_back();
}
std::optional<size_t> JsonWriteArchive::BeginList(std::string_view name) {
  json& list = (*stack_.back())[std::string(name)] = json::array();
  stack_.push_back(&list);
  return std::nullopt;  // write the existing items
}
void JsonWriteArchive::BeginItem(size_t) {
  stack_.back()->push_back(json::object());
  stack_.push_back(&stack_.back()->back());
}
void JsonWriteArchive::EndItem() {
  stack_.pop_back();
}
void JsonWriteArchive::EndList() {
  stack_.pop_back();
}

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

void JsonReadArchive::CheckBounds(std::string_view name, double value, const Bounds& bounds) const {
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

std::optional<size_t> JsonReadArchive::BeginList(std::string_view name) {
  const json& v = Get(name);
  if (!v.is_array()) Fail(name, "must be a list of objects");
  for (const json& item : v) {
    if (!item.is_object()) Fail(name, "must be a list of objects");
  }
  stack_.push_back(&v);
  path_.emplace_back(name);
  return v.size();
}

void JsonReadArchive::BeginItem(size_t index) {
  stack_.push_back(&stack_.back()->at(index));
  path_.push_back(std::to_string(index));
}

void JsonReadArchive::EndItem() {
  stack_.pop_back();
  path_.pop_back();
}

void JsonReadArchive::EndList() {
  stack_.pop_back();
  path_.pop_back();
}

void JsonReadArchive::CheckNoUnknownKeys() const {
  // Walk the object; every key must have been read (groups and list items recurse into their
  // members, an item's keys being "list.index.key").
  std::function<void(const json&, const std::string&)> walk = [&](const json& node,
                                                                  const std::string& prefix) {
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = prefix + it.key();
      if (std::find(visited_.begin(), visited_.end(), key) == visited_.end()) {
        throw SchemaError(fmt::format("{}: unknown key '{}'", origin_, key));
      }
      if (it->is_object()) walk(*it, key + ".");
      if (it->is_array()) {
        for (size_t i = 0; i < it->size(); ++i) {
          if ((*it)[i].is_object()) walk((*it)[i], key + "." + std::to_string(i) + ".");
        }
      }
    }
  };
  walk(*stack_.front(), "");
}

}  // namespace sonicboom::learning::internal
