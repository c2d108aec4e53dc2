// `config`: the resolved config as YAML, or (--markdown SECTIONS) its keys under the named
// top-level sections as a Markdown table, the form docs/conventions.md embeds and a test keeps
// current (scripts/update_docs_defaults.py rewrites the doc's generated blocks).
#include <CLI/CLI.hpp>

#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>
#include <nlohmann/json.hpp>

#include "internal/subcommands.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/commands.h"

namespace sonicboom::experiments {
namespace {

// (dotted key, value) of every leaf under `node`; a list is one value in flow style.
void Flatten(const YAML::Node& node, const std::string& key,
             std::vector<std::pair<std::string, std::string>>* rows) {
  if (node.IsMap()) {
    for (const auto& item : node) Flatten(item.second, key + "." + item.first.Scalar(), rows);
    return;
  }
  if (node.IsScalar()) {
    rows->emplace_back(key, node.Scalar().empty() ? "\"\"" : node.Scalar());
    return;
  }
  YAML::Emitter flow;
  flow << YAML::Flow << node;
  rows->emplace_back(key, flow.c_str());
}

std::string MarkdownTable(const std::string& yaml, const std::string& sections) {
  const YAML::Node root = YAML::Load(yaml);
  std::vector<std::pair<std::string, std::string>> rows;
  std::stringstream list(sections);
  for (std::string section; std::getline(list, section, ',');) {
    const YAML::Node node = root[section];
    if (!node || !node.IsMap()) {
      std::string known;
      for (const auto& item : root) {
        if (item.second.IsMap()) known += (known.empty() ? "" : ", ") + item.first.Scalar();
      }
      throw ConfigError(
          fmt::format("--markdown: no config section '{}' (sections: {})", section, known));
    }
    Flatten(node, section, &rows);
  }
  std::string table = "| key | value |\n|---|---|\n";
  for (const auto& [key, value] : rows) table += fmt::format("| `{}` | {} |\n", key, value);
  return table;
}

}  // namespace

CommandResult RunConfig(const GlobalOptions& g, const std::string& markdown_sections) {
  const std::string yaml = ConfigToYaml(ResolveConfig(g.sources));
  if (markdown_sections.empty()) return {nlohmann::json{{"config_yaml", yaml}}.dump(), yaml};
  const std::string table = MarkdownTable(yaml, markdown_sections);
  return {nlohmann::json{{"markdown", table}}.dump(), table};
}

void RegisterConfig(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto sections = std::make_shared<std::string>();
  auto* config = app.add_subcommand("config", "print the resolved config");
  config->add_option("--markdown", *sections,
                     "SECTIONS: a Markdown table of the keys of these comma-separated sections "
                     "(docs/conventions.md)");
  config->callback(
      [&g, run, sections] { *run = [&g, sections] { return RunConfig(g, *sections); }; });
}

}  // namespace sonicboom::experiments
