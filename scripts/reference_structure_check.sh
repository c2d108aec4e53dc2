#!/usr/bin/env bash
# Which part of the configured tube makes the reference solid's modes converge slowly: the coarse
# convergence check (`sonicboom reference`, 0-3 kHz, meshes of 32, 23 and 18 mm) of the configured
# tube, then with its holes, its mounts, both taken out, and of the ideal tube. Each report has
# the Richardson table by rank and by shape; table.md collects the by-shape rows
# (docs/reference_model.md, "Rank or shape, and where the slow convergence comes from").
# About 5 min on 2 cores.
# Usage: scripts/reference_structure_check.sh [OUTDIR=runs/reference_structure] [THREADS=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/reference_structure}
THREADS=${2:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
COMMON=(reference --max-frequency 3000 --element-m 0.03 --levels 3 --ratio 1.3 --cache-dir "$OUT/levels")
NOHOLES=(--set 'shell.hole_z_m=[]' --set 'shell.hole_theta_deg=[]')
NOMOUNTS=(--set shell.flange_mount_stiffness_n_m2=0 --set shell.tool_mount_stiffness_n_m2=0)
run() {  # name, then the global options that make the variant
  local name=$1
  shift
  "$BIN" --threads "$THREADS" -q "$@" "${COMMON[@]}" --out "$OUT/$name.md" --json \
    > "$OUT/$name.json"
}
run configured
run no_holes "${NOHOLES[@]}"
run no_mounts "${NOMOUNTS[@]}"
run seam_and_bolts_only "${NOHOLES[@]}" "${NOMOUNTS[@]}"
run ideal --set shell.ideal=true
/usr/bin/python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
rows = ["| tube | modes followed | 90th percentile (%) | max (%) | over 0.3 % | median order | non-monotone |",
        "|---|---|---|---|---|---|---|"]
for name in ["configured", "no_holes", "no_mounts", "seam_and_bolts_only", "ideal"]:
    j = json.load(open(f"{out}/{name}.json"))
    b = j["bands_by_shape"][0]
    rows.append(f"| {name.replace('_', ' ')} | {j['followed_by_shape']} of {j['finest_modes']} | "
                f"{100 * b['p90_relative_error']:.2f} | {100 * b['max_relative_error']:.2f} | "
                f"{b['over_0_3_percent']} | {b['median_order']:.1f} | {b['non_monotone']} |")
open(f"{out}/table.md", "w").write("\n".join(rows) + "\n")
print("\n".join(rows))
PY
