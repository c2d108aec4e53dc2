#!/usr/bin/env bash
# `train --init-from` with its default `--tune auto` (docs/captures.md) against the pretrained run
# zero-shot and the former fixed recipe (every layer, lr 3e-4), at n labelled strikes of three
# families, for a run pretrained on the randomized preset: `in` (that distribution itself),
# `chain` (one structure with the tie bolts and the other sensor chain of
# scripts/transfer_common.sh) and `built` (the preset with configs/built.yaml over it: soft
# strikers, a floor set by the strike's peak, other filters).
#
#   scripts/auto_tune_study.sh OUT PRETRAINED_RUN [THREADS=2] [FAMILIES="in chain built"]
#
# Per family: the labelled strikes are the first n from sample index 500000 (n = 10, 25, 50), the
# test part 100 other strikes from index 500050; every test figure is one eval of one run, read
# once. Auto chooses by its cross-validation on the n strikes alone. Both fine-tunes train 40
# epochs. Resumable (finished runs and evals are kept). Output: OUT/table.md, OUT/results.json.
# Mode solves uncached (SONICBOOM_CACHE_MAX_BYTES=0) unless the caller sets it.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/auto_tune_study.sh OUT PRETRAINED_RUN [THREADS] [FAMILIES]}
PRE=${2:?usage: scripts/auto_tune_study.sh OUT PRETRAINED_RUN [THREADS] [FAMILIES]}
THREADS=${3:-2}
FAMILIES=${4:-"in chain built"}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
export SONICBOOM_CACHE_MAX_BYTES=${SONICBOOM_CACHE_MAX_BYTES:-0}
SHOTS="10 25 50"
EPOCHS=40
mkdir -p "$OUT"
# shellcheck source=scripts/transfer_common.sh
source "$ROOT/scripts/transfer_common.sh"

gen_family() {  # name first count family: `in` and `built` keep the preset's pool of structures
  if [ "$4" = in ]; then gen "$1" "$2" "$3" "${RAND[@]}"; return; fi
  if [ "$4" = built ]; then gen "$1" "$2" "$3" "${RAND[@]}" --config "$ROOT/configs/built.yaml"; return; fi
  # shellcheck disable=SC2046
  gen "$1" "$2" "$3" "${RAND[@]}" "${ONE[@]}" $(family_args "$4")
}
evaluate() {  # name run family: OUT/eval_<name>.json once
  [ -f "$OUT/eval_$1.json" ] || "$BIN" --threads "$THREADS" -q eval --model "$2" \
    --data "$OUT/test_$3.h5" --json > "$OUT/eval_$1.json"
}
tune() {  # name family n [recipe options]: a fine-tune of PRE on pool_<family>_<n>, timed
  local name=$1 f=$2 n=$3 start; shift 3
  if [ ! -f "$OUT/$name/model.json" ] && [ ! -f "$OUT/$name/ensemble.json" ]; then
    start=$(date +%s)
    "$BIN" --threads "$THREADS" -q train --init-from "$PRE" --epochs "$EPOCHS" "$@" \
      --data "$OUT/pool_${f}_$n.h5" --out "$OUT/$name" --force --json > "$OUT/train_$name.json"
    echo $(( $(date +%s) - start )) > "$OUT/$name.wall_s"
  fi
  evaluate "$name" "$OUT/$name" "$f"
}

for f in $FAMILIES; do
  gen_family "test_$f" 500050 100 "$f"
  for n in $SHOTS; do gen_family "pool_${f}_$n" 500000 "$n" "$f"; done
  evaluate "zero_$f" "$PRE" "$f"
  for n in $SHOTS; do
    tune "auto_${f}_$n" "$f" "$n"
    tune "fixed_${f}_$n" "$f" "$n" --freeze none --lr 3e-4
  done
done

/usr/bin/python3 - "$OUT" "$FAMILIES" "$SHOTS" <<'PY'
import json, sys
out, families, shots = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
med = lambda name: json.load(open(f"{out}/eval_{name}.json"))["med_cm"]
rows, results = [], {}
rows.append("| family | n | zero-shot | auto (chosen) | fixed: none, lr 3e-4 | auto wall s |")
rows.append("|---|---|---|---|---|---|")
for f in families:
    for n in shots:
        ft = json.load(open(f"{out}/auto_{f}_{n}/fine_tune.json"))
        wall = open(f"{out}/auto_{f}_{n}.wall_s").read().strip()
        r = {"zero_shot_cm": med(f"zero_{f}"), "auto_cm": med(f"auto_{f}_{n}"),
             "fixed_cm": med(f"fixed_{f}_{n}"), "auto_chosen": ft["chosen"],
             "auto_folds": {c["name"]: c["mean_med_cm"] for c in ft["candidates"]},
             "auto_wall_s": int(wall)}
        results[f"{f}_{n}"] = r
        rows.append(f"| {f} | {n} | {r['zero_shot_cm']:.2f} | {r['auto_cm']:.2f} "
                    f"({ft['chosen']}) | {r['fixed_cm']:.2f} | {wall} |")
open(f"{out}/table.md", "w").write("\n".join(rows) + "\n")
json.dump(results, open(f"{out}/results.json", "w"), indent=2)
print("\n".join(rows))
PY
