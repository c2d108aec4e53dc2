#!/usr/bin/env bash
# Runs a command as one process of a data-parallel training: RANK and WORLD_SIZE from the
# launcher (torchrun-style variables if set, else Open MPI, PMI or Slurm's), MASTER_ADDR and
# MASTER_PORT kept or defaulted (127.0.0.1:29500; under Slurm the job's first node).
#
#   srun -n 4 scripts/cluster/ddp_env.sh build/bin/sonicboom train --data D.h5 --out RUN
#   mpirun -np 4 scripts/cluster/ddp_env.sh build/bin/sonicboom train --data D.h5 --out RUN
set -euo pipefail
export RANK=${RANK:-${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-${SLURM_PROCID:-0}}}}
export WORLD_SIZE=${WORLD_SIZE:-${OMPI_COMM_WORLD_SIZE:-${PMI_SIZE:-${SLURM_NTASKS:-1}}}}
if [ -z "${MASTER_ADDR:-}" ] && [ -n "${SLURM_JOB_NODELIST:-}" ] && command -v scontrol >/dev/null; then
  MASTER_ADDR=$(scontrol show hostnames "$SLURM_JOB_NODELIST" | head -n 1)
fi
export MASTER_ADDR=${MASTER_ADDR:-127.0.0.1}
export MASTER_PORT=${MASTER_PORT:-29500}
exec "$@"
