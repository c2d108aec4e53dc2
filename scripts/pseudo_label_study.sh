#!/usr/bin/env bash
# Self-training on unlabelled strikes of another theory (issue 32 item 4; docs/reference_model.md,
# "Pseudo-labels"): `train --init-from RUN --pseudo-labels F` fine-tunes a pretrained run on the
# target's strikes, labelled by the run's own answers (its six-image average) to the fraction F
# of them it is surest of; no label of the target is read.
#
# Choice on the validation families only (scripts/reference_fewshot.sh's OUT dirs, closed form and
# reference solid: val_pool.h5, 50 strikes from index 330000; val_test.h5, 200 from 340000), in two
# settings: "pool", adapted on val_pool and scored on val_test; "test-time", adapted on val_test
# itself (its labels unread) and scored on it. Variants: F = 0.5 or 1, `--freeze none` at lr 1e-4
# or 3e-4, 40 epochs (the labelled few-shot recipe's epochs). CHOSEN="F LR" (after reading
# OUT/table.md) scores that variant once on each test family: adapted on test_pool.h5 (50, index
# 320000) and scored on TEST_DIR's closed.h5 / reference.h5 (300 strikes from index 300000), and
# test-time on those 300 themselves.
#
# Usage: scripts/pseudo_label_study.sh OUT RUN VAL_CLOSED_DIR VAL_SOLID_DIR TEST_DIR
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
USAGE="usage: pseudo_label_study.sh OUT RUN VAL_CLOSED_DIR VAL_SOLID_DIR TEST_DIR"
OUT=${1:?$USAGE}
RUN=${2:?$USAGE}
VAL_CLOSED=${3:?$USAGE}
VAL_SOLID=${4:?$USAGE}
TEST_DIR=${5:?$USAGE}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
CHOSEN=${CHOSEN:-}
VARIANTS=("0.5 0.0001" "0.5 0.0003" "1 0.0001" "1 0.0003")
mkdir -p "$OUT"

score() {  # json model data
  [ -f "$1" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "$3" --json > "$1"
}
selftrain() {  # out unlabelled fraction lr
  [ -f "$1/ensemble.json" ] || [ -f "$1/model.json" ] || "$BIN" --threads "$THREADS" -q train \
    --init-from "$RUN" --data "$2" --out "$1" --pseudo-labels "$3" --freeze none --lr "$4" \
    --epochs 40 --force --json > "$1.json"
}
for family in closed reference; do
  dir=$VAL_CLOSED; [ $family = reference ] && dir=$VAL_SOLID
  score "$OUT/val_${family}_none.json" "$RUN" "$dir/val_test.h5"
  for v in "${VARIANTS[@]}"; do
    read -r f lr <<< "$v"
    name=${f}_$lr
    selftrain "$OUT/val_${family}_pool_$name" "$dir/val_pool.h5" "$f" "$lr"
    score "$OUT/val_${family}_pool_$name.eval.json" "$OUT/val_${family}_pool_$name" "$dir/val_test.h5"
    selftrain "$OUT/val_${family}_tta_$name" "$dir/val_test.h5" "$f" "$lr"
    score "$OUT/val_${family}_tta_$name.eval.json" "$OUT/val_${family}_tta_$name" "$dir/val_test.h5"
  done
  if [ -n "$CHOSEN" ]; then
    read -r f lr <<< "$CHOSEN"
    name=${f}_$lr
    test_h5=$TEST_DIR/closed.h5; [ $family = reference ] && test_h5=$TEST_DIR/reference.h5
    selftrain "$OUT/test_${family}_pool_$name" "$dir/test_pool.h5" "$f" "$lr"
    score "$OUT/test_${family}_pool_$name.eval.json" "$OUT/test_${family}_pool_$name" "$test_h5"
    selftrain "$OUT/test_${family}_tta_$name" "$test_h5" "$f" "$lr"
    score "$OUT/test_${family}_tta_$name.eval.json" "$OUT/test_${family}_tta_$name" "$test_h5"
  fi
done

PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" "$CHOSEN" "${VARIANTS[@]}" <<'PY'
import json, sys
from transfer_tables import EVAL_HEAD as head, eval_cell as cell
out, chosen, variants = sys.argv[1], sys.argv[2], [v.replace(" ", "_") for v in sys.argv[3:]]
def labels(path):  # kept pseudo-labels: count and MED against the real labels
    p = json.load(open(path))["pseudo_labels"]
    return "%d, %.2f" % (p["kept"], p["med_cm_against_labels"])
def rows(split, names):
    lines = []
    for setting, what in [("pool", "pool of 50"), ("tta", "test-time")]:
        for n in names:
            f, lr = n.split("_")
            c, r = f"{out}/{split}_closed_{setting}_{n}", f"{out}/{split}_reference_{setting}_{n}"
            lines.append(f"| {what} | {f} | {lr} | {cell(c + '.eval.json')} | {labels(c + '.json')} | "
                         f"{cell(r + '.eval.json')} | {labels(r + '.json')} |")
    return lines
hdr = (f"| unlabelled strikes | kept fraction | lr | closed form: {head} | its pseudo-labels: kept, "
       f"MED (cm) | reference solid: {head} | its pseudo-labels: kept, MED (cm) |")
lines = ["Validation families (choose here; MED etc. on the 200 held-out strikes):", "",
         f"pretrained, no adaptation: closed form {cell(out + '/val_closed_none.json')}; reference "
         f"solid {cell(out + '/val_reference_none.json')}", "", hdr, "|---|---|---|---|---|---|---|"]
lines += rows("val", variants)
if chosen:
    lines += ["", f"Test families, variant {chosen} (each scored once on 300 strikes):", "", hdr,
              "|---|---|---|---|---|---|---|"] + rows("test", [chosen.replace(" ", "_")])
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
