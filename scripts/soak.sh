#!/usr/bin/env bash
# Memory of long generations: generates each COUNT of strikes of the default robot scene with
# THREADS threads and prints the peak resident memory (GNU time's maximum RSS) and the wall time
# of each, so that a longer run can be seen to need no more memory. The datasets are removed.
#
# Usage: scripts/soak.sh OUT [THREADS=2] COUNT...      (e.g. scripts/soak.sh /tmp/soak 2 2000 20000)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:?usage: scripts/soak.sh OUT [THREADS] COUNT...}
THREADS=${2:-2}
shift 2
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
mkdir -p "$OUT"
echo "| strikes | peak RSS (MB) | wall (s) | file (MB) |"
echo "|---|---|---|---|"
for count in "$@"; do
  rm -f "$OUT/soak.h5" "$OUT/soak.h5.config.yaml"
  /usr/bin/time -v "$BIN" -q --threads "$THREADS" generate --count "$count" --out "$OUT/soak.h5" \
    >/dev/null 2>"$OUT/time-$count.txt"
  rss_kb=$(grep 'Maximum resident set size' "$OUT/time-$count.txt" | awk '{print $NF}')
  wall=$(grep 'Elapsed (wall clock)' "$OUT/time-$count.txt" | awk '{print $NF}')
  size=$(du -m "$OUT/soak.h5" | cut -f1)
  echo "| $count | $((rss_kb / 1024)) | $wall | $size |"
  rm -f "$OUT/soak.h5" "$OUT/soak.h5.config.yaml"
done
