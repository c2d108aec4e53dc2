#!/usr/bin/env bash
# The ablation table: generates a training and a held-out set of the ts1 scenario, then runs
# `sonicboom ablate` over configs/ablations/ (modality sets and preprocessing switches) with the
# small model of the demo (width 64, 2 blocks, 4 heads, compact encoder).
# Usage: scripts/ablation_study.sh [OUTDIR=runs/ablations] [TRAIN=600] [TEST=200] [EPOCHS=12] [THREADS=2]
# Output: OUTDIR/table.md and OUTDIR/results.json (rerunning reuses finished datasets and runs).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/ablations}
TRAIN=${2:-600}
TEST=${3:-200}
EPOCHS=${4:-12}
THREADS=${5:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
[ -f "$OUT/train.h5" ] || "$BIN" --config "$ROOT/configs/ts1.yaml" --threads "$THREADS" -q \
  generate --count "$TRAIN" --out "$OUT/train.h5"
[ -f "$OUT/test.h5" ] || "$BIN" --config "$ROOT/configs/ts1.yaml" --threads "$THREADS" -q \
  generate --count "$TEST" --first-index 100000 --out "$OUT/test.h5"
"$BIN" --config "$ROOT/configs/ts1.yaml" --threads "$THREADS" \
  --set model.width=64 --set model.blocks=2 --set model.heads=4 --set model.dropout=0 \
  --set train.epochs="$EPOCHS" --set train.batch_size=32 --set train.learning_rate=0.001 \
  --set train.lr_step_epochs=$(( (EPOCHS + 2) / 3 )) \
  ablate --data "$OUT/train.h5" --test "$OUT/test.h5" --out "$OUT/runs" \
  --configs "$ROOT/configs/ablations" -q
cp "$OUT/runs/table.md" "$OUT/table.md"
cp "$OUT/runs/results.json" "$OUT/results.json"
cat "$OUT/table.md"
