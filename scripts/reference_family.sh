#!/usr/bin/env bash
# The other-theory family (docs/reference_model.md): TEST strikes of ts4 on the default structure
# (stationary, every grid point off; sample indices from 300000 under seed 1, so no training set
# of transfer_benchmark.sh or transfer_ablation.sh holds them), rendered twice: by our shell
# model (`generate`, the `nominal` family of transfer_benchmark.sh under another index range) and
# again by the reference solid, a 3-D elastic solid with its own contact, damping and sensor chain
# drawn per strike from its own ranges (`rerender`). A third family renders the same strikes by a
# third theory, the closed-form rung: Flügge's modes of an ideal simply supported tube (no seam,
# holes or bolts) under a prescribed Hertz pulse, its preamp gain 12 dB down (chosen before any
# model was scored, so that its median peak, 16 k counts, sits near the shell family's 18.5 k
# instead of clipping 22 strikes in 30). A model trained with randomize.reference_fraction > 0
# has seen the solid; for it only the closed-form family is out of theory. Nothing is trained or
# chosen here: each RUN given is evaluated once on each family, beside the training-free arrival
# locator and a constant.
#
# Usage: scripts/reference_family.sh OUT [TEST=300] [BAND=15000] [RUN ...]
# Writes OUT/shell.h5, OUT/reference.h5, OUT/closed.h5, OUT/<name>_<family>.json and
# OUT/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: reference_family.sh OUT [TEST] [BAND] [RUN ...]}
TEST=${2:-300}
BAND=${3:-15000}
shift $(( $# < 3 ? $# : 3 ))
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
TS4=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0)

if [ ! -f "$OUT/shell.h5" ]; then
  "$BIN" "${TS4[@]}" --threads "$THREADS" -q generate --count "$TEST" --first-index 300000 \
    --out "$OUT/shell.h5" --json > "$OUT/shell.generate.json"
fi
if [ ! -f "$OUT/closed.h5" ]; then
  "$BIN" "${TS4[@]}" --set acoustics.model=modal-closed-form \
    --set 'daq.channel_gain_db=[-12,-12,-12,-12,-12,-12]' --threads "$THREADS" -q generate \
    --count "$TEST" --first-index 300000 --out "$OUT/closed.h5" --json > "$OUT/closed.generate.json"
fi
# the constant predictor's labels: other strikes of the same scene
if [ ! -f "$OUT/constant_train.h5" ]; then
  "$BIN" "${TS4[@]}" --threads "$THREADS" -q generate --count "$TEST" --first-index 310000 \
    --out "$OUT/constant_train.h5" --json > /dev/null
fi
if [ ! -f "$OUT/reference.h5" ]; then
  "$BIN" --threads "$THREADS" -q rerender --in "$OUT/shell.h5" --out "$OUT/reference.h5" \
    --max-frequency "$BAND" --json > "$OUT/reference.rerender.json"
fi

for family in shell reference closed; do
  [ -f "$OUT/arrival_$family.json" ] ||
    "$BIN" --threads "$THREADS" -q baseline --method arrival --data "$OUT/$family.h5" \
      --json > "$OUT/arrival_$family.json"
  [ -f "$OUT/constant_$family.json" ] ||
    "$BIN" --threads "$THREADS" -q baseline --method constant --train "$OUT/constant_train.h5" \
      --data "$OUT/$family.h5" --json > "$OUT/constant_$family.json"
  for run in "$@"; do
    name=$(basename "$run")
    [ "$name" = model ] && name=$(basename "$(dirname "$run")")  # the demo's RUN/model
    [ -f "$OUT/${name}_$family.json" ] ||
      "$BIN" --threads "$THREADS" -q eval --model "$run" --data "$OUT/$family.h5" \
        --json > "$OUT/${name}_$family.json"
  done
done

/usr/bin/python3 - "$OUT" <<'PY'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = {}
for f in sorted(out.glob("*_shell.json")) + sorted(out.glob("*_reference.json")) + sorted(out.glob("*_closed.json")):
    if f.name.endswith((".generate.json", ".rerender.json")):
        continue
    name, family = f.stem.rsplit("_", 1)
    m = json.loads(f.read_text())
    m = m.get("metrics", m)
    rows.setdefault(name, {})[family] = m
def cell(m, key, scale=1.0, fmt="{:.2f}"):
    v = m.get(key)
    return fmt.format(v * scale) if isinstance(v, (int, float)) else "–"
lines = ["| model | shell: MED (cm) | shell: angle (°) | reference: MED (cm) | reference: height (cm) | reference: angle (°) | reference: 90 % z coverage | closed form: MED (cm) | closed form: angle (°) | closed form: 90 % z coverage |",
         "|---|---|---|---|---|---|---|---|---|---|"]
for name, fam in rows.items():
    s, r, c = fam.get("shell", {}), fam.get("reference", {}), fam.get("closed", {})
    lines.append(f"| {name} | {cell(s, 'med_cm')} | {cell(s, 'angle_err_deg', fmt='{:.1f}')} | "
                 f"{cell(r, 'med_cm')} | {cell(r, 'height_err_cm')} | "
                 f"{cell(r, 'angle_err_deg', fmt='{:.1f}')} | {cell(r, 'z_coverage_90')} | "
                 f"{cell(c, 'med_cm')} | {cell(c, 'angle_err_deg', fmt='{:.1f}')} | "
                 f"{cell(c, 'z_coverage_90')} |")
(out / "table.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
PY
