#!/usr/bin/env bash
# The reference solid's convergence study to 20 kHz (issue 31's band): a self-similar family of
# three meshes, every interval between forced edges (seams, bolt patches, holes) cut into 3, 4
# and 5 times the elements of 40.5 mm (nominal 13.5, 10.1 and 8.1 mm; intervals under 10 mm stay
# one element), so that every refined element shrinks by the same ratio, as the Richardson fit
# assumes. Each level is solved by its own `reference_levels` process into a cache directory (a
# killed study resumes at the first level not yet there), then the report of `sonicboom
# reference` over the cached levels: Richardson tables by rank and by shape, first arrivals at
# the discs. About 100 min on 2 cores here (1107 + 1853 + 2976 s), near 6 GB resident at the
# finest level (docs/reference_model.md, "The configured tube to 20 kHz").
# Usage: scripts/reference_20k.sh [OUTDIR=runs/reference_20k] [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/reference_20k}
THREADS=${2:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin}
mkdir -p "$OUT"
STUDY=(--max-frequency 20000 --element-m 0.0405 --subdivisions 3,4,5 --cache-dir "$OUT/cache")
for level in 0 1 2; do
  start=$(date +%s)
  "$BIN/reference_levels" "${STUDY[@]}" --only-level "$level" > "$OUT/level$level.log" 2>&1
  echo "level $level: $(($(date +%s) - start)) s (read from the cache if solved before)"
done
"$BIN/sonicboom" --threads "$THREADS" -q reference "${STUDY[@]}" --out "$OUT/report.md"
"$BIN/sonicboom" --threads "$THREADS" -q --json reference "${STUDY[@]}" > "$OUT/report.json"
echo "report: $OUT/report.md, $OUT/report.json"
