// `generate`: simulated strikes into a dataset (or one shard of it).
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <limits>

#include <algorithm>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/pipeline.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

// --count and --first-index not given: the config's dataset.count and dataset.first_index
constexpr int64_t kUnset = std::numeric_limits<int64_t>::min();

CommandResult RunGenerate(const GlobalOptions& g, const std::string& out, int64_t count,
                          int64_t first_index, int64_t shard, int64_t num_shards) {
  const SonicBoomConfig config = Resolve(g);
  RequireParentDir(out);
  const int64_t n = count == kUnset ? config.dataset.count : count;
  const int64_t first = first_index == kUnset ? config.dataset.first_index : first_index;
  WriteConfigBeside(out, config);
  const GenerateResult r =
      GenerateDataset(config, out, n, first, shard, num_shards, g.threads, !g.quiet);
  json j = {{"path", r.path},     {"written", r.written},
            {"valid", r.valid},   {"clipped", r.clipped},
            {"wall_s", r.wall_s}, {"strikes_per_s", r.written / std::max(r.wall_s, 1e-9)}};
  return {j.dump(), fmt::format("wrote {} strikes ({} valid, {} clipped) to {} in {:.1f} s\n",
                                r.written, r.valid, r.clipped, r.path, r.wall_s)};
}

void RegisterGenerate(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string out;
    int64_t count = kUnset, first_index = kUnset, shard = 0, num_shards = 1;
  };
  auto o = std::make_shared<Options>();
  auto* generate = app.add_subcommand("generate", "simulate strikes into an HDF5 dataset");
  generate->add_option("--out", o->out, "dataset file (.h5)")->required();
  generate->add_option("--count", o->count, "number of strikes (default dataset.count)");
  generate->add_option("--first-index", o->first_index, "global index of the first strike");
  generate->add_option("--shard", o->shard,
                       "this shard (owns indices i with i % num-shards == shard)");
  generate->add_option("--num-shards", o->num_shards, "number of shards");
  generate->callback([&g, run, o] {
    *run = [&g, o] {
      return RunGenerate(g, o->out, o->count, o->first_index, o->shard, o->num_shards);
    };
  });
}

}  // namespace sonicboom::experiments
