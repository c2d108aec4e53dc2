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
                       const std::vector<std::string>& shards, bool virtual_audio, bool force) {
  std::vector<ReadPath> reads;
  for (const std::string& shard : shards) reads.push_back({shard, "shard"});
  CheckOutput(g, {out, "--out", force}, reads);
  CheckConfigSidecar({out, "--out", force});
  MergeDatasets(shards, out, virtual_audio);
  DatasetReader reader(out);
  WriteTextAtomic(out + ".config.yaml", reader.info().config_yaml);
  json j = {{"path", out},
            {"num_samples", reader.size()},
            {"shards", shards.size()},
            {"virtual", virtual_audio}};
  return {j.dump(),
          fmt::format("merged {} shards into {} ({} samples{})\n", shards.size(), out,
                      reader.size(), virtual_audio ? "; audio read from the shards in place" : "")};
}

void RegisterMerge(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string out;
    std::vector<std::string> shards;
    bool virtual_audio = false, force = false;
  };
  auto o = std::make_shared<Options>();
  auto* merge = app.add_subcommand("merge", "join dataset shards into one file");
  merge->add_option("--out", o->out, "merged dataset file")->required();
  merge->add_option("shards", o->shards, "shard files")->required();
  merge->add_flag("--virtual", o->virtual_audio,
                  "audio as an HDF5 virtual dataset over the shards (no copy; keep the shards "
                  "where they are, relative to the output)");
  merge->add_flag("--force", o->force, "replace an existing output (once the new one is complete)");
  merge->callback([&g, run, o] {
    *run = [&g, o] { return RunMerge(g, o->out, o->shards, o->virtual_audio, o->force); };
  });
}

}  // namespace sonicboom::experiments
