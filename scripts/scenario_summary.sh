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
gen = json.loads(sys.argv[2]); s = json.load(sys.stdin); c = s["contacts"]
speed = s.get("normal_speed_m_s") or {}
print(f"{sys.argv[1]}: {gen[\"strikes_per_s\"]:.1f} strikes/s, valid {s[\"valid\"]}/{s[\"num_samples\"]}, "
      f"clipped {s[\"clipped\"]}, speed {speed.get(\"min\", float(\"nan\")):.3f}-{speed.get(\"max\", float(\"nan\")):.3f} m/s, "
      f"kinds {c[\"kinds\"]}, objects {len(c[\"objects\"])}")
for reason, count in sorted(s["invalid_reasons"].items(), key=lambda kv: -kv[1]):
    print(f"    invalid {count} x {reason}")
' "$scenario" "$gen"
done
