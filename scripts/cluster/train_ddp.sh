#!/usr/bin/env bash
# Data-parallel training on this machine: NP processes of THREADS threads each, one model
# (learning::Train with c10d's Gloo backend; docs/cluster.md). Extra arguments go to
# `sonicboom` before the subcommand (--config, --set).
#
#   THREADS=1 scripts/cluster/train_ddp.sh NP DATA.h5 RUN [--config C.yaml ...]
#   TRAIN_ARGS="--resume" ...: options of `train` itself (--resume, --force)
set -euo pipefail
NP=${1:?usage: scripts/cluster/train_ddp.sh NP DATA.h5 RUN [sonicboom options]}
DATA=${2:?dataset}
RUN=${3:?run directory}
shift 3
BIN=${SONICBOOM_BIN:-build/bin/sonicboom}
THREADS=${THREADS:-1}
export MASTER_ADDR=${MASTER_ADDR:-127.0.0.1} MASTER_PORT=${MASTER_PORT:-29500} WORLD_SIZE=$NP
pids=()
for ((r = NP - 1; r >= 0; --r)); do
  RANK=$r "$BIN" --threads "$THREADS" "$@" train --data "$DATA" --out "$RUN" ${TRAIN_ARGS:-} &
  pids+=($!)
done
status=0
for p in "${pids[@]}"; do wait "$p" || status=$?; done
exit $status
