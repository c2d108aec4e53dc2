#!/usr/bin/env bash
# Generates every scenario of configs/ (ts1..ts4, materials) with N strikes each and prints one
# summary line per scenario: strikes/s, valid count, invalid reasons, contact kinds and the
# approach-speed range, from `sonicboom generate --json` and `sonicboom inspect --json`.
# Usage: scripts/scenario_summary.sh [N=200] [OUTDIR=runs/scenarios] [THREADS=2]
set -euo pipefail
N=${1:-200}
OUT=${2:-runs/scenarios}
THREADS=${3:-2}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
for scenario in ts1 ts2 ts3 ts4 materials; do
  gen=$("$BIN" generate --config "$ROOT/configs/$scenario.yaml" --count "$N" --threads "$THREADS" \
        --out "$OUT/$scenario.h5" -q --json)
  "$BIN" inspect "$OUT/$scenario.h5" --json | /usr/bin/python3 -c '
import json, sys
name, gen = sys.argv[1], json.loads(sys.argv[2])
s = json.load(sys.stdin)
c = s["contacts"]
speed = s.get("normal_speed_m_s") or {"min": float("nan"), "max": float("nan")}
print("%s: %.1f strikes/s, valid %d/%d, clipped %d, approach speed %.3f-%.3f m/s, kinds %s, objects %s"
      % (name, gen["strikes_per_s"], s["valid"], s["num_samples"], s["clipped"], speed["min"],
         speed["max"], c["kinds"], c["objects"]))
for reason, count in sorted(s["invalid_reasons"].items(), key=lambda kv: -kv[1]):
    print("    invalid %d x %s" % (count, reason))
' "$scenario" "$gen"
done
