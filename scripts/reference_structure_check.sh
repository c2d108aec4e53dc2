#!/usr/bin/env bash
# Which part of the configured tube makes the reference solid's modes converge slowly: the coarse
# convergence check (`sonicboom reference`, 0-3 kHz, meshes of 32, 23 and 18 mm) of the configured
# tube, then with its holes, its mounts, both taken out, and of the ideal tube. Each report has
# the Richardson table by rank and by shape; table.md collects the by-shape rows
# (docs/reference_model.md, "Rank or shape, and where the slow convergence comes from").
# About 5 min on 2 cores. The band, the coarsest element and the ratio can be given too: the fine
# check of docs/reference_model.md is `... OUT 2 3000 0.018 1.2` (meshes of 17, 15 and 12 mm,
# about 25 min). table.md also gives each tube's median step between the meshes (a converging
# sequence's second step is the smaller). TUBES picks some of the five (space-separated names).
# Usage: scripts/reference_structure_check.sh [OUTDIR=runs/reference_structure] [THREADS=2]
#        [MAX_FREQUENCY_HZ=3000] [ELEMENT_M=0.03] [RATIO=1.3]
#        [TUBES="configured no_holes no_mounts seam_and_bolts_only ideal"]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/reference_structure}
THREADS=${2:-2}
MAX_HZ=${3:-3000}
ELEMENT_M=${4:-0.03}
RATIO=${5:-1.3}
TUBES=${6:-configured no_holes no_mounts seam_and_bolts_only ideal}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
COMMON=(reference --max-frequency "$MAX_HZ" --element-m "$ELEMENT_M" --levels 3 --ratio "$RATIO"
  --cache-dir "$OUT/levels")
NOHOLES=(--set 'shell.hole_z_m=[]' --set 'shell.hole_theta_deg=[]')
NOMOUNTS=(--set shell.flange_mount_stiffness_n_m2=0 --set shell.tool_mount_stiffness_n_m2=0)
run() {  # name, then the global options that make the variant
  local name=$1
  shift
  [[ " $TUBES " == *" $name "* ]] || return 0
  "$BIN" --threads "$THREADS" -q "$@" "${COMMON[@]}" --out "$OUT/$name.md" --json \
    > "$OUT/$name.json"
}
run configured
run no_holes "${NOHOLES[@]}"
run no_mounts "${NOMOUNTS[@]}"
run seam_and_bolts_only "${NOHOLES[@]}" "${NOMOUNTS[@]}"
run ideal --set shell.ideal=true
/usr/bin/python3 - "$OUT" "$TUBES" <<'PY'
import json, sys
out, tubes = sys.argv[1], sys.argv[2].split()
rows = ["| tube | modes followed | 90th percentile (%) | max (%) | over 0.3 % | median order | non-monotone | median steps (%) | step ratio |",
        "|---|---|---|---|---|---|---|---|---|"]
for name in tubes:
    j = json.load(open(f"{out}/{name}.json"))
    b = j["bands_by_shape"][0]
    # each mode's change from the coarsest to the middle mesh and from the middle to the finest
    f = [m["f_hz"] for m in j["modes"]]
    first = sorted((x[1] - x[0]) / x[2] for x in f)[len(f) // 2]
    second = sorted((x[2] - x[1]) / x[2] for x in f)[len(f) // 2]
    rows.append(f"| {name.replace('_', ' ')} | {j['followed_by_shape']} of {j['finest_modes']} | "
                f"{100 * b['p90_relative_error']:.2f} | {100 * b['max_relative_error']:.2f} | "
                f"{b['over_0_3_percent']} | {b['median_order']:.1f} | {b['non_monotone']} | "
                f"{100 * first:.3f}, {100 * second:.3f} | {second / first:.2f} |")
open(f"{out}/table.md", "w").write("\n".join(rows) + "\n")
print("\n".join(rows))
PY
