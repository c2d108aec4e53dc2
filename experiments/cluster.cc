#include "sonicboom/experiments/cluster.h"

#include <fmt/format.h>

#include <charconv>
#include <cstdlib>
#include <optional>

#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {
namespace {

// An integer variable, or nullopt when unset; ConfigError naming it when not an integer.
std::optional<int64_t> IntegerVariable(const EnvironmentLookup& lookup, const char* name) {
  const char* text = lookup(name);
  if (text == nullptr || *text == '\0') return std::nullopt;
  int64_t value = 0;
  const char* end = text + std::char_traits<char>::length(text);
  const auto [ptr, ec] = std::from_chars(text, end, value);
  if (ec != std::errc() || ptr != end) {
    throw ConfigError(fmt::format("--shard auto: {}='{}' is not an integer", name, text));
  }
  return value;
}

ShardAssignment Checked(int64_t shard, int64_t num_shards, std::string source) {
  if (num_shards < 1 || shard < 0 || shard >= num_shards) {
    throw ConfigError(fmt::format("--shard auto: {} gives shard {} of {}, outside [0, {})", source,
                                  shard, num_shards, num_shards));
  }
  return {shard, num_shards, std::move(source)};
}

}  // namespace

ShardAssignment ShardFromEnvironment(const EnvironmentLookup& given) {
  const EnvironmentLookup lookup =
      given ? given : EnvironmentLookup([](const char* name) { return std::getenv(name); });
  // Slurm job array: task ids min..max, possibly 1-based
  if (const auto id = IntegerVariable(lookup, "SLURM_ARRAY_TASK_ID")) {
    const auto min = IntegerVariable(lookup, "SLURM_ARRAY_TASK_MIN");
    const auto max = IntegerVariable(lookup, "SLURM_ARRAY_TASK_MAX");
    if (!min || !max) {
      throw ConfigError(
          "--shard auto: SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_MIN / "
          "SLURM_ARRAY_TASK_MAX are not");
    }
    const int64_t span = *max - *min + 1;
    if (const auto count = IntegerVariable(lookup, "SLURM_ARRAY_TASK_COUNT");
        count && *count != span) {
      throw ConfigError(fmt::format(
          "--shard auto: SLURM_ARRAY_TASK_COUNT = {} but the task ids span {}..{}: use a "
          "contiguous array (--array={}-{}) without a step",
          *count, *min, *max, *min, *min + *count - 1));
    }
    return Checked(*id - *min, span, "SLURM_ARRAY_TASK_ID/MIN/MAX");
  }
  // MPI launchers: the rank and size of the world
  const std::pair<const char*, const char*> mpi[] = {
      {"OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"},
      {"PMI_RANK", "PMI_SIZE"},
      {"PMIX_RANK", "OMPI_COMM_WORLD_SIZE"},
      {"PMIX_RANK", "PMI_SIZE"},
      {"SLURM_PROCID", "SLURM_NTASKS"}};
  for (const auto& [rank_name, size_name] : mpi) {
    const auto rank = IntegerVariable(lookup, rank_name);
    if (!rank) continue;
    const auto size = IntegerVariable(lookup, size_name);
    if (!size) continue;
    return Checked(*rank, *size, fmt::format("{}/{}", rank_name, size_name));
  }
  throw ConfigError(
      "--shard auto: no launcher variables found (SLURM_ARRAY_TASK_ID, OMPI_COMM_WORLD_RANK, "
      "PMI_RANK, PMIX_RANK, SLURM_PROCID); run under sbatch --array, mpirun or srun, or give "
      "--shard and --num-shards");
}

std::string ShardOutputPath(const std::string& out, const ShardAssignment& shard) {
  std::string path = out;
  bool has_shard = false;
  for (const auto& [key, value] : {std::pair{std::string("{shard}"), shard.shard},
                                   std::pair{std::string("{num_shards}"), shard.num_shards}}) {
    for (size_t at = path.find(key); at != std::string::npos; at = path.find(key, at)) {
      path.replace(at, key.size(), std::to_string(value));
      has_shard = has_shard || key == "{shard}";
    }
  }
  // every process of a launcher runs the same command: its file must differ by shard
  if (shard.source != "--shard" && shard.num_shards > 1 && !has_shard) {
    throw ConfigError(
        fmt::format("--out {}: {} shards would write one file; put {{shard}} in the name (e.g. "
                    "data-{{shard}}.h5)",
                    out, shard.num_shards));
  }
  return path;
}

}  // namespace sonicboom::experiments
