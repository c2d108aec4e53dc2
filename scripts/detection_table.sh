#!/usr/bin/env bash
# The strike-detection table of docs/robustness.md ("No strike"): dsp::CheckStrike's detection
# rate over peak-to-noise for hard and soft strikers, and its false alarms on background-only
# records (white floor, hum, arm motion, both). Builds nothing: runs build/bin/detection_bench
# (cmake --build build --target detection_bench), which solves (or reads from the mode cache) the
# default tube's modes.
# Usage: scripts/detection_table.sh [OUT=runs/detection/table.md] [RECORDS=200] [STRIKES=20] [SEED=1]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/detection/table.md}
RECORDS=${2:-200}
STRIKES=${3:-20}
SEED=${4:-1}
BIN=${SONICBOOM_BENCH_BIN:-$ROOT/build/bin/detection_bench}
[ -x "$BIN" ] || { echo "detection_table.sh: $BIN is not built (cmake --build build --target detection_bench)" >&2; exit 1; }
mkdir -p "$(dirname "$OUT")"
"$BIN" --records "$RECORDS" --strikes "$STRIKES" --seed "$SEED" | tee "$OUT.partial"
mv "$OUT.partial" "$OUT"
