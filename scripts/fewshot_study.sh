#!/usr/bin/env bash
# Few-shot fine-tuning (docs/captures.md): a transfer model pretrained on randomized strikes,
# fine-tuned on n strikes of a structure family it never saw, against the same network trained
# from scratch on those n strikes; MED on a held-out part of the family.
#
#   scripts/fewshot_study.sh OUT PRETRAINED_RUN [THREADS=2] [FAMILIES="stiff chain"]
#
# PRETRAINED_RUN: a transfer run on randomized ts4 strikes (a single network or an ensemble),
# e.g. the transfer run of `scripts/transfer_benchmark.sh OUT 3000 300 2`. The networks trained
# from scratch use the pretrained run's own config (its features, network, epochs, members).
# Families (scripts/transfer_common.sh): the preset's strikers and sensor chain on one structure
# outside the training ranges. Each family gets a pool (sample indices 300000 on; the first n are
# the n target strikes) and a held-out test part (200 strikes from index 310000).
# Both train on 80 % of the n strikes and calibrate their intervals on the other 20 %; with
# KEEP_BEST=true (environment) both also keep the epoch with the lowest loss on those 20 %
# (train.keep_best).
# Selection: the freeze mode and learning rate of the fine-tune are chosen at n = 50 on the
# `loose` family's held-out part (a validation family, never reported as a test); the test
# families are evaluated once per cell, with that setting. Resumable. Output: OUT/table.md,
# OUT/results.json, OUT/fewshot.png.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/fewshot_study.sh OUT PRETRAINED_RUN [THREADS] [FAMILIES]}
PRE=${2:?usage: scripts/fewshot_study.sh OUT PRETRAINED_RUN [THREADS] [FAMILIES]}
THREADS=${3:-2}
FAMILIES=${4:-"stiff chain"}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
# shellcheck source=scripts/transfer_common.sh
source "$ROOT/scripts/transfer_common.sh"
SHOTS="10 25 50 100 400"
FREEZES="none encoders all-but-head"
RATES="0.0001 0.0003 0.001"
EPOCHS=40
KEEP_BEST=${KEEP_BEST:-false}

data() {  # family: its pool prefixes and held-out part
  local f=$1 n
  # shellcheck disable=SC2046
  gen "test_$f" 310000 200 "${RAND[@]}" "${ONE[@]}" $(family_args "$f")
  for n in $SHOTS; do
    # shellcheck disable=SC2046
    gen "pool_${f}_$n" 300000 "$n" "${RAND[@]}" "${ONE[@]}" $(family_args "$f")
  done
}
evaluate() {  # run family: OUT/eval_<run>.json once
  [ -f "$OUT/eval_$1.json" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" \
    --data "$OUT/test_$3.h5" --json > "$OUT/eval_$1.json"
}
tune() {  # name family n freeze lr
  [ -f "$OUT/$1/model.json" ] || [ -f "$OUT/$1/ensemble.json" ] || "$BIN" --threads "$THREADS" -q train --init-from "$PRE" \
    --freeze "$4" --lr "$5" --epochs "$EPOCHS" --set train.keep_best=$KEEP_BEST --data "$OUT/pool_$2_$3.h5" --out "$OUT/$1" \
    $(resume_flag "$OUT/$1") --json > "$OUT/train_$1.json"
  evaluate "$1" "$OUT/$1" "$2"
}
scratch() {  # name family n
  [ -f "$OUT/$1/model.json" ] || [ -f "$OUT/$1/ensemble.json" ] || "$BIN" --config "$PRE/config.yaml" \
    --set train.keep_best=$KEEP_BEST --threads "$THREADS" -q train --data "$OUT/pool_$2_$3.h5" --out "$OUT/$1" $(resume_flag "$OUT/$1") \
    --json > "$OUT/train_$1.json"
  evaluate "$1" "$OUT/$1" "$2"
}

# 1. the fine-tune setting, chosen on the validation family
data loose
for fr in $FREEZES; do
  for lr in $RATES; do tune "select_${fr}_$lr" loose 50 "$fr" "$lr"; done
done
BEST=$(/usr/bin/python3 - "$OUT" "$FREEZES" "$RATES" <<'PY'
import json, sys
out, freezes, rates = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
med = {(f, r): json.load(open(f"{out}/eval_select_{f}_{r}.json"))["med_cm"] for f in freezes for r in rates}
f, r = min(med, key=med.get)
print(f, r)
PY
)
read -r FREEZE LR <<< "$BEST"
echo "chosen on loose (n = 50): --freeze $FREEZE --lr $LR" | tee "$OUT/chosen.txt"

# 2. the test families: n = 0 (the pretrained model), fine-tuned and from scratch
for f in $FAMILIES; do
  data "$f"
  evaluate "pre_$f" "$PRE" "$f"
  for n in $SHOTS; do
    tune "tune_${f}_$n" "$f" "$n" "$FREEZE" "$LR"
    scratch "scratch_${f}_$n" "$f" "$n"
  done
done

/usr/bin/python3 "$ROOT/scripts/fewshot_report.py" "$OUT" "$FREEZES" "$RATES" "$FAMILIES" "$SHOTS"
/usr/bin/python3 "$ROOT/scripts/plot.py" fewshot "$OUT/results.json" "$OUT/fewshot.png"
