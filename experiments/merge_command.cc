// `merge`: dataset shards joined into one file.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

CommandResult RunMerge(const GlobalOptions& g, const std::string& out,
                       const std::vector<std::string>& shards) {
  for (const std::string& shard : shards) RefuseOverwritingInput(out, shard, "shard");
  RequireParentDir(out);
  MergeDatasets(shards, out);
  DatasetReader reader(out);
  WriteTextAtomic(out + ".config.yaml", reader.info().config_yaml);
  json j = {{"path", out}, {"num_samples", reader.size()}, {"shards", shards.size()}};
  return {j.dump(), fmt::format("merged {} shards into {} ({} samples)\n", shards.size(), out,
                                reader.size())};
}

void RegisterMerge(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto out = std::make_shared<std::string>();
  auto shards = std::make_shared<std::vector<std::string>>();
  auto* merge = app.add_subcommand("merge", "join dataset shards into one file");
  merge->add_option("--out", *out, "merged dataset file")->required();
  merge->add_option("shards", *shards, "shard files")->required();
  merge->callback(
      [&g, run, out, shards] { *run = [&g, out, shards] { return RunMerge(g, *out, *shards); }; });
}

}  // namespace sonicboom::experiments
