#!/usr/bin/env bash
# The paper's evaluation in simulation: train one localizer on the training distribution (ts1
# config, sample indices 0..TRAIN-1), evaluate it on held-out strikes of every scenario (ts1 with
# indices from 100000, ts2, ts3, ts4) and write a Markdown table with the 3-D MED, the published
# code's mixed-unit MED, height and angle errors, model size and training time.
#
# Usage: scripts/med_study.sh [OUTDIR=runs/med_study] [TRAIN=6000] [TEST=500] [THREADS=2]
#                            [MODEL_CONFIG=configs/study.yaml]
# Stages are resumable: a dataset file appears only when complete and is reused; a finished
# training run (metrics.jsonl complete and model.json present) is reused.
# Output: OUTDIR/table.md, OUTDIR/results.json (one eval JSON per scenario and baseline).
# BASELINES="knn tdoa constant" (the default) picks the baselines; kNN uses k = 1 and all GCC lags,
# the setting docs/baselines.md chose on a validation set. STAGE=generate stops after the data.
# VAL=N also generates N validation strikes per scenario (indices from 200000, disjoint from the
# test sets) and evaluates the model on them (OUTDIR/val_<ts>.json); STAGE=val stops there, before
# any test set is touched (scripts/scenario_selection.sh chooses settings that way). DATA=DIR keeps
# the datasets in DIR (shared by several runs); MODEL_SET="--set k=v ..." layers keys over
# MODEL_CONFIG for training.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/med_study}
TRAIN=${2:-6000}
TEST=${3:-500}
THREADS=${4:-2}
MODEL_CONFIG=${5:-$ROOT/configs/study.yaml}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
PY=/usr/bin/python3
DATA=${DATA:-$OUT}
VAL=${VAL:-0}
read -r -a MODEL_SET <<< "${MODEL_SET:-}"
mkdir -p "$OUT" "$DATA"

# datasets: training strikes, then held-out strikes with disjoint indices for every scenario
gen() {  # name config count first_index
  if [ ! -f "$DATA/$1.h5" ]; then
    "$BIN" generate --config "$2" --count "$3" --first-index "$4" --threads "$THREADS" \
      --out "$DATA/$1.h5" -q --json > "$DATA/$1.generate.json"
  fi
}
gen train "$ROOT/configs/ts1.yaml" "$TRAIN" 0
for ts in ts1 ts2 ts3 ts4; do gen "test_$ts" "$ROOT/configs/$ts.yaml" "$TEST" 100000; done
if [ "$VAL" -gt 0 ]; then
  for ts in ts1 ts2 ts3 ts4; do gen "val_$ts" "$ROOT/configs/$ts.yaml" "$VAL" 200000; done
fi
[ "${STAGE:-all}" = generate ] && exit 0

# training on the ts1 distribution
if [ ! -f "$OUT/model/model.json" ]; then
  start=$(date +%s)
  "$BIN" --config "$ROOT/configs/ts1.yaml" --config "$MODEL_CONFIG" --threads "$THREADS" -q \
    "${MODEL_SET[@]}" train --data "$DATA/train.h5" --out "$OUT/model" \
    $( [ -e "$OUT/model.partial" ] && echo --resume ) --json > "$OUT/train.json"
  echo $(( $(date +%s) - start )) > "$OUT/train_wall_s"
fi

# validation sets first (a choice made on them never sees a test set)
if [ "$VAL" -gt 0 ]; then
  for ts in ts1 ts2 ts3 ts4; do
    [ -f "$OUT/val_$ts.json" ] ||
      "$BIN" --threads "$THREADS" -q eval --model "$OUT/model" --data "$DATA/val_$ts.h5" --json \
        > "$OUT/val_$ts.json"
  done
fi
[ "${STAGE:-all}" = val ] && exit 0

# evaluation of the model and the baselines on every scenario
for ts in ts1 ts2 ts3 ts4; do
  "$BIN" --threads "$THREADS" -q eval --model "$OUT/model" --data "$DATA/test_$ts.h5" --json \
    > "$OUT/eval_$ts.json"
  for method in ${BASELINES:-knn tdoa constant}; do
    [ -f "$OUT/baseline_${method}_$ts.json" ] && continue
    "$BIN" --config "$ROOT/configs/ts1.yaml" --config "$MODEL_CONFIG" --threads "$THREADS" -q \
      baseline --method "$method" $([ "$method" = knn ] && echo "--k 1 --gcc-lags 441") \
      --train "$DATA/train.h5" --data "$DATA/test_$ts.h5" --json \
      > "$OUT/baseline_${method}_$ts.json.partial"
    mv "$OUT/baseline_${method}_$ts.json.partial" "$OUT/baseline_${method}_$ts.json"
  done
done
"$BIN" inspect "$OUT/model" --json > "$OUT/model_inspect.json"

# the table
"$PY" - "$OUT" "$MODEL_CONFIG" <<'EOF'
import json, os, sys
out, model_config = sys.argv[1], sys.argv[2]
def load(name):
    with open(os.path.join(out, name)) as f:
        return json.load(f)
targets = {"ts1": 0.4, "ts2": 1.0, "ts3": 2.0, "ts4": 2.2}
# training wall time (features + epochs) as this script measured it; else the epochs' own sum
if os.path.exists(os.path.join(out, "train_wall_s")):
    train_s = int(open(os.path.join(out, "train_wall_s")).read())
else:
    with open(os.path.join(out, "model", "metrics.jsonl")) as f:
        train_s = sum(json.loads(line)["epoch_seconds"] for line in f if line.strip())
model = load("model_inspect.json")
results = {"model": model, "train_wall_s": train_s, "scenarios": {}}
lines = ["| scenario | n | 3-D MED (cm) | target (cm) | met | published-code MED | height (cm) "
         "| angle (deg) | z cover 90 % | θ cover 90 % | kNN MED | TDOA MED | constant MED |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
for ts in ["ts1", "ts2", "ts3", "ts4"]:
    e = load("eval_%s.json" % ts)
    b = {m: (load("baseline_%s_%s.json" % (m, ts)) if os.path.exists(os.path.join(
        out, "baseline_%s_%s.json" % (m, ts))) else {"med_cm": None}) for m in ["knn", "tdoa", "constant"]}
    results["scenarios"][ts] = {"model": e, **b}
    fmt = lambda v, p=2: "–" if v is None else ("%.*f" % (p, v))
    lines.append("| %s | %d | %s | %.1f | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
        ts, e["n"], fmt(e["med_cm"]), targets[ts], "yes" if e["med_cm"] <= targets[ts] else "no",
        fmt(e["reference_med_cm"]), fmt(e["height_err_cm"]), fmt(e["angle_err_deg"], 1),
        fmt(e.get("z_coverage_90")), fmt(e.get("theta_coverage_90")), fmt(b["knn"]["med_cm"]),
        fmt(b["tdoa"]["med_cm"]), fmt(b["constant"]["med_cm"])))
with open(os.path.join(out, "results.json"), "w") as f:
    json.dump(results, f, indent=2)
cfg = model.get("model", {}).get("model", {})
lines.append("")
lines.append("Model: %s audio encoder, width %s, %s blocks, %s heads, %s trainable parameters; "
             "trained %s epochs in %s s." % (cfg.get("audio_encoder"), cfg.get("width"),
             cfg.get("blocks"), cfg.get("heads"), model.get("parameters", {}).get("total"),
             model.get("model", {}).get("epochs_trained"), "%.0f" % train_s if train_s else None))
with open(os.path.join(out, "table.md"), "w") as f:
    f.write("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
