// `generate`: simulated strikes into a dataset (or one shard of it).
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <charconv>
#include <filesystem>
#include <limits>

#include <algorithm>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/cluster.h"
#include "sonicboom/experiments/pipeline.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// --count and --first-index not given: the config's dataset.count and dataset.first_index
constexpr int64_t kUnset = std::numeric_limits<int64_t>::min();

// --shard: a number, or "auto" (from the launcher's environment, with --num-shards)
ShardAssignment ParseShard(const std::string& shard, int64_t num_shards) {
  if (shard == "auto") return ShardFromEnvironment();
  int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(shard.data(), shard.data() + shard.size(), value);
  if (ec != std::errc() || ptr != shard.data() + shard.size()) {
    throw ConfigError(fmt::format("--shard '{}' must be an integer or auto", shard));
  }
  if (num_shards < 1) {
    throw ConfigError(fmt::format("--num-shards must be >= 1, got {}", num_shards));
  }
  if (value < 0 || value >= num_shards) {
    throw ConfigError(fmt::format("--shard must be in [0, {}), got {}", num_shards, value));
  }
  return {value, num_shards, "--shard"};
}

// An existing output: the same dataset, complete, is a finished shard (skipped); anything else
// is replaced only with --force.
bool AlreadyGenerated(const std::string& out, const DatasetInfo& identity, bool force) {
  if (!fs::exists(out)) return false;
  bool same = false;
  try {
    same = SameDatasetIdentity(DatasetReader(out).info(), identity);
  } catch (const Error&) {
    same = false;  // not a complete dataset of ours
  }
  if (same && !force) return true;
  if (!force) {
    throw IoError(fmt::format(
        "{}: exists and holds another dataset; --force replaces it once the new one is complete",
        out));
  }
  return false;
}

}  // namespace

CommandResult RunGenerate(const GlobalOptions& g, const std::string& out_pattern, int64_t count,
                          int64_t first_index, const std::string& shard_option, int64_t num_shards,
                          bool force) {
  const SonicBoomConfig config = Resolve(g);
  const ShardAssignment shard = ParseShard(shard_option, num_shards);
  const std::string out = ShardOutputPath(out_pattern, shard);
  RequireParentDir(out);
  RefuseWritingOverInputs(g, {out, "--out", force}, {});
  CheckConfigSidecar({out, "--out", force});
  const int64_t n = count == kUnset ? config.dataset.count : count;
  const int64_t first = first_index == kUnset ? config.dataset.first_index : first_index;

  GenerateResult r;
  if (n >= 1 &&
      AlreadyGenerated(out, GeneratedDatasetInfo(config, first, n, shard.shard, shard.num_shards),
                       force)) {
    // a rerun of a finished shard (a resumed cluster job): nothing to do
    const DatasetReader done(out);
    r.path = out;
    r.skipped = true;
    r.written = done.size();
    spdlog::info("{}: already complete (shard {} of {}); skipped", out, shard.shard,
                 shard.num_shards);
  } else {
    r = GenerateDataset(config, out,
                        {.count = n,
                         .first_index = first,
                         .shard = shard.shard,
                         .num_shards = shard.num_shards,
                         .threads = g.threads,
                         .show_progress = !g.quiet});
  }
  // the config sidecar once the data is in place
  WriteConfigBeside(out, config);
  json j = {{"path", r.path},       {"written", r.written},
            {"valid", r.valid},     {"clipped", r.clipped},
            {"resumed", r.resumed}, {"skipped", r.skipped},
            {"shard", shard.shard}, {"num_shards", shard.num_shards},
            {"wall_s", r.wall_s},   {"strikes_per_s", r.written / std::max(r.wall_s, 1e-9)}};
  if (r.skipped) {
    return {j.dump(), fmt::format("{} is complete ({} strikes, shard {} of {}); nothing to do\n",
                                  r.path, r.written, shard.shard, shard.num_shards)};
  }
  std::string text = fmt::format("wrote {} strikes ({} valid, {} clipped) to {} in {:.1f} s",
                                 r.written, r.valid, r.clipped, r.path, r.wall_s);
  if (r.resumed > 0) text += fmt::format(" ({} carried over from an interrupted run)", r.resumed);
  if (shard.num_shards > 1) text += fmt::format(" (shard {} of {})", shard.shard, shard.num_shards);
  return {j.dump(), text + "\n"};
}

void RegisterGenerate(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string out, shard = "0";
    int64_t count = kUnset, first_index = kUnset, num_shards = 1;
    bool force = false;
  };
  auto o = std::make_shared<Options>();
  auto* generate = app.add_subcommand("generate", "simulate strikes into an HDF5 dataset");
  generate
      ->add_option("--out", o->out,
                   "dataset file (.h5); {shard} in the name is replaced by the shard number")
      ->required();
  generate->add_option("--count", o->count, "number of strikes (default dataset.count)");
  generate->add_option("--first-index", o->first_index, "global index of the first strike");
  generate->add_option("--shard", o->shard,
                       "this shard (owns indices i with i % num-shards == shard), or auto: from "
                       "Slurm array or MPI launcher variables");
  generate->add_option("--num-shards", o->num_shards, "number of shards (with a numbered --shard)");
  generate->add_flag("--force", o->force,
                     "replace an existing output (once the new one is complete)");
  generate->callback([&g, run, o] {
    *run = [&g, o] {
      return RunGenerate(g, o->out, o->count, o->first_index, o->shard, o->num_shards, o->force);
    };
  });
}

}  // namespace sonicboom::experiments
