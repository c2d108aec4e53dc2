#pragma once
/// Drake-style config serialization: every config struct has
///   void Serialize(sonicboom::Archive* a) { a->Visit("name_unit", &name_unit, Bounds::Positive());
///   ... }
/// and the same function drives YAML reading (strict: unknown keys are errors), YAML writing
/// (resolved configs beside every output) and docs. Archive implementations live in .cc files.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace sonicboom {

/// One value of a config enum and its name in YAML. Every enum a config holds declares, in its
/// own namespace, `std::span<const EnumName<E>> EnumNames(E)` listing each value once (found by
/// argument-dependent lookup); Archive::Visit reads and writes it by name.
template <typename E>
struct EnumName {
  E value;
  std::string_view name;
};

/// The YAML name of an enum value (names of values missing from the table are empty).
template <typename E>
requires std::is_enum_v<E> std::string_view NameOf(E value) {
  for (const EnumName<E>& e : EnumNames(E{})) {
    if (e.value == value) return e.name;
  }
  return {};
}

/// The enum value named `name`, or nullopt when no value has that name.
template <typename E>
requires std::is_enum_v<E> std::optional<E> EnumFromName(std::string_view name) {
  for (const EnumName<E>& e : EnumNames(E{})) {
    if (e.name == name) return e.value;
  }
  return std::nullopt;
}

/// Every name of an enum in table order, joined by ", " (for messages and help texts).
template <typename E>
requires std::is_enum_v<E> std::string EnumNameList() {
  std::string list;
  for (const EnumName<E>& e : EnumNames(E{})) {
    if (!list.empty()) list += ", ";
    list += e.name;
  }
  return list;
}

/// Allowed range of a numeric config value; checked when a config is read.
struct Bounds {
  double lo{-std::numeric_limits<double>::infinity()};
  double hi{std::numeric_limits<double>::infinity()};
  bool lo_open{false};  // lo itself excluded
  bool hi_open{false};  // hi itself excluded

  static Bounds Any() { return {}; }
  static Bounds Positive() { return {0.0, std::numeric_limits<double>::infinity(), true, false}; }
  static Bounds NonNegative() {
    return {0.0, std::numeric_limits<double>::infinity(), false, false};
  }
  static Bounds Closed(double lo, double hi) { return {lo, hi, false, false}; }
  static Bounds Open(double lo, double hi) { return {lo, hi, true, true}; }
  bool Contains(double v) const;
  std::string Describe() const;  // e.g. "(0, inf)"
};

/// Visitor over named config fields. Nested structs (and lists of them) are visited through their
/// Serialize.
class Archive {
 public:
  virtual ~Archive() = default;

  virtual void Visit(std::string_view name, double* value, Bounds bounds = {}) = 0;
  virtual void Visit(std::string_view name, int64_t* value, Bounds bounds = {}) = 0;
  virtual void Visit(std::string_view name, bool* value) = 0;
  virtual void Visit(std::string_view name, std::string* value) = 0;
  virtual void Visit(std::string_view name, std::vector<double>* value, Bounds bounds = {}) = 0;
  virtual void Visit(std::string_view name, std::vector<std::string>* value) = 0;
  /// A string restricted to a fixed set of choices.
  virtual void VisitChoice(std::string_view name, std::string* value,
                           const std::vector<std::string>& choices) = 0;

  /// An enum (EnumNames above): written by name; read by name, any other value refused naming
  /// the key and the allowed names.
  template <typename E>
  requires std::is_enum_v<E>
  void Visit(std::string_view name, E* value) {
    std::vector<std::string> names;
    for (const EnumName<E>& e : EnumNames(E{})) names.emplace_back(e.name);
    std::string chosen(NameOf(*value));
    VisitChoice(name, &chosen, names);
    for (const EnumName<E>& e : EnumNames(E{})) {
      if (e.name == chosen) *value = e.value;
    }
  }

  /// A nested config struct with its own Serialize.
  template <typename T>
  requires(!std::is_enum_v<T>) void Visit(std::string_view name, T* value) {
    BeginGroup(name);
    value->Serialize(this);
    EndGroup();
  }

  /// A list of nested config structs (each with its own Serialize). Reading: when the key is
  /// present, the list is replaced by that many default-constructed items, each then read; when
  /// absent, the existing items (defaults) are kept. Writing: every existing item is written.
  template <typename T>
  void VisitList(std::string_view name, std::vector<T>* values) {
    if (const std::optional<size_t> n = BeginList(name)) *values = std::vector<T>(*n);
    for (size_t i = 0; i < values->size(); ++i) {
      BeginItem(i);
      (*values)[i].Serialize(this);
      EndItem();
    }
    EndList();
  }

 protected:
  virtual void BeginGroup(std::string_view name) = 0;
  virtual void EndGroup() = 0;
  /// Opens a list: nullopt keeps the existing items, n replaces them with n default items.
  virtual std::optional<size_t> BeginList(std::string_view name) = 0;
  /// Item `index` of the open list; its fields are visited between BeginItem and EndItem.
  virtual void BeginItem(size_t index) = 0;
  virtual void EndItem() = 0;
  virtual void EndList() = 0;
};

}  // namespace sonicboom
