#!/usr/bin/env bash
# The scenario study's GCC-PHAT span chosen on validation strikes only (issue 34's honest
# protocol), then the chosen model scored once on the test sets. Candidates: the latency profile
# (configs/study_fast.yaml) with GCC-PHAT over the whole 1.5 s window, and over its centre 1 s.
# Each is trained on the same TRAIN ts1 strikes (scripts/med_study.sh, datasets shared in
# OUT/data) and evaluated on VAL = TEST validation strikes per scenario (indices from 200000);
# the span with the lower mean validation MED over ts1-ts4 wins, and only its run goes on to the
# test sets (indices from 100000). The epochs stay the profile's 60; the table reports each
# candidate's validation MED (on its own ts1 split) at epochs 20, 40 and 60 from metrics.jsonl.
#
# Usage: scripts/scenario_selection.sh OUT [TRAIN=3000] [TEST=400] [THREADS=2]
# Writes OUT/selection.md (validation table and choice) and OUT/<candidate>/table.md (test).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scenario_selection.sh OUT [TRAIN] [TEST] [THREADS]}
TRAIN=${2:-3000}
TEST=${3:-400}
THREADS=${4:-2}
mkdir -p "$OUT"
declare -A SPAN=([whole]=0.0 [centre1s]=1.0)
for c in whole centre1s; do
  DATA="$OUT/data" VAL="$TEST" STAGE=val BASELINES="" \
    MODEL_SET="--set features.gcc_window_s=${SPAN[$c]}" \
    bash "$ROOT/scripts/med_study.sh" "$OUT/$c" "$TRAIN" "$TEST" "$THREADS" \
    "$ROOT/configs/study_fast.yaml"
done
chosen=$(/usr/bin/python3 - "$OUT" <<'PY'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
spans = {"whole": "1.5 (whole window)", "centre1s": "1.0 (centre)"}
rows, mean = [], {}
for c in ["whole", "centre1s"]:
    meds = [json.loads((out / c / f"val_{ts}.json").read_text())["med_cm"] for ts in
            ["ts1", "ts2", "ts3", "ts4"]]
    mean[c] = sum(meds) / 4
    curve = [json.loads(l) for l in (out / c / "model" / "metrics.jsonl").read_text().splitlines()
             if l.strip()]
    at = {e["epoch"]: e.get("val", {}).get("med_cm") for e in curve}
    ep = " / ".join("%.2f" % at[k] if at.get(k) is not None else "–" for k in (20, 40, 60))
    rows.append(f"| {spans[c]} | " + " | ".join("%.2f" % m for m in meds) +
                f" | {mean[c]:.2f} | {ep} |")
best = min(mean, key=mean.get)
text = ["| GCC span (s) | val ts1 | val ts2 | val ts3 | val ts4 | mean | own ts1 split, epoch 20 / 40 / 60 |",
        "|---|---|---|---|---|---|---|"] + rows + ["", f"Chosen on validation: {spans[best]}."]
(out / "selection.md").write_text("\n".join(text) + "\n")
print("\n".join(text), file=sys.stderr)
print(best)
PY
)
DATA="$OUT/data" VAL="$TEST" MODEL_SET="--set features.gcc_window_s=${SPAN[$chosen]}" \
  bash "$ROOT/scripts/med_study.sh" "$OUT/$chosen" "$TRAIN" "$TEST" "$THREADS" \
  "$ROOT/configs/study_fast.yaml"
