#!/usr/bin/env bash
# Data-parallel training against one process on this machine: the transfer model
# (configs/transfer_mel.yaml) on COUNT randomized ts4 strikes for EPOCHS epochs, trained by one process
# of one thread, by one process of NP threads, and by NP processes of one thread each
# (scripts/cluster/train_ddp.sh), same global batch. Prints the mean epoch time of each, the
# speed-ups over one thread, the per-epoch training losses side by side and the runs' validation
# MED (docs/cluster.md quotes it).
#
# Usage: scripts/ddp_speedup.sh OUT [COUNT=3000] [EPOCHS=20] [NP=2]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/ddp_speedup.sh OUT [COUNT] [EPOCHS] [NP]}
COUNT=${2:-3000}
EPOCHS=${3:-20}
NP=${4:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
cd "$OUT"
scene=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0
       --config "$ROOT/configs/randomized.yaml")
model=(--config "$ROOT/configs/transfer_mel.yaml" --set "train.epochs=$EPOCHS")
"$BIN" -q --threads "$NP" "${scene[@]}" generate --count "$COUNT" --out data.h5
"$BIN" -q --threads 1 "${scene[@]}" "${model[@]}" train --force --data data.h5 --out single
"$BIN" -q --threads "$NP" "${scene[@]}" "${model[@]}" train --force --data data.h5 --out one
rm -rf parallel parallel.partial
SONICBOOM_BIN=$BIN THREADS=1 MASTER_PORT=${MASTER_PORT:-29517} \
  bash "$ROOT/scripts/cluster/train_ddp.sh" "$NP" data.h5 parallel -q "${scene[@]}" "${model[@]}" \
  > parallel.log
/usr/bin/python3 - "$NP" <<'PY'
import json, sys
np_ = int(sys.argv[1])
def run(name):
    lines = [json.loads(l) for l in open(name + "/metrics.jsonl")]
    return ([l["epoch_seconds"] for l in lines], [l["train_loss"] for l in lines],
            json.load(open(name + "/model.json"))["val_metrics"]["med_cm"])
t0, l0, m0 = run("single")
t1, l1, m1 = run("one")
tp, lp, mp = run("parallel")
mean = lambda v: sum(v) / len(v)
print(f"one process x 1 thread: {mean(t0):.2f} s per epoch, validation MED {m0:.2f} cm")
print(f"one process x {np_} threads: {mean(t1):.2f} s per epoch ({mean(t0) / mean(t1):.2f}x), "
      f"validation MED {m1:.2f} cm")
print(f"{np_} processes x 1 thread: {mean(tp):.2f} s per epoch ({mean(t0) / mean(tp):.2f}x), "
      f"validation MED {mp:.2f} cm")
print(f"data parallel against {np_} threads: {mean(t1) / mean(tp):.2f}x")
print("epoch | loss, one process | loss, data parallel | ratio")
for e, (a, b) in enumerate(zip(l1, lp), 1):
    print(f"{e} | {a:.4f} | {b:.4f} | {b / a:.3f}")
PY
