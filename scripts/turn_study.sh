#!/usr/bin/env bash
# Turned rings in training and turn-averaged answers (issue 32; docs/reference_model.md): the
# shell-only training set trained with configs/transfer.yaml (train.rotate_rings and
# model.turn_average on, as shipped), and each run given (trained before those keys, or with
# rotate_rings alone) scored on the two validation families of scripts/reference_fewshot.sh
# (the closed form's and the reference solid's 200 strikes from sample index 340000) as it
# answers and with `eval --turn-average`. The choice is made there; the test families (TEST_DIR:
# scripts/reference_family.sh's shell, reference and closed.h5) are scored once per run, turn-
# averaged.
#
# Usage: scripts/turn_study.sh OUT SHELL_TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR [RUN ...]
# Writes OUT/shell_rotate (the run), OUT/val_*.json, OUT/test_*.json and OUT/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: turn_study.sh OUT SHELL_TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR [RUN ...]}
TRAIN=${2:?shell-only training set}
VAL_CLOSED=${3:?closed-form validation family}
VAL_SOLID=${4:?reference-solid validation family}
TEST_DIR=${5:?test families}
shift 5
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
[ -f "$OUT/shell_rotate/ensemble.json" ] || "$BIN" --config "$ROOT/configs/transfer.yaml" \
  --seed 1 --threads "$THREADS" train --data "$TRAIN" --out "$OUT/shell_rotate" --json \
  > "$OUT/train_shell_rotate.json"

score() {  # json model data [flags]
  [ -f "$1" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "$3" "${@:4}" --json > "$1"
}
runs=("$@" "$OUT/shell_rotate")
for run in "${runs[@]}"; do
  name=$(basename "$run")
  for pair in "closed:$VAL_CLOSED" "reference:$VAL_SOLID"; do
    score "$OUT/val_${pair%%:*}_${name}_plain.json" "$run" "${pair#*:}"
    score "$OUT/val_${pair%%:*}_${name}_turn.json" "$run" "${pair#*:}" --turn-average
  done
  for family in shell reference closed; do
    score "$OUT/test_${family}_${name}_turn.json" "$run" "$TEST_DIR/$family.h5" --turn-average
  done
done

PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" "${runs[@]}" <<'PY'
import os, sys
from transfer_tables import EVAL_HEAD as head, eval_cell as cell
out, runs = sys.argv[1], [os.path.basename(r) for r in sys.argv[2:]]
lines = ["Validation families (choose here):", "",
         f"| run | answers | closed form: {head} | reference solid: {head} |", "|---|---|---|---|"]
for n in runs:
    for mode, label in [("plain", "as trained"), ("turn", "turn-averaged")]:
        lines.append(f"| {n} | {label} | {cell(f'{out}/val_closed_{n}_{mode}.json')} | "
                     f"{cell(f'{out}/val_reference_{n}_{mode}.json')} |")
lines += ["", "Test families (each run scored once, turn-averaged):", "",
          f"| run | shell: {head} | reference solid: {head} | closed form: {head} |",
          "|---|---|---|---|"]
for n in runs:
    lines.append(f"| {n} | {cell(f'{out}/test_shell_{n}_turn.json')} | "
                 f"{cell(f'{out}/test_reference_{n}_turn.json')} | "
                 f"{cell(f'{out}/test_closed_{n}_turn.json')} |")
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
