#!/usr/bin/env bash
# The reference solid's convergence study to 20 kHz (issue 31's band): three meshes of 13.5,
# 11.25 and 9.4 mm (nominal), each level solved by its own `reference_levels` process into a
# cache directory (a killed study resumes at the first level not yet there), then the report of
# `sonicboom reference` over the cached levels: Richardson tables by rank and by shape, first
# arrivals at the discs. About 70 min on 2 cores here (model version 3: 905 + 1082 + 2148 s),
# over 4 GB resident at the finest level
# (docs/reference_model.md, "The configured tube to 20 kHz").
# Usage: scripts/reference_20k.sh [OUTDIR=runs/reference_20k] [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/reference_20k}
THREADS=${2:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin}
mkdir -p "$OUT"
STUDY=(--max-frequency 20000 --element-m 0.0135 --levels 3 --ratio 1.2 --cache-dir "$OUT/cache")
for level in 0 1 2; do
  start=$(date +%s)
  "$BIN/reference_levels" "${STUDY[@]}" --only-level "$level" > "$OUT/level$level.log" 2>&1
  echo "level $level: $(($(date +%s) - start)) s (read from the cache if solved before)"
done
"$BIN/sonicboom" --threads "$THREADS" -q reference "${STUDY[@]}" --out "$OUT/report.md"
"$BIN/sonicboom" --threads "$THREADS" -q --json reference "${STUDY[@]}" > "$OUT/report.json"
echo "report: $OUT/report.md, $OUT/report.json"
