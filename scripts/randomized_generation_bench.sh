#!/usr/bin/env bash
# Randomized generation at paper scale (a bench, not a test): COUNT stationary ts4 strikes under
# configs/randomized.yaml, with the structure pool first solved cold (an empty mode cache) and
# then read warm from it. Prints the wall time of the pool alone (a 1-strike run), of the whole
# run, and per strike, each cold and warm. docs/randomization.md quotes its output.
#
# Usage: scripts/randomized_generation_bench.sh [OUT=runs/generation_bench] [COUNT=18000]
#                                               [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/generation_bench}
COUNT=${2:-18000}
THREADS=${3:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
export SONICBOOM_CACHE_DIR="$OUT/cache"
CONFIG=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0
        --config "$ROOT/configs/randomized.yaml" --threads "$THREADS" -q)

timed() {  # label count: one generate run, prints "label count wall_s"
  local start end
  start=$(date +%s%N)
  "$BIN" "${CONFIG[@]}" generate --count "$2" --out "$OUT/$1.h5" --json > "$OUT/$1.json"
  end=$(date +%s%N)
  echo "$1 $2 $(( (end - start) / 1000000 ))e-3"
}

rm -rf "$SONICBOOM_CACHE_DIR"
cold=$(timed pool_cold 1)
warm=$(timed pool_warm 1)
full=$(timed strikes_warm "$COUNT")
rm -f "$OUT"/pool_*.h5
/usr/bin/python3 - "$cold" "$warm" "$full" "$THREADS" <<'EOF'
import sys
cold, warm, full = (float(a.split()[2]) for a in sys.argv[1:4])
count = int(sys.argv[3].split()[1])
per = (full - warm) / count
print("threads %s" % sys.argv[4])
print("structure pool, cold cache: %.1f s" % cold)
print("structure pool, warm cache: %.1f s" % warm)
print("%d strikes, warm cache: %.1f s (%.1f ms per strike after the pool)" % (count, full, per * 1e3))
print("%d strikes, cold cache: %.1f s" % (count, full - warm + cold))
EOF
