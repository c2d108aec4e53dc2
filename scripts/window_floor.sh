#!/usr/bin/env bash
# What the 20 ms wavefront window can reach on ts4's own strikes when nothing varies: the
# transfer model's features and network (configs/transfer_mel.yaml) and the latency profile over the
# full window (configs/study_fast.yaml, audio + GCC-PHAT), both trained on TRAIN strikes of the
# default structure (ts4 as configured, indices from 0: the benchmark's train_default), scored on
# the VALIDATION sets of scripts/transfer_ablation.sh (no test set is touched, nothing is chosen).
# docs/history.md ("The window's floor") reads it as the floor of the in-distribution target on ts4-like strikes.
#
# Usage: scripts/window_floor.sh [OUT=runs/window_floor] [ABLATION=runs/transfer_ablation]
#                                [TRAIN=3000] [THREADS=2]
# ABLATION must hold val_in/val_struct/val_contact/val_nominal.h5 (scripts/transfer_ablation.sh,
# STAGE=generate is not needed: the sets are made first). Resumable. Output: OUT/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/window_floor}
ABLATION=${2:-runs/transfer_ablation}
TRAIN=${3:-3000}
THREADS=${4:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"

# shellcheck source=scripts/transfer_common.sh
source "$ROOT/scripts/transfer_common.sh"
gen train_nominal 0 "$TRAIN"
SETS="val_in val_struct val_contact val_nominal"
for s in $SETS; do
  [ -f "$ABLATION/$s.h5" ] || { echo "$ABLATION/$s.h5: missing (run scripts/transfer_ablation.sh)" >&2; exit 1; }
done
model_args() {
  case $1 in
    window20ms) echo "--config $ROOT/configs/transfer_mel.yaml" ;;
    full) echo "--config $ROOT/configs/study_fast.yaml --set model.modalities=[audio,gcc]" ;;
  esac
}
for m in window20ms full; do
  if [ ! -f "$OUT/$m/model.json" ]; then
    # shellcheck disable=SC2046
    "$BIN" "${TS4[@]}" $(model_args "$m") --threads "$THREADS" -q train \
      --data "$OUT/train_nominal.h5" --out "$OUT/$m" $(resume_flag "$OUT/$m") --json > "$OUT/train_$m.json"
  fi
  for s in $SETS; do
    [ -f "$OUT/${s}_$m.json" ] || "$BIN" --threads "$THREADS" -q eval --model "$OUT/$m" \
      --data "$ABLATION/$s.h5" --json > "$OUT/${s}_$m.json"
  done
done

/usr/bin/python3 - "$OUT" <<'PY'
import json, os, sys
out = sys.argv[1]
sets = ["val_in", "val_struct", "val_contact", "val_nominal"]
names = {"window20ms": "20 ms window (configs/transfer_mel.yaml)",
         "full": "1.5 s window (study_fast, audio + GCC-PHAT)"}
lines = ["| trained on the default structure | " + " | ".join(sets) +
         " | val_nominal height (cm) / angle (deg) |", "|---|" + "---|" * (len(sets) + 1)]
for m, name in names.items():
    e = {s: json.load(open(os.path.join(out, "%s_%s.json" % (s, m)))) for s in sets}
    lines.append("| %s | %s | %.2f / %.1f |" % (
        name, " | ".join("%.2f" % e[s]["med_cm"] for s in sets),
        e["val_nominal"]["height_err_cm"], e["val_nominal"]["angle_err_deg"]))
open(os.path.join(out, "table.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
