#!/usr/bin/env bash
# Generates a dataset with N processes under mpirun (Open MPI, MPICH or any launcher that sets
# OMPI_COMM_WORLD_RANK/SIZE or PMI_RANK/SIZE), then merges the shards into one file. The same
# line works on one machine (-np = cores / threads) or across hosts (add --hostfile). Rerunning
# it skips finished shards and resumes interrupted ones. The result equals a single-process run.
#
#   scripts/cluster/generate_mpirun.sh NP OUT_DIR COUNT [CONFIG...]
set -euo pipefail
NP=${1:?usage: scripts/cluster/generate_mpirun.sh NP OUT_DIR COUNT [CONFIG...]}
OUT=${2:?output directory}
COUNT=${3:?count of strikes}
shift 3
BIN=${SONICBOOM_BIN:-build/bin/sonicboom}
configs=()
for c in "$@"; do configs+=(--config "$c"); done
mkdir -p "$OUT"
# as root (containers) Open MPI needs to be told that this is intended
root_flag=()
[ "$(id -u)" -eq 0 ] && root_flag=(--allow-run-as-root)
mpirun "${root_flag[@]}" --oversubscribe -np "$NP" "$BIN" -q --threads "${THREADS:-1}" \
  "${configs[@]}" generate --count "$COUNT" --shard auto --out "$OUT/shard-{shard}.h5"
shards=()
for ((s = 0; s < NP; ++s)); do shards+=("$OUT/shard-$s.h5"); done
# the merged file follows the shards: a rerun writes it again
"$BIN" -q merge --force --out "$OUT/dataset.h5" "${shards[@]}"
