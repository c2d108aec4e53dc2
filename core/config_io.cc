#include "sonicboom/core/config_io.h"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"

namespace sonicboom {

// ---- Bounds ----

bool Bounds::Contains(double v) const {
  if (std::isnan(v)) return false;
  if (lo_open ? !(v > lo) : !(v >= lo)) return false;
  if (hi_open ? !(v < hi) : !(v <= hi)) return false;
  return true;
}

std::string Bounds::Describe() const {
  return fmt::format("{}{}, {}{}", lo_open ? "(" : "[", lo, hi, hi_open ? ")" : "]");
}

// ---- layers ----

struct ConfigLayers::Impl {
  YAML::Node merged{YAML::NodeType::Map};
  std::map<std::string, std::string> origin;  // dotted key -> file or override that set it

  // recursive merge: maps merge key by key, everything else replaces
  void Merge(YAML::Node dst, const YAML::Node& src, const std::string& prefix,
             const std::string& from) {
    for (const auto& kv : src) {
      const std::string key = kv.first.as<std::string>();
      const std::string path = prefix.empty() ? key : prefix + "." + key;
      origin[path] = from;
      if (kv.second.IsMap() && dst[key] && dst[key].IsMap()) {
        Merge(dst[key], kv.second, path, from);
      } else {
        dst[key] = YAML::Clone(kv.second);
        MarkOrigins(kv.second, path, from);
      }
    }
  }
  void MarkOrigins(const YAML::Node& node, const std::string& prefix, const std::string& from) {
    if (!node.IsMap()) return;
    for (const auto& kv : node) {
      const std::string path = prefix + "." + kv.first.as<std::string>();
      origin[path] = from;
      MarkOrigins(kv.second, path, from);
    }
  }
  std::string OriginOf(const std::string& path) const {
    // the closest enclosing key that a layer set
    std::string p = path;
    while (true) {
      auto it = origin.find(p);
      if (it != origin.end()) return it->second;
      const auto dot = p.rfind('.');
      if (dot == std::string::npos) return "defaults";
      p = p.substr(0, dot);
    }
  }
};

ConfigLayers::ConfigLayers() : impl_(std::make_unique<Impl>()) {}
ConfigLayers::~ConfigLayers() = default;
ConfigLayers::ConfigLayers(ConfigLayers&&) noexcept = default;
ConfigLayers& ConfigLayers::operator=(ConfigLayers&&) noexcept = default;

namespace {

// Deepest nesting a config may have; the config structs nest four levels at most.
constexpr int kMaxConfigDepth = 32;
// Most nodes a config may expand to, aliases followed (the defaults hold about 700): bounds the
// expansion of nested aliases, which a YAML parser shares but every walk of the tree visits
constexpr int64_t kMaxConfigNodes = 100000;

// Refuses what a YAML parser accepts but a config cannot mean: a key twice in one mapping, and
// nesting without end (an alias that refers to its own ancestor makes a cycle).
void CheckTree(const YAML::Node& node, const std::string& path, const std::string& origin,
               int depth, int64_t* nodes) {
  if (++*nodes > kMaxConfigNodes) {
    throw ConfigError(fmt::format(
        "{}: expands to more than {} nodes (aliases of aliases?); a config is far smaller",
        origin, kMaxConfigNodes));
  }
  if (depth > kMaxConfigDepth) {
    const std::string shown = path.size() > 60 ? path.substr(0, 60) + "..." : path;
    throw ConfigError(
        fmt::format("{}: key '{}' nests deeper than {} levels (an alias that refers to itself?)",
                    origin, shown, kMaxConfigDepth));
  }
  if (node.IsSequence()) {
    for (size_t i = 0; i < node.size(); ++i) {
      CheckTree(node[i], fmt::format("{}[{}]", path, i), origin, depth + 1, nodes);
    }
    return;
  }
  if (!node.IsMap()) return;
  std::set<std::string> keys;
  for (const auto& kv : node) {
    if (!kv.first.IsScalar()) {
      throw ConfigError(fmt::format("{}: a key under '{}' is not a plain name", origin, path));
    }
    const std::string key = kv.first.Scalar();
    const std::string child = path.empty() ? key : path + "." + key;
    if (!keys.insert(key).second) {
      throw ConfigError(fmt::format("{}: key '{}' appears twice", origin, child));
    }
    CheckTree(kv.second, child, origin, depth + 1, nodes);
  }
}

}  // namespace

void ConfigLayers::AddFile(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IoError(fmt::format("{}: no such config file", path));
  if (std::filesystem::is_directory(path)) {
    throw IoError(fmt::format("{}: is a directory, not a config file", path));
  }
  RequireReadableFile(path);
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot read config file", path));
  std::stringstream text;
  text << in.rdbuf();
  AddText(text.str(), path);
}

namespace {

// Counts documents and keeps nothing: the parser's events are dropped.
class DocumentCounter : public YAML::EventHandler {
 public:
  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

// Whether the text holds a second YAML document. At most two are parsed: yaml-cpp's LoadAll
// loops forever on some damaged input (a 28-byte file with NUL bytes, found by fuzzing).
bool HasSecondDocument(const std::string& yaml_text) {
  std::stringstream in(yaml_text);
  YAML::Parser parser(in);
  DocumentCounter counter;
  int documents = 0;
  while (documents < 2 && parser.HandleNextDocument(counter)) ++documents;
  return documents >= 2;
}

}  // namespace

void ConfigLayers::AddText(const std::string& yaml_text, const std::string& origin) {
  YAML::Node node;
  try {
    if (HasSecondDocument(yaml_text)) {
      throw ConfigError(fmt::format(
          "{}: holds more than one YAML document; a config is one document ('---' starts another)",
          origin));
    }
    node = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: invalid YAML at line {}, column {}: {}", origin,
                                  e.mark.line + 1, e.mark.column + 1, e.msg));
  }
  if (node.IsNull()) return;
  if (!node.IsMap()) throw ConfigError(fmt::format("{}: a config must be a YAML mapping", origin));
  int64_t nodes = 0;
  CheckTree(node, "", origin, 0, &nodes);
  impl_->Merge(impl_->merged, node, "", origin);
}

