#!/usr/bin/env bash
# Times `sonicboom import` of N published-layout trials (docs/captures.md): generates N
# stationary ts4 strikes, exports them with `export --layout trial`, then imports them back
# and checks that every good capture came through.
#   scripts/import_bench.sh OUT [N=1000] [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
OUT=${1:?usage: scripts/import_bench.sh OUT [N] [THREADS]}
N=${2:-1000}
THREADS=${3:-2}
mkdir -p "$OUT"
CFG=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0)

# the trials: simulated strikes in the published layout
[ -f "$OUT/sim.h5" ] || "$BIN" "${CFG[@]}" --threads "$THREADS" -q generate --count "$N" --out "$OUT/sim.h5"
[ -d "$OUT/trials" ] || "$BIN" -q export --layout trial --in "$OUT/sim.h5" --out "$OUT/trials"

# the timed import (clipped strikes are bad captures: --skip-bad lists and skips them)
rm -f "$OUT/imported.h5" "$OUT/imported.h5.config.yaml"
start=$(date +%s.%N)
"$BIN" "${CFG[@]}" --threads "$THREADS" -q import --layout trial --in "$OUT/trials" \
  --out "$OUT/imported.h5" --skip-bad --json > "$OUT/import.json"
end=$(date +%s.%N)
TRIALS=$(find "$OUT/trials" -mindepth 1 -maxdepth 1 -name 'trial*' | wc -l)  # valid strikes
/usr/bin/python3 - "$OUT" "$TRIALS" "$start" "$end" <<'PY'
import json, sys
out, n, start, end = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
r = json.load(open(out + "/import.json"))
secs = end - start
print(f"imported {r['imported']} of {n} trials ({len(r['bad'])} bad: clipped or otherwise) "
      f"in {secs:.1f} s ({1000 * secs / n:.1f} ms per trial)")
PY
