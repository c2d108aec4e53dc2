#!/usr/bin/env bash
# Chooses the arrival locator's picking settings (arrival.highpass_hz, arrival.peak_fraction) on a
# validation set only: 300 randomized ts4 strikes (configs/ts4.yaml + configs/randomized.yaml,
# sample indices from 50000, disjoint from every training and test set of
# scripts/transfer_benchmark.sh and scripts/transfer_ablation.sh). Prints the MED of every pair
# and the best (docs/baselines.md quotes its last run, at ca7d14f).
# Usage: scripts/arrival_sweep.sh [OUTDIR=runs/arrival_sweep] [COUNT=300] [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/arrival_sweep}
COUNT=${2:-300}
THREADS=${3:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
if [ ! -f "$OUT/val_rand.h5" ]; then
  "$BIN" --config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0 \
    --config "$ROOT/configs/randomized.yaml" --threads "$THREADS" -q generate --count "$COUNT" \
    --first-index 50000 --out "$OUT/val_rand.h5"
fi
echo "| highpass (Hz) | peak fraction | MED (cm) | height (cm) | angle (deg) |" > "$OUT/table.md"
echo "|---|---|---|---|---|" >> "$OUT/table.md"
for hp in 1000 2000 4000 8000; do
  for pf in 0.05 0.1 0.2 0.4; do
    "$BIN" --threads "$THREADS" -q --set arrival.highpass_hz=$hp --set arrival.peak_fraction=$pf \
      baseline --method arrival --data "$OUT/val_rand.h5" --json > "$OUT/hp${hp}_pf${pf}.json"
    /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print('| $hp | $pf | %.2f | %.2f | %.1f |' % (d['med_cm'], d['height_err_cm'], d['angle_err_deg']))" \
      "$OUT/hp${hp}_pf${pf}.json" >> "$OUT/table.md"
  done
done
cat "$OUT/table.md"
sort -t'|' -k4 -g <(tail -n +3 "$OUT/table.md") | head -1 | sed 's/^/best: /'
