#!/usr/bin/env bash
# Augmentations that break what one structure teaches (issue 32 item 2; docs/reference_model.md):
# the two-theory training set of scripts/multitheory_study.sh trained with configs/transfer.yaml
# and train.time_stretch = 0.15 (seeds 1 and 2) or train.rotate_rings = true (seed 1), each
# scored on the two validation families (the closed-form rung's and the reference solid's, 200
# strikes each from sample index 340000: VAL_CLOSED and VAL_SOLID, made by
# scripts/reference_fewshot.sh) beside the runs without them (BASE RUN ...). The choice is made on
# those; the test families (TEST_DIR: scripts/reference_family.sh's shell, reference and
# closed.h5) are scored once per run.
#
# Usage: scripts/theory_augment_study.sh OUT TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR [BASE_RUN ...]
# Writes OUT/<variant>/ (runs), OUT/val_<family>_<name>.json, OUT/test_<family>_<name>.json and
# OUT/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: theory_augment_study.sh OUT TRAIN_H5 VAL_CLOSED VAL_SOLID TEST_DIR [BASE_RUN ...]}
TRAIN=${2:?train set}
VAL_CLOSED=${3:?closed-form validation family}
VAL_SOLID=${4:?reference-solid validation family}
TEST_DIR=${5:?test families}
shift 5
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
mkdir -p "$OUT"

train() {  # name seed overrides...
  local name=$1 seed=$2
  shift 2
  # configs/transfer.yaml as it was measured here (before it turned the rings), then the variant
  [ -f "$OUT/$name/ensemble.json" ] || "$BIN" --config "$ROOT/configs/transfer.yaml" \
    --seed "$seed" --threads "$THREADS" --set train.rotate_rings=false \
    --set model.turn_average=false "$@" train --data "$TRAIN" --out "$OUT/$name" --json \
    > "$OUT/train_$name.json"
}
train stretch 1 --set train.time_stretch=0.15
train stretch_seed2 2 --set train.time_stretch=0.15
train rotate 1 --set train.rotate_rings=true

runs=("$@" "$OUT/stretch" "$OUT/stretch_seed2" "$OUT/rotate")
for run in "${runs[@]}"; do
  name=$(basename "$run")
  for pair in "closed:$VAL_CLOSED" "reference:$VAL_SOLID"; do
    f=$OUT/val_${pair%%:*}_$name.json
    [ -f "$f" ] || "$BIN" --threads "$THREADS" -q eval --model "$run" --data "${pair#*:}" \
      --json > "$f"
  done
  for family in shell reference closed; do
    f=$OUT/test_${family}_$name.json
    [ -f "$f" ] || "$BIN" --threads "$THREADS" -q eval --model "$run" \
      --data "$TEST_DIR/$family.h5" --json > "$f"
  done
done

PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" "${runs[@]}" <<'PY'
import os, sys
from transfer_tables import EVAL_HEAD as head, eval_cell
out, runs = sys.argv[1], [os.path.basename(r) for r in sys.argv[2:]]
def row(kind, family, name):
    return eval_cell(f"{out}/{kind}_{family}_{name}.json")
lines = ["Validation families (choose here):", "",
         f"| run | closed form: {head} | reference solid: {head} |", "|---|---|---|"]
lines += [f"| {n} | {row('val', 'closed', n)} | {row('val', 'reference', n)} |" for n in runs]
lines += ["", "Test families (each run scored once):", "",
          f"| run | shell: {head} | reference solid: {head} | closed form: {head} |",
          "|---|---|---|---|"]
lines += [f"| {n} | {row('test', 'shell', n)} | {row('test', 'reference', n)} | "
          f"{row('test', 'closed', n)} |" for n in runs]
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
