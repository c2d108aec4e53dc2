#!/usr/bin/env bash
# Few-shot adaptation in another theory (issue 32): a transfer model pretrained on randomized
# shell strikes, fine-tuned on n = 50 labelled strikes rendered by the reference solid
# (`rerender`, docs/reference_model.md), against the same network trained from scratch on those
# 50, and against the pretrained model itself (n = 0). ts4 strikes of the default structure.
#
#   scripts/reference_fewshot.sh OUT PRETRAINED_RUN [THREADS=2] [TEST_FAMILY_DIR]
#
# Selection: the fine-tune's freeze mode and learning rate are chosen on a validation family of
# the other theory (pool: 50 strikes from sample index 330000; held-out part: 200 from 340000),
# never on the test. Test: the 50 target strikes from index 320000, scored once per row on the
# other-theory family of scripts/reference_family.sh (300 strikes from index 300000; pass its
# OUT as TEST_FAMILY_DIR to reuse its reference.h5). Both trainings use 80 % of the 50 and
# calibrate their intervals on the other 20 %. Writes OUT/table.md and OUT/results.json.
# THEORY=closed renders every family by the closed-form rung instead (Flügge modes of an ideal
# simply supported tube, gain 12 dB down, as scripts/reference_family.sh's closed.h5): the third
# theory, where the pretrained models are wrong (2.5-2.7 cm), so the recipe is chosen where it
# has something to fix; TEST_FAMILY_DIR then supplies closed.h5.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/reference_fewshot.sh OUT PRETRAINED_RUN [THREADS] [TEST_FAMILY_DIR]}
PRE=${2:?usage: scripts/reference_fewshot.sh OUT PRETRAINED_RUN [THREADS] [TEST_FAMILY_DIR]}
THREADS=${3:-2}
FAMILY=${4:-}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
BAND=${REFERENCE_BAND:-15000}
THEORY=${THEORY:-reference}
mkdir -p "$OUT"
TS4=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0)
FREEZES="none encoders all-but-head"
RATES="0.0001 0.0003 0.001"
EPOCHS=40

other() {  # name first count: OUT/name.h5, ts4 strikes rendered by the other theory
  [ -f "$OUT/$1.h5" ] && return
  if [ "$THEORY" = closed ]; then
    "$BIN" "${TS4[@]}" --set acoustics.model=modal-closed-form \
      --set 'daq.channel_gain_db=[-12,-12,-12,-12,-12,-12]' --threads "$THREADS" -q generate \
      --first-index "$2" --count "$3" --out "$OUT/$1.h5" --json > /dev/null
    return
  fi
  [ -f "$OUT/$1_shell.h5" ] || "$BIN" "${TS4[@]}" --threads "$THREADS" -q generate \
    --first-index "$2" --count "$3" --out "$OUT/$1_shell.h5" --json > /dev/null
  "$BIN" --threads "$THREADS" -q rerender --in "$OUT/$1_shell.h5" --out "$OUT/$1.h5" \
    --max-frequency "$BAND" --json > "$OUT/$1.rerender.json"
}
evaluate() {  # name run data: OUT/eval_<name>.json once
  [ -f "$OUT/eval_$1.json" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" --data "$3" \
    --json > "$OUT/eval_$1.json"
}
done_run() { [ -f "$1/model.json" ] || [ -f "$1/ensemble.json" ]; }
tune() {  # name pool freeze lr
  done_run "$OUT/$1" || "$BIN" --threads "$THREADS" -q train --init-from "$PRE" --freeze "$3" \
    --lr "$4" --epochs "$EPOCHS" --data "$OUT/$2.h5" --out "$OUT/$1" --force --json \
    > "$OUT/train_$1.json"
}

other val_pool 330000 50
other val_test 340000 200
other test_pool 320000 50
if [ -n "$FAMILY" ]; then
  TEST="$FAMILY/$([ "$THEORY" = closed ] && echo closed || echo reference).h5"
else
  other test 300000 300
  TEST="$OUT/test.h5"
fi

# 1. the fine-tune setting, chosen on the validation family of the other theory
for fr in $FREEZES; do
  for lr in $RATES; do
    tune "select_${fr}_$lr" val_pool "$fr" "$lr"
    evaluate "select_${fr}_$lr" "$OUT/select_${fr}_$lr" "$OUT/val_test.h5"
  done
done
evaluate val_zero_shot "$PRE" "$OUT/val_test.h5"
read -r FREEZE LR < <(/usr/bin/python3 - "$OUT" "$FREEZES" "$RATES" <<'PY'
import json, sys
out, freezes, rates = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
med = {(f, r): json.load(open(f"{out}/eval_select_{f}_{r}.json"))["med_cm"] for f in freezes for r in rates}
print(*min(med, key=med.get))
PY
)
echo "chosen on the validation family (n = 50): --freeze $FREEZE --lr $LR" | tee "$OUT/chosen.txt"

# 2. the test: zero-shot, fine-tuned with the chosen setting, from scratch, each scored once
evaluate zero_shot "$PRE" "$TEST"
tune tuned test_pool "$FREEZE" "$LR"
evaluate tuned "$OUT/tuned" "$TEST"
done_run "$OUT/scratch" || "$BIN" --config "$PRE/config.yaml" --threads "$THREADS" -q train \
  --data "$OUT/test_pool.h5" --out "$OUT/scratch" --force --json > "$OUT/train_scratch.json"
evaluate scratch "$OUT/scratch" "$TEST"
[ -f "$OUT/eval_arrival.json" ] || "$BIN" --threads "$THREADS" -q baseline --method arrival \
  --data "$TEST" --json > "$OUT/eval_arrival.json"

/usr/bin/python3 - "$OUT" "$FREEZES" "$RATES" <<'PY'
import json, pathlib, sys
out, freezes, rates = pathlib.Path(sys.argv[1]), sys.argv[2].split(), sys.argv[3].split()
load = lambda n: json.load(open(out / f"eval_{n}.json"))  # noqa: E731
lines = ["Selection on the other-theory validation family (n = 50; MED cm on its 200 held-out "
         f"strikes; zero-shot {load('val_zero_shot')['med_cm']:.2f}):", "",
         "| freeze | " + " | ".join(f"lr {r}" for r in rates) + " |", "|---|" + "---|" * len(rates)]
for f in freezes:
    lines.append(f"| {f} | " + " | ".join(f"{load(f'select_{f}_{r}')['med_cm']:.2f}" for r in rates) + " |")
lines += ["", (out / "chosen.txt").read_text().strip(), "",
          "| on the other-theory test family | MED (cm) | height (cm) | angle (°) | 90 % z / θ coverage |",
          "|---|---|---|---|---|"]
rows = {}
for name, label in [("zero_shot", "pretrained, zero-shot (n = 0)"), ("tuned", "fine-tuned on 50"),
                    ("scratch", "same network from scratch on 50"), ("arrival", "arrival locator")]:
    e = load(name)
    rows[name] = e
    cov = (f"{e['z_coverage_90']:.2f} / {e['theta_coverage_90']:.2f}"
           if e.get("z_coverage_90") is not None else "–")
    lines.append(f"| {label} | {e['med_cm']:.2f} | {e.get('height_err_cm', float('nan')):.2f} | "
                 f"{e.get('angle_err_deg', float('nan')):.1f} | {cov} |")
text = "\n".join(lines) + "\n"
(out / "table.md").write_text(text)
json.dump(rows, open(out / "results.json", "w"), indent=2)
print(text)
PY
