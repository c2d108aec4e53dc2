#!/usr/bin/env bash
# Inputs of the 20 ms wavefront window (docs/transfer.md): the log-mel localizer of
# configs/transfer_mel.yaml against finer time and frequency resolutions, early GCC-PHAT, the
# waveform itself through strided 1-D convolutions (features.audio_representation = waveform,
# model.audio_encoder = conv1d), longer training, and ensembles; all trained on the randomized
# ts4 strikes of scripts/transfer_ablation.sh and scored on its VALIDATION sets only (val_in,
# val_struct, val_contact, val_nominal; none is a test set of scripts/transfer_benchmark.sh).
# configs/transfer.yaml is the variant chosen here, by the mean MED of the four sets.
#
# Usage: scripts/transfer_waveform.sh [OUT=runs/transfer_waveform] [ABLATION=runs/transfer_ablation]
#                                     [THREADS=2]
# ABLATION must hold train.h5 and the val_*.h5 sets (scripts/transfer_ablation.sh makes them).
# Resumable. Output: OUT/table.md, OUT/results.json.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-runs/transfer_waveform}
ABLATION=${2:-runs/transfer_ablation}
THREADS=${3:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
# shellcheck source=scripts/transfer_common.sh
source "$ROOT/scripts/transfer_common.sh"
SETS="val_in val_struct val_contact val_nominal"
for s in train $SETS; do
  [ -f "$ABLATION/$s.h5" ] || { echo "$ABLATION/$s.h5: missing (run scripts/transfer_ablation.sh)" >&2; exit 1; }
done

WAVE="--set features.audio_representation=waveform --set model.audio_encoder=conv1d
 --set model.crop_frames=882 --set train.time_shift_frames=16 --set train.time_mask_frames=64
 --set train.freq_mask_bands=0"
E150="--set train.epochs=150 --set train.lr_step_epochs=40"
variant_args() {  # over configs/transfer_mel.yaml
  case $1 in
    mel) echo "" ;;
    mel-fft256) echo "--set features.n_fft=256 --set features.n_mels=32" ;;
    mel-fft128-8khz) echo "--set features.n_fft=128 --set features.n_mels=32 --set features.f_max_hz=8000" ;;
    mel-fft256-40ms) echo "--set features.n_fft=256 --set features.n_mels=32 --set features.window_s=0.04 --set model.crop_frames=221" ;;
    mel-hop4) echo "--set features.hop=4 --set model.crop_frames=221 --set train.time_shift_frames=4 --set train.time_mask_frames=16" ;;
    mel-hop2) echo "--set features.n_fft=32 --set features.hop=2 --set features.n_mels=8 --set model.crop_frames=442 --set train.time_shift_frames=8 --set train.time_mask_frames=32 --set train.freq_mask_bands=1" ;;
    mel-hop4-fft128-8khz) echo "--set features.hop=4 --set model.crop_frames=221 --set train.time_shift_frames=4 --set train.time_mask_frames=16 --set features.n_fft=128 --set features.n_mels=32 --set features.f_max_hz=8000" ;;
    mel+gcc3ms) echo "--set model.modalities=[audio,gcc] --set features.gcc_window_s=0.003 --set features.gcc_max_lag=48 --set model.gcc_encoder=conv" ;;
    mel+gcc5ms) echo "--set model.modalities=[audio,gcc] --set features.gcc_window_s=0.005 --set features.gcc_max_lag=64 --set model.gcc_encoder=conv" ;;
    mel-e150) echo "$E150" ;;
    wave) echo "$WAVE" ;;
    wave-e150) echo "$WAVE $E150" ;;
    wave-e300) echo "$WAVE --set train.epochs=300 --set train.lr_step_epochs=80" ;;
    wave-e150-lr2e-3) echo "$WAVE $E150 --set train.learning_rate=0.002" ;;
    wave-e150-3members) echo "$WAVE $E150 --set train.ensemble_members=3" ;;
  esac
}
VARIANTS=${VARIANTS:-"mel mel-fft256 mel-fft128-8khz mel-fft256-40ms mel-hop4 mel-hop2
 mel-hop4-fft128-8khz mel+gcc3ms mel+gcc5ms mel-e150 wave wave-e150 wave-e300 wave-e150-lr2e-3
 wave-e150-3members"}
for v in $VARIANTS; do
  if [ ! -f "$OUT/$v/model.json" ] && [ ! -f "$OUT/$v/ensemble.json" ]; then
    # shellcheck disable=SC2046
    "$BIN" "${TS4[@]}" "${RAND[@]}" --config "$ROOT/configs/transfer_mel.yaml" $(variant_args "$v") \
      --threads "$THREADS" -q train --data "$ABLATION/train.h5" --out "$OUT/$v" \
      $(resume_flag "$OUT/$v") --json > "$OUT/train_$v.json"
  fi
  for s in $SETS; do
    [ -f "$OUT/${s}_$v.json" ] || "$BIN" --threads "$THREADS" -q eval --model "$OUT/$v" \
      --data "$ABLATION/$s.h5" --json > "$OUT/${s}_$v.json"
  done
done

# shellcheck disable=SC2086
PYTHONPATH="$ROOT/scripts" /usr/bin/python3 - "$OUT" $VARIANTS <<'PY'
import json, os, sys
import transfer_tables
out, variants = sys.argv[1], sys.argv[2:]
sets = ["val_in", "val_struct", "val_contact", "val_nominal"]
load = lambda name: transfer_tables.load(out, name)
train_seconds = lambda v: transfer_tables.train_seconds(out, v)
lines = ["| variant | " + " | ".join(s + " MED (cm)" for s in sets) +
         " | mean | val_nominal height (cm) / angle (deg) | training, sum of epochs (s) |",
         "|---|" + "---|" * (len(sets) + 3)]
results = {}
for v in variants:
    e = {s: load("%s_%s.json" % (s, v)) for s in sets}
    mean = sum(e[s]["med_cm"] for s in sets) / len(sets)
    lines.append("| %s | %s | %.2f | %.2f / %.1f | %s |" % (
        v, " | ".join("%.2f" % e[s]["med_cm"] for s in sets), mean,
        e["val_nominal"]["height_err_cm"], e["val_nominal"]["angle_err_deg"], train_seconds(v)))
    results[v] = {"med_cm": {s: e[s]["med_cm"] for s in sets}, "mean_cm": mean,
                  "training_s": train_seconds(v)}
best = min(variants, key=lambda v: results[v]["mean_cm"])
lines += ["", "Lowest mean MED of the four validation sets: %s (%.2f cm)." % (
    best, results[best]["mean_cm"])]
transfer_tables.write(out, lines, results)
PY
