#!/usr/bin/env bash
# The discs' mirror symmetry in training and in the answers (issue 32; docs/reference_model.md,
# "Mirrored answers"): configs/transfer.yaml as shipped (turned rings, turn-averaged answers) and
# the same with train.mirror_rings and model.mirror_average, each trained with seeds 1 and 2 on
# one shell-only training set, scored on the two validation families of another theory (the
# closed form's and the reference solid's 200 strikes from sample index 340000) as they answer,
# the shipped runs also with `eval --mirror-average`. The choice is made there; the test families
# (TEST_DIR: shell.h5, solid.h5 and closed.h5, one set of strikes rendered three ways) are scored
# once per run, as each answers.
#
# Usage: scripts/mirror_study.sh OUT SHELL_TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR
# Writes OUT/<run> (shipped, shipped_s2, mirror, mirror_s2), OUT/val_*.json, OUT/test_*.json and
# OUT/table.md. About 15 min of training a run on 2 cores.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: mirror_study.sh OUT SHELL_TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR}
TRAIN=${2:?shell-only training set}
VAL_CLOSED=${3:?closed-form validation family}
VAL_SOLID=${4:?reference-solid validation family}
TEST_DIR=${5:?test families}
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
MIRROR=(--set train.mirror_rings=true --set model.mirror_average=true)

train() {  # name seed [flags]
  [ -f "$OUT/$1/ensemble.json" ] || "$BIN" --config "$ROOT/configs/transfer.yaml" --seed "$2" \
    --threads "$THREADS" -q "${@:3}" train --data "$TRAIN" --out "$OUT/$1" --json \
    > "$OUT/train_$1.json"
}
score() {  # json model data [flags]
  [ -f "$1" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "$3" "${@:4}" --json > "$1"
}
train shipped 1
train mirror 1 "${MIRROR[@]}"
train shipped_s2 2
train mirror_s2 2 "${MIRROR[@]}"
runs="shipped shipped_s2 mirror mirror_s2"
for run in $runs; do
  for pair in "closed:$VAL_CLOSED" "solid:$VAL_SOLID"; do
    score "$OUT/val_${pair%%:*}_${run}_own.json" "$OUT/$run" "${pair#*:}"
    case $run in shipped*)
      score "$OUT/val_${pair%%:*}_${run}_mirror.json" "$OUT/$run" "${pair#*:}" --mirror-average ;;
    esac
  done
done
[ "${STAGE:-}" = validation ] && exit 0
for run in $runs; do
  for family in shell solid closed; do
    score "$OUT/test_${family}_${run}_own.json" "$OUT/$run" "$TEST_DIR/$family.h5"
  done
done

PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" $runs <<'PY'
import os, sys
from transfer_tables import EVAL_HEAD as head, eval_cell as cell
out, runs = sys.argv[1], sys.argv[2:]
lines = ["Validation families (choose here):", "",
         f"| run | answers | closed form: {head} | reference solid: {head} |", "|---|---|---|---|"]
for n in runs:
    modes = [("own", "as configured")]
    if n.startswith("shipped"):
        modes.append(("mirror", "--mirror-average"))
    for mode, label in modes:
        lines.append(f"| {n} | {label} | {cell(f'{out}/val_closed_{n}_{mode}.json')} | "
                     f"{cell(f'{out}/val_solid_{n}_{mode}.json')} |")
lines += ["", "Test families (each run scored once, as configured):", "",
          f"| run | shell: {head} | reference solid: {head} | closed form: {head} |",
          "|---|---|---|---|"]
for n in runs:
    lines.append(f"| {n} | {cell(f'{out}/test_shell_{n}_own.json')} | "
                 f"{cell(f'{out}/test_solid_{n}_own.json')} | "
                 f"{cell(f'{out}/test_closed_{n}_own.json')} |")
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
