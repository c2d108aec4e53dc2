#!/usr/bin/env bash
# Behaviour fingerprint of the generator and the feature stage, for refactors that must change
# nothing: COUNT strikes generated under every config in configs/ (each alone over the defaults,
# and configs/randomized.yaml over ts4), and the features of the default dataset under each, as
# content digests (scripts/h5_digest.py: every array and attribute but the creation time).
# Run it before and after a change and compare: diff BEFORE/digests.txt AFTER/digests.txt.
#
# Usage: scripts/identity_check.sh OUT [COUNT=6] [THREADS=2]   Output: OUT/digests.txt
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/identity_check.sh OUT [COUNT] [THREADS]}
COUNT=${2:-6}
THREADS=${3:-2}
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
rm -f "$OUT"/*.h5 "$OUT"/*.config.yaml "$OUT/digests.txt"
# relative paths inside OUT: a features file records its input's path as given
cd "$OUT"

# name -> config arguments
cases() {
  echo "default"
  for f in "$ROOT"/configs/*.yaml "$ROOT"/configs/ablations/*.yaml; do
    echo "${f#"$ROOT"/configs/}"
  done
  echo "ts4+randomized"
}
args_of() {
  case $1 in
    default) ;;
    ts4+randomized) echo "--config $ROOT/configs/ts4.yaml --config $ROOT/configs/randomized.yaml" ;;
    *) echo "--config $ROOT/configs/$1" ;;
  esac
}
"$BIN" -q --threads "$THREADS" generate --count "$COUNT" --out gen_default.h5
while read -r name; do
  tag=${name//\//_}
  tag=${tag%.yaml}
  # shellcheck disable=SC2046
  [ "$name" = default ] || "$BIN" -q --threads "$THREADS" $(args_of "$name") generate \
    --count "$COUNT" --out "gen_$tag.h5"
  # shellcheck disable=SC2046
  "$BIN" -q --threads "$THREADS" $(args_of "$name") features --in gen_default.h5 \
    --out "feat_$tag.h5"
done < <(cases)
/usr/bin/python3 "$ROOT/scripts/h5_digest.py" gen_*.h5 feat_*.h5 > digests.txt
wc -l < digests.txt