void ConfigLayers::AddOverride(const std::string& assignment) {
  // "a.b.c=value" -> nested mapping {a: {b: {c: value}}}
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError(fmt::format("--set '{}': expected key=value", assignment));
  }
  const std::string key = assignment.substr(0, eq);
  const std::string value = assignment.substr(eq + 1);
  if (value.find_first_not_of(" \t") == std::string::npos) {
    throw ConfigError(fmt::format(
        "--set '{}': empty value (give {} a value, or leave the option out)", assignment, key));
  }
  YAML::Node leaf;
  try {
    leaf = YAML::Load(value);
  } catch (const YAML::Exception&) {
    leaf = YAML::Node(value);
  }
  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string part; std::getline(ss, part, '.');) {
    if (part.empty()) throw ConfigError(fmt::format("--set '{}': empty key segment", assignment));
    parts.push_back(part);
  }
  // built leaf-first; Node::reset rebinds (operator= would copy into the old node)
  YAML::Node node = leaf;
  for (size_t i = parts.size(); i-- > 0;) {
    YAML::Node parent(YAML::NodeType::Map);
    parent[parts[i]] = node;
    node.reset(parent);
  }
  const YAML::Node root = node;
  int64_t nodes = 0;
  CheckTree(root, "", "--set " + assignment, 0, &nodes);
  impl_->Merge(impl_->merged, root, "", "--set " + assignment);
}

// ---- strict YAML reader ----

namespace {

class YamlReadArchive : public Archive {
 public:
  YamlReadArchive(const YAML::Node& root, std::function<std::string(const std::string&)> origin_of)
      : origin_of_(std::move(origin_of)) {
    frames_.push_back({root, "", {}});
  }

  void Visit(std::string_view name, double* value, Bounds bounds) override {
    if (auto node = Child(name)) {
      *value = Convert<double>(node, name, "a number");
      CheckBounds(name, *value, bounds);
    }
  }
  void Visit(std::string_view name, int64_t* value, Bounds bounds) override {
    if (auto node = Child(name)) {
      *value = Convert<int64_t>(node, name, "an integer");
      CheckBounds(name, static_cast<double>(*value), bounds);
    }
  }
  void Visit(std::string_view name, bool* value) override {
    if (auto node = Child(name)) *value = Convert<bool>(node, name, "true or false");
  }
  void Visit(std::string_view name, std::string* value) override {
    if (auto node = Child(name)) *value = Convert<std::string>(node, name, "a string");
  }
  void Visit(std::string_view name, std::vector<double>* value, Bounds bounds) override {
    if (auto node = Child(name)) {
      if (!node.IsSequence()) Fail(name, "expected a list of numbers", node);
      value->clear();
      for (const auto& item : node) {
        value->push_back(Convert<double>(item, name, "a list of numbers"));
        CheckBounds(name, value->back(), bounds);
      }
    }
  }
  void Visit(std::string_view name, std::vector<std::string>* value) override {
    if (auto node = Child(name)) {
      if (!node.IsSequence()) Fail(name, "expected a list of strings", node);
      value->clear();
      for (const auto& item : node) value->push_back(Convert<std::string>(item, name, "strings"));
    }
  }
  void VisitChoice(std::string_view name, std::string* value,
                   const std::vector<std::string>& choices) override {
    if (auto node = Child(name)) {
      const auto s = Convert<std::string>(node, name, "a string");
      if (std::find(choices.begin(), choices.end(), s) == choices.end()) {
        std::string list;
        for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
        throw ConfigError(fmt::format("config key '{}' = '{}' (from {}) is not one of: {}",
                                      Path(name), s, origin_of_(Path(name)), list));
      }
      *value = s;
    }
  }

