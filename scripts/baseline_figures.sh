#!/usr/bin/env bash
# docs/baselines.md, "Figures": the baselines on held-out strikes of the default config (MuJoCo
# strikes on the seamed tube): 300 training strikes (indices 0-299), 200 test (300-499) and 200
# validation strikes (500-699) on which the kNN settings are chosen, never on the test. Each row
# is one `sonicboom baseline` on the test set with its wall time.
#   scripts/baseline_figures.sh OUT [THREADS=2]
# Resumable: finished datasets and results are reused. Output: OUT/table.md, OUT/results.json.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
OUT=${1:?usage: scripts/baseline_figures.sh OUT [THREADS]}
THREADS=${2:-2}
mkdir -p "$OUT"

gen() {  # name first count
  [ -f "$OUT/$1.h5" ] || "$BIN" --threads "$THREADS" -q generate --first-index "$2" --count "$3" \
    --out "$OUT/$1.h5" --json > /dev/null
}
gen train 0 300
gen test 300 200
gen val 500 200

run() {  # name data args...: OUT/<name>.json with its wall time in seconds
  local name=$1 data=$2; shift 2
  [ -f "$OUT/$name.json" ] && return
  local start end
  start=$(date +%s.%N)
  "$BIN" --threads "$THREADS" -q baseline "$@" --data "$OUT/$data.h5" --json > "$OUT/$name.partial"
  end=$(date +%s.%N)
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); d['wall_s']=float(sys.argv[3])-float(sys.argv[2]); json.dump(d,open(sys.argv[4],'w'))" \
    "$OUT/$name.partial" "$start" "$end" "$OUT/$name.json"
  rm "$OUT/$name.partial"
}
# the kNN settings, on the validation strikes
for k in 1 3 5 10; do
  run "val_knn_mel_k$k" val --method knn --k "$k" --train "$OUT/train.h5"
  run "val_knn_gcc_k$k" val --method knn --k "$k" --gcc-lags 441 --train "$OUT/train.h5"
done
# the chosen settings (lowest validation MED of each feature set), then the test rows
best() {  # prefix: the k of the lowest validation MED
  /usr/bin/python3 -c "
import json, sys
ks = [1, 3, 5, 10]
med = {k: json.load(open('$OUT/val_$1_k%d.json' % k))['med_cm'] for k in ks}
print(min(ks, key=lambda k: (med[k], k)))"
}
KMEL=$(best knn_mel)
KGCC=$(best knn_gcc)
TDOA=(--method tdoa --train "$OUT/train.h5")
run constant test --method constant --train "$OUT/train.h5"
run knn_mel test --method knn --k "$KMEL" --train "$OUT/train.h5"
run knn_gcc test --method knn --k "$KGCC" --gcc-lags 441 --train "$OUT/train.h5"
run tdoa_fitted test "${TDOA[@]}"
run tdoa_one_speed test "${TDOA[@]}" --non-dispersive
run tdoa_bands test "${TDOA[@]}" --bands 1000,2000,4000,8000
run tdoa_bands_one_speed test "${TDOA[@]}" --bands 1000,2000,4000,8000 --non-dispersive
run tdoa_no_seams test "${TDOA[@]}" --set shell.ideal=true
run arrival test --method arrival

/usr/bin/python3 - "$OUT" "$KMEL" "$KGCC" <<'PY'
import json, sys
out, kmel, kgcc = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def load(name):  # a run's JSON, or "run/key" for a figure nested in it
    run, _, key = name.partition("/")
    r = json.load(open(f"{out}/{run}.json"))
    return r[key] if key else r
rows = [("constant", "constant", "--method constant --train train.h5"),
        ("knn_mel", f"kNN, mel only, k = {kmel}", f"--method knn --k {kmel} --train train.h5"),
        ("knn_gcc", f"kNN, mel + all GCC lags, k = {kgcc}",
         f"--method knn --k {kgcc} --gcc-lags 441 --train train.h5"),
        ("tdoa_fitted/analytic", "TDOA, analytic plate speeds", "(`analytic` of the next row)"),
        ("tdoa_fitted", "TDOA, fitted speed scale", "--method tdoa --train train.h5"),
        ("tdoa_one_speed/analytic", "TDOA, one speed, analytic", "(`analytic` of the next row)"),
        ("tdoa_one_speed", "TDOA, one speed, fitted", "... --non-dispersive"),
        ("tdoa_bands", "TDOA, 1–8 kHz bands, fitted", "... --bands 1000,2000,4000,8000"),
        ("tdoa_bands_one_speed", "TDOA, 1–8 kHz, one speed, fitted",
         "... --bands 1000,2000,4000,8000 --non-dispersive"),
        ("tdoa_no_seams", "TDOA, no seams in the path model", "... --set shell.ideal=true"),
        ("arrival", "arrival locator (no training)", "--method arrival")]
lines = ["| baseline | command (after `sonicboom baseline`, with `--data test.h5`) | MED cm | "
         "height cm | angle ° | wall (s) |", "|---|---|---|---|---|---|"]
results = {}
for name, label, cmd in rows:
    r = load(name)
    scale = r.get("speed_scale")
    if scale is not None and "fitted" in label:
        label += f" ({scale:.3f})"
    cell = cmd if cmd.startswith("(") else f"`{cmd}`"
    lines.append(f"| {label} | {cell} | {r['med_cm']:.2f} | {r['height_err_cm']:.2f} | "
                 f"{r['angle_err_deg']:.1f} | {'%.0f' % r['wall_s'] if 'wall_s' in r else '–'} |")
    results[name.replace("/", "_")] = r
val = {f"{feat}_k{k}": load(f"val_knn_{feat}_k{k}")["med_cm"] for feat in ("mel", "gcc")
       for k in (1, 3, 5, 10)}
lines += ["", "kNN validation MED (cm; chooses k): " +
          ", ".join(f"{key} {v:.2f}" for key, v in val.items()),
          "", "`...` stands for `--method tdoa --train train.h5`; 200 test strikes (indices "
          "300-499), 300 training (0-299)."]
results["knn_validation_med_cm"] = val
open(f"{out}/table.md", "w").write("\n".join(lines) + "\n")
json.dump(results, open(f"{out}/results.json", "w"), indent=1)
print("\n".join(lines))
PY
