#!/usr/bin/env bash
# What the self-similar family of scripts/reference_20k.sh leaves out: its intervals under 10 mm
# between forced edges (the end rims, the holes, the bolt patches) stay one element on every
# level, so its Richardson limit is that of a mesh whose short intervals are never refined. This
# check solves, in a lower band, the same family (40.5 mm cut into 3, 4 and 5) and a family that
# refines every interval (40.5 mm cut into 1, 2 and 3, --fixed-interval-m 0; its finest level
# cuts the short intervals into 3) and compares their extrapolated limits mode by mode (by rank):
# the difference is the floor the short intervals leave. Writes OUT/fixed.json, OUT/all.json and
# OUT/floor.md (docs/reference_model.md, "The configured tube to 20 kHz"). About 25 min on 2
# cores at 3 kHz.
# Usage: scripts/reference_fixed_floor.sh [OUTDIR=runs/reference_floor] [MAX_FREQUENCY_HZ=3000]
#        [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/reference_floor}
MAX_HZ=${2:-3000}
THREADS=${3:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
COMMON=(reference --max-frequency "$MAX_HZ" --element-m 0.0405 --cache-dir "$OUT/levels" --json)
"$BIN" --threads "$THREADS" -q "${COMMON[@]}" --subdivisions 3,4,5 > "$OUT/fixed.json"
"$BIN" --threads "$THREADS" -q "${COMMON[@]}" --subdivisions 1,2,3 --fixed-interval-m 0 \
  > "$OUT/all.json"
/usr/bin/python3 - "$OUT" "$MAX_HZ" <<'PY'
import json, sys

out, max_hz = sys.argv[1], float(sys.argv[2])
fixed = json.load(open(f"{out}/fixed.json"))
every = json.load(open(f"{out}/all.json"))


def quantile(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


n = min(len(fixed["modes"]), len(every["modes"]))
floor, err_fixed, err_all = [], [], []
for a, b in zip(fixed["modes"][:n], every["modes"][:n]):
    floor.append(100.0 * abs(a["limit_hz"] - b["limit_hz"]) / b["limit_hz"])
    err_fixed.append(100.0 * a["relative_error"])
    err_all.append(100.0 * b["relative_error"])
rows = [
    ("limit of the 3,4,5 family (short intervals one element) against the 1,2,3 family "
     "(every interval refined)", floor),
    ("Richardson error estimate of the 3,4,5 family's finest mesh", err_fixed),
    ("Richardson error estimate of the 1,2,3 family's finest mesh", err_all),
]
levels = lambda j: " / ".join(f"{1e3 * l['h_m']:.1f} mm ({l['dofs']} DOFs)" for l in j["levels"])
md = [
    f"Made by `scripts/reference_fixed_floor.sh {out} {max_hz:g}`: {n} modes to {max_hz:g} Hz, "
    "matched by rank.\n",
    f"- 3,4,5 family, intervals under 10 mm one element: {levels(fixed)}",
    f"- 1,2,3 family, every interval refined: {levels(every)}\n",
    "| relative difference (%) | median | 90th percentile | max |",
    "|---|---|---|---|",
]
for name, v in rows:
    md.append(f"| {name} | {quantile(v, 0.5):.4f} | {quantile(v, 0.9):.4f} | {max(v):.4f} |")
open(f"{out}/floor.md", "w").write("\n".join(md) + "\n")
print("\n".join(md))
PY