  // unknown keys at the root
  void Finish() { CheckUnknown(frames_.back()); }

 protected:
  void BeginGroup(std::string_view name) override {
    YAML::Node node = Child(name);
    if (node && !node.IsMap()) Fail(name, "expected a mapping", node);
    frames_.push_back({node ? node : YAML::Node(), Path(name), {}});
  }
  void EndGroup() override {
    CheckUnknown(frames_.back());
    frames_.pop_back();
  }
  std::optional<size_t> BeginList(std::string_view name) override {
    YAML::Node node = Child(name);
    if (node) {
      if (!node.IsSequence()) Fail(name, "expected a list of mappings", node);
      for (const auto& item : node) {
        if (!item.IsMap()) Fail(name, "expected a list of mappings", item);
      }
    }
    // the list frame holds the sequence; its items get frames "name.0", "name.1", ...
    frames_.push_back({node ? node : YAML::Node(), Path(name), {}});
    if (!node) return std::nullopt;
    return node.size();
  }
  void BeginItem(size_t index) override {
    const Frame& list = frames_.back();
    Frame item{
        list.node ? list.node[index] : YAML::Node(), list.path + "." + std::to_string(index), {}};
    frames_.push_back(std::move(item));
  }
  void EndItem() override {
    CheckUnknown(frames_.back());
    frames_.pop_back();
  }
  void EndList() override { frames_.pop_back(); }

 private:
  struct Frame {
    YAML::Node node;
    std::string path;
    std::set<std::string> visited;
  };

  std::string Path(std::string_view name) const {
    const auto& prefix = frames_.back().path;
    return prefix.empty() ? std::string(name) : prefix + "." + std::string(name);
  }
  YAML::Node Child(std::string_view name) {
    auto& frame = frames_.back();
    frame.visited.insert(std::string(name));
    if (!frame.node || !frame.node.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    YAML::Node child = frame.node[std::string(name)];
    if (!child) return YAML::Node(YAML::NodeType::Undefined);
    // "key:" with nothing after it (an empty value, or a section whose keys were left out)
    if (child.IsNull()) Fail(name, "has no value (an empty value or a bare section)", child);
    return child;
  }
  template <typename T>
  T Convert(const YAML::Node& node, std::string_view name, const char* expected) {
    T value{};
    try {
      if (!node.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "not a scalar");
      value = node.as<T>();
    } catch (const YAML::Exception&) {
      Fail(name, fmt::format("expected {}", expected), node);
    }
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      CheckNumberText(name, node, expected);
      if constexpr (std::is_floating_point_v<T>) {
        if (!std::isfinite(value)) Fail(name, "expected a finite number", node);
      }
    }
    return value;
  }
  // A number written as YAML 1.1 reads it behind the user's back: a leading zero (010 is octal
  // 8), hexadecimal or octal prefixes
  void CheckNumberText(std::string_view name, const YAML::Node& node, const char* expected) {
    const std::string& text = node.Scalar();
    size_t i = (!text.empty() && (text[0] == '+' || text[0] == '-')) ? 1 : 0;
    const char next = i + 1 < text.size() ? text[i + 1] : '\0';
    if (text[i] == '0' && (std::isdigit(static_cast<unsigned char>(next)) ||
                           std::strchr("xXoObB", next) != nullptr) && next != '\0') {
      Fail(name,
           fmt::format("expected {} in plain decimal (a leading zero or a 0x / 0o prefix reads "
                       "as octal or hexadecimal)",
                       expected),
           node);
    }
  }
  [[noreturn]] void Fail(std::string_view name, const std::string& what, const YAML::Node& node) {
    std::string shown = node.IsScalar()     ? node.Scalar()
                        : node.IsSequence() ? "a list"
                        : node.IsNull()     ? "nothing"
                                            : "a mapping";
    throw ConfigError(fmt::format("config key '{}' (from {}): {}, got '{}'", Path(name),
                                  origin_of_(Path(name)), what, shown));
  }
  void CheckBounds(std::string_view name, double v, const Bounds& bounds) {
    if (!bounds.Contains(v)) {
      throw ConfigError(fmt::format("config key '{}' = {} (from {}) is out of range {}", Path(name),
                                    v, origin_of_(Path(name)), bounds.Describe()));
    }
  }
  void CheckUnknown(const Frame& frame) {
    if (!frame.node || !frame.node.IsMap()) return;
    for (const auto& kv : frame.node) {
      const auto key = kv.first.as<std::string>();
      if (!frame.visited.count(key)) {
        const std::string path = frame.path.empty() ? key : frame.path + "." + key;
        throw ConfigError(fmt::format("unknown config key '{}' (from {})", path, origin_of_(path)));
      }
    }
  }

