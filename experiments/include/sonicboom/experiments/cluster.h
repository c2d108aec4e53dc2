#pragma once
/// Generation on a cluster: which shard this process is, from the environment its launcher set,
/// so that one unchanged command runs under `sbatch --array` and `mpirun -np N`
/// (scripts/cluster/). Shards merge into the dataset a single process would write.

#include <cstdint>
#include <functional>
#include <string>

namespace sonicboom::experiments {

/// A process's shard of a generated set.
struct ShardAssignment {
  int64_t shard{0};
  int64_t num_shards{1};
  std::string source;  // the variables it came from, for messages
};

/// Reads an environment variable (nullptr when unset); std::getenv by default.
using EnvironmentLookup = std::function<const char*(const char*)>;

/// The shard of this process, in this order of precedence:
///   Slurm job array: SLURM_ARRAY_TASK_ID in [SLURM_ARRAY_TASK_MIN, SLURM_ARRAY_TASK_MAX]
///     (SLURM_ARRAY_TASK_COUNT, when set, must equal their span: a stepped array is refused);
///   Open MPI: OMPI_COMM_WORLD_RANK / OMPI_COMM_WORLD_SIZE;
///   PMI (MPICH, Intel MPI, srun --mpi=pmi2): PMI_RANK / PMI_SIZE;
///   PMIx: PMIX_RANK with OMPI_COMM_WORLD_SIZE or PMI_SIZE;
///   Slurm tasks (srun -n N): SLURM_PROCID / SLURM_NTASKS.
/// ConfigError naming the variables when none is set, or when a value is not an integer or
/// lies outside its range.
ShardAssignment ShardFromEnvironment(const EnvironmentLookup& lookup = {});

/// `out` with "{shard}" and "{num_shards}" replaced by the assignment's numbers. ConfigError when
/// several shards of a launcher would write one file (an assignment from the environment,
/// num_shards > 1, and no "{shard}" in `out`).
std::string ShardOutputPath(const std::string& out, const ShardAssignment& shard);

}  // namespace sonicboom::experiments
