#!/usr/bin/env bash
# Training data from two theories (issue 32, docs/reference_model.md): the transfer recipe's
# training set (3000 ts4 strikes under configs/randomized.yaml, seed 1, indices 0-2999, the shell
# with every mode to 20 kHz as runs/thick) layered with configs/two_theories.yaml, so that a share
# of its strikes is rendered by the reference solid instead (randomize.reference_fraction: the
# layer's 0.3, or FRACTION), and the transfer ensemble (configs/transfer.yaml) trained on it. Evaluate it with scripts/reference_family.sh, where only the closed-form family
# is out of theory for it.
#
# Usage: scripts/multitheory_study.sh OUT [FRACTION=the layer's] [SEED=1]
# Writes OUT/train.h5 (+ .generate.json, .wall_s) and OUT/transfer (the run, + train.json).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: multitheory_study.sh OUT [FRACTION] [SEED]}
FRACTION=${2:-}
SEED=${3:-1}
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
CFG=(--config "$ROOT/configs/ts4.yaml" --config "$ROOT/configs/randomized.yaml"
     --config "$ROOT/configs/two_theories.yaml" --set scene.stationary.z_grid_m=0
     --set acoustics.max_frequency_hz=20000 --seed "$SEED")
[ -n "$FRACTION" ] && CFG+=(--set randomize.reference_fraction="$FRACTION")

if [ ! -f "$OUT/train.h5" ]; then
  start=$(date +%s)
  "$BIN" "${CFG[@]}" --threads "$THREADS" -q generate --count 3000 --out "$OUT/train.h5" \
    --json > "$OUT/train.generate.json"
  echo $(( $(date +%s) - start )) > "$OUT/train.wall_s"
fi
# the recipe as it was measured (before configs/transfer.yaml turned the rings)
if [ ! -d "$OUT/transfer" ]; then
  "$BIN" --config "$ROOT/configs/transfer.yaml" --seed "$SEED" --threads "$THREADS" \
    --set train.rotate_rings=false --set model.turn_average=false train \
    --data "$OUT/train.h5" --out "$OUT/transfer" --json > "$OUT/train.json"
fi
