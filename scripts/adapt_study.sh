#!/usr/bin/env bash
# Unlabelled adaptation (issue 32 item 4; docs/reference_model.md): `sonicboom adapt` re-estimates
# a pretrained run's per-mic input statistics and BatchNorm statistics on unlabelled strikes of
# the target, in three variants (both, BatchNorm only, input statistics only), for each run given.
# Choice on the validation families (scripts/reference_fewshot.sh's: adapted on the 50-strike
# pool, scored on the 200 held-out strikes; VAL_CLOSED_DIR and VAL_SOLID_DIR hold val_pool.h5 and
# val_test.h5); the test families are touched once per run, by the chosen variant only (adapted
# on the test family's 50-strike pool test_pool.h5 of TEST_CLOSED_DIR / TEST_SOLID_DIR, scored on
# TEST_DIR's closed.h5 / reference.h5, scripts/reference_family.sh).
#
# Usage: scripts/adapt_study.sh OUT VAL_CLOSED_DIR VAL_SOLID_DIR TEST_DIR RUN...
#   CHOSEN=variant (after reading OUT/table.md) also runs the test rows.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: adapt_study.sh OUT VAL_CLOSED_DIR VAL_SOLID_DIR TEST_DIR RUN...}
VAL_CLOSED=${2:?closed-form validation dir}
VAL_SOLID=${3:?reference-solid validation dir}
TEST_DIR=${4:?test families}
shift 4
BIN=${BIN:-$ROOT/build/bin/sonicboom}
THREADS=${THREADS:-2}
CHOSEN=${CHOSEN:-}
mkdir -p "$OUT"
declare -A FLAGS=([both]="" [batchnorm]="--keep-mel-statistics" [inputs]="--keep-batch-norm")

score() {  # json model data
  [ -f "$1" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "$3" --json > "$1"
}
adapt() {  # out model pool variant
  [ -f "$1/config.yaml" ] || "$BIN" --threads "$THREADS" -q adapt --model "$2" --data "$3" \
    --out "$1" ${FLAGS[$4]} > /dev/null
}
for run in "$@"; do
  name=$(basename "$run")
  for family in closed reference; do
    dir=$VAL_CLOSED; [ $family = reference ] && dir=$VAL_SOLID
    score "$OUT/val_${family}_${name}_none.json" "$run" "$dir/val_test.h5"
    for v in both batchnorm inputs; do
      adapt "$OUT/$name/val_${family}_$v" "$run" "$dir/val_pool.h5" $v
      score "$OUT/val_${family}_${name}_$v.json" "$OUT/$name/val_${family}_$v" "$dir/val_test.h5"
    done
    if [ -n "$CHOSEN" ]; then
      test_h5=$TEST_DIR/closed.h5; [ $family = reference ] && test_h5=$TEST_DIR/reference.h5
      adapt "$OUT/$name/test_${family}_$CHOSEN" "$run" "$dir/test_pool.h5" $CHOSEN
      score "$OUT/test_${family}_${name}_$CHOSEN.json" "$OUT/$name/test_${family}_$CHOSEN" "$test_h5"
    fi
  done
done

PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" "$CHOSEN" "$@" <<'PY'
import os, sys
from transfer_tables import EVAL_HEAD as head, eval_cell as cell
out, chosen, runs = sys.argv[1], sys.argv[2], [os.path.basename(r) for r in sys.argv[3:]]
lines = ["Validation families (adapted on the 50-strike pool, scored on 200; choose here):", "",
         f"| run | adaptation | closed form: {head} | reference solid: {head} |", "|---|---|---|---|"]
for n in runs:
    for v in ["none", "both", "batchnorm", "inputs"]:
        lines.append(f"| {n} | {v} | {cell(f'{out}/val_closed_{n}_{v}.json')} | "
                     f"{cell(f'{out}/val_reference_{n}_{v}.json')} |")
if chosen:
    lines += ["", f"Test families (adapted on the test family's own 50-strike pool, variant {chosen}):",
              "", f"| run | closed form: {head} | reference solid: {head} |", "|---|---|---|"]
    for n in runs:
        lines.append(f"| {n} | {cell(f'{out}/test_closed_{n}_{chosen}.json')} | "
                     f"{cell(f'{out}/test_reference_{n}_{chosen}.json')} |")
text = "\n".join(lines) + "\n"
open(f"{out}/table.md", "w").write(text)
print(text)
PY
