#!/usr/bin/env bash
# Arrival picks as inputs (issue 32 item 2; docs/reference_model.md): one network of
# configs/transfer.yaml (without the turned rings and answers it ships with since, so that the
# rows compare with the two-theory ensemble's member 0) trained on TRAIN_H5 with
# model.arrival_picks = token and = only, each scored on the two validation families of
# scripts/reference_fewshot.sh beside member 0 of BASE_RUN. No test family is scored.
#
# Usage: scripts/arrival_picks_study.sh OUT TRAIN_H5 VAL_CLOSED VAL_SOLID BASE_RUN
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: arrival_picks_study.sh OUT TRAIN_H5 VAL_CLOSED VAL_SOLID BASE_RUN}
TRAIN=${2:?training set}
VAL_CLOSED=${3:?closed-form validation family}
VAL_SOLID=${4:?reference-solid validation family}
BASE=${5:?the ensemble whose member 0 is the waveform row}
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
score() {  # name model
  for pair in "closed:$VAL_CLOSED" "reference:$VAL_SOLID"; do
    f=$OUT/val_${pair%%:*}_$1.json
    [ -f "$f" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "${pair#*:}" --json > "$f"
  done
}
for picks in token only; do
  [ -f "$OUT/$picks/model.json" ] || "$BIN" --config "$ROOT/configs/transfer.yaml" --seed 1 \
    --threads "$THREADS" --set train.ensemble_members=1 --set train.rotate_rings=false \
    --set model.turn_average=false --set model.arrival_picks=$picks train --data "$TRAIN" \
    --out "$OUT/$picks" --json > "$OUT/train_$picks.json"
  score "$picks" "$OUT/$picks"
done
score waveform "$BASE/member0"
/usr/bin/python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
def cell(f):
    e = json.load(open(f))
    return f"{e['med_cm']:.2f} / {e['height_err_cm']:.2f} / {e['angle_err_deg']:.1f}"
lines = ["| one network | closed form: MED (cm) / height (cm) / angle (°) | reference solid: same |",
         "|---|---|---|"]
for name in ["waveform", "token", "only"]:
    lines.append(f"| {name} | {cell(f'{out}/val_closed_{name}.json')} | "
                 f"{cell(f'{out}/val_reference_{name}.json')} |")
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
