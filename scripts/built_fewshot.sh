#!/usr/bin/env bash
# Few labelled taps of a tube as built (docs/transfer.md, "Taps of the tube as built"): a
# pretrained run zero-shot, fine-tuned by `train --init-from` (its default `--tune auto`) on the
# first n = 10 / 25 / 50 strikes of an as-built family's validation copy (seed 13, indices from
# 500000: the same tube, other strikes), and the same network trained from scratch on the 50;
# each scored once on the family's test copy of scripts/built_benchmark.sh (BENCH/test_<f>.h5:
# seed 11, indices from 400000).
#
#   scripts/built_fewshot.sh OUT PRETRAINED_RUN BENCH [THREADS=2] [FAMILIES="built noisy soft"]
#
# Resumable (finished datasets, runs and evaluations are kept). Output: OUT/table.md,
# OUT/results.json.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/built_fewshot.sh OUT PRETRAINED_RUN BENCH [THREADS] [FAMILIES]}
PRE=${2:?usage: scripts/built_fewshot.sh OUT PRETRAINED_RUN BENCH [THREADS] [FAMILIES]}
BENCH=${3:?usage: scripts/built_fewshot.sh OUT PRETRAINED_RUN BENCH [THREADS] [FAMILIES]}
THREADS=${4:-2}
FAMILIES=${5:-"built noisy soft"}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
SHOTS="10 25 50"
mkdir -p "$OUT"
# shellcheck source=scripts/transfer_common.sh
source "$ROOT/scripts/transfer_common.sh"

evaluate() {  # name run family: OUT/eval_<name>.json once
  [ -f "$OUT/eval_$1.json" ] || "$BIN" --threads "$THREADS" -q --json eval --model "$2" \
    --data "$BENCH/test_$3.h5" > "$OUT/eval_$1.json.tmp" && mv "$OUT/eval_$1.json.tmp" "$OUT/eval_$1.json"
}
timed() {  # name command...: runs the command unless OUT/name exists, its wall time beside it
  local name=$1 start; shift
  [ -e "$OUT/$name" ] && return
  start=$(date +%s)
  "$@"
  echo $(( $(date +%s) - start )) > "$OUT/$name.wall_s"
}

for f in $FAMILIES; do
  [ -f "$BENCH/test_$f.h5" ] || { echo "$BENCH/test_$f.h5 is missing: run scripts/built_benchmark.sh $BENCH first" >&2; exit 1; }
  # shellcheck disable=SC2046
  for n in $SHOTS; do gen "pool_${f}_$n" 500000 "$n" --seed 13 $(built_family_args "$f"); done
  evaluate "zero_$f" "$PRE" "$f"
  for n in $SHOTS; do
    timed "auto_${f}_$n" "$BIN" --threads "$THREADS" -q train --init-from "$PRE" \
      --data "$OUT/pool_${f}_$n.h5" --out "$OUT/auto_${f}_$n"
    evaluate "auto_${f}_$n" "$OUT/auto_${f}_$n" "$f"
  done
  timed "scratch_${f}_50" "$BIN" --threads "$THREADS" -q train --config "$PRE/config.yaml" \
    --data "$OUT/pool_${f}_50.h5" --out "$OUT/scratch_${f}_50"
  evaluate "scratch_${f}_50" "$OUT/scratch_${f}_50" "$f"
done

/usr/bin/python3 - "$OUT" "$FAMILIES" "$SHOTS" <<'PY'
import json, sys
out, families, shots = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
ev = lambda name: json.load(open(f"{out}/eval_{name}.json"))
cell = lambda m: (f"{m['med_cm']:.2f} ({m['angle_err_deg']:.1f}; "
                  f"{m.get('z_coverage_90', float('nan')):.2f} / "
                  f"{m.get('theta_coverage_90', float('nan')):.2f})")
rows = ["| family | zero-shot | " + " | ".join(f"auto, n = {n}" for n in shots) +
        " | scratch, n = 50 |", "|---|---|" + "---|" * len(shots) + "---|"]
results = {}
for f in families:
    r = {"zero_shot": ev(f"zero_{f}"), "scratch_50": ev(f"scratch_{f}_50")}
    cells = [cell(r["zero_shot"])]
    for n in shots:
        ft = json.load(open(f"{out}/auto_{f}_{n}/fine_tune.json"))
        r[f"auto_{n}"] = ev(f"auto_{f}_{n}")
        r[f"auto_{n}_chosen"] = ft["chosen"]
        r[f"auto_{n}_wall_s"] = int(open(f"{out}/auto_{f}_{n}.wall_s").read())
        cells.append(cell(r[f"auto_{n}"]) + f" [{ft['chosen']}]")
    cells.append(cell(r["scratch_50"]))
    results[f] = r
    rows.append(f"| {f} | " + " | ".join(cells) + " |")
open(f"{out}/table.md", "w").write("\n".join(rows) + "\n")
json.dump(results, open(f"{out}/results.json", "w"), indent=1)
print("\n".join(rows))
PY