  std::vector<Frame> frames_;
  std::function<std::string(const std::string&)> origin_of_;
};

// ---- YAML writer ----

class YamlWriteArchive : public Archive {
 public:
  YamlWriteArchive() { stack_.push_back({"", YAML::Node(YAML::NodeType::Map)}); }

  void Visit(std::string_view name, double* value, Bounds) override {
    Set(name, YAML::Node(FormatDouble(*value)));
  }
  void Visit(std::string_view name, int64_t* value, Bounds) override {
    Set(name, YAML::Node(*value));
  }
  void Visit(std::string_view name, bool* value) override { Set(name, YAML::Node(*value)); }
  void Visit(std::string_view name, std::string* value) override { Set(name, YAML::Node(*value)); }
  void Visit(std::string_view name, std::vector<double>* value, Bounds) override {
    YAML::Node seq(YAML::NodeType::Sequence);
    seq.SetStyle(YAML::EmitterStyle::Flow);
    for (double v : *value) seq.push_back(YAML::Node(FormatDouble(v)));
    Set(name, seq);
  }
  void Visit(std::string_view name, std::vector<std::string>* value) override {
    YAML::Node seq(YAML::NodeType::Sequence);
    seq.SetStyle(YAML::EmitterStyle::Flow);
    for (const auto& v : *value) seq.push_back(YAML::Node(v));
    Set(name, seq);
  }
  void VisitChoice(std::string_view name, std::string* value,
                   const std::vector<std::string>&) override {
    Set(name, YAML::Node(*value));
  }

  std::string Emit() const {
    YAML::Emitter out;
    out << stack_.front().second;
    return std::string(out.c_str()) + "\n";
  }

 protected:
  void BeginGroup(std::string_view name) override {
    stack_.push_back({std::string(name), YAML::Node(YAML::NodeType::Map)});
  }
  void EndGroup() override {
    // attach the finished group under its name in the parent
    auto group = stack_.back();
    stack_.pop_back();
    stack_.back().second[group.first] = group.second;
  }
  std::optional<size_t> BeginList(std::string_view name) override {
    stack_.push_back({std::string(name), YAML::Node(YAML::NodeType::Sequence)});
    return std::nullopt;  // write the existing items
  }
  void BeginItem(size_t) override { stack_.push_back({"", YAML::Node(YAML::NodeType::Map)}); }
  void EndItem() override {
    auto item = stack_.back();
    stack_.pop_back();
    stack_.back().second.push_back(item.second);
  }
  void EndList() override {
    auto list = stack_.back();
    stack_.pop_back();
    stack_.back().second[list.first] = list.second;
  }

 private:
  static std::string FormatDouble(double v) { return fmt::format("{}", v); }
  void Set(std::string_view name, const YAML::Node& node) {
    stack_.back().second[std::string(name)] = node;
  }

  std::vector<std::pair<std::string, YAML::Node>> stack_;  // (group or list name, node)
};

}  // namespace

std::unique_ptr<Archive> ConfigLayers::MakeReadArchive() const {
  const Impl* impl = impl_.get();
  return std::make_unique<YamlReadArchive>(
      impl->merged, [impl](const std::string& path) { return impl->OriginOf(path); });
}

void ConfigLayers::FinishRead(Archive* archive) const {
  static_cast<YamlReadArchive*>(archive)->Finish();
}

}  // namespace sonicboom

namespace sonicboom::internal {

std::unique_ptr<Archive> MakeYamlWriteArchive() {
  return std::make_unique<YamlWriteArchive>();
}

std::string FinishYamlWrite(Archive* archive) {
  return static_cast<YamlWriteArchive*>(archive)->Emit();
}

}  // namespace sonicboom::internal
