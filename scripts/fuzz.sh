#!/usr/bin/env bash
# Fuzzes the readers of untrusted files (fuzz/*_fuzz.cc: WAV, robot-log CSV, .npy, HDF5 dataset,
# YAML config) with libFuzzer under ASan + UBSan, SECONDS each, starting from a copy of the seed
# corpus (fuzz/corpus, left unchanged). Builds with Debian's clang-14 in build-fuzz/. Runs in
# libFuzzer's fork mode, so that an input on which a library loops (a timeout, 10 s) is recorded
# and the campaign goes on; a crash (memory error, undefined behaviour, abort, leak) ends it.
# Prints a Markdown table (executions, corpus growth, crashes, timeouts) and writes it to
# OUT/report.md; the inputs land in OUT/<target>/crashes/ (crash-*, leak-*, timeout-*).
#
# Usage: scripts/fuzz.sh [SECONDS=60] [OUT=build-fuzz/runs]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SECONDS_EACH=${1:-60}
[ "$SECONDS_EACH" -ge 1 ] || { echo "fuzz.sh: SECONDS must be >= 1" >&2; exit 2; }
OUT=${2:-$ROOT/build-fuzz/runs}
BUILD=$ROOT/build-fuzz
TARGETS=(wav robot_log npy dataset config)
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang-14 \
  -DCMAKE_CXX_COMPILER=clang++-14 -DSONICBOOM_FUZZ=ON -DSONICBOOM_BUILD_TESTS=OFF \
  -DSONICBOOM_BUILD_BENCH=OFF >/dev/null
cmake --build "$BUILD" -j"$(nproc)" --target "${TARGETS[@]/#/fuzz_}" >/dev/null
mkdir -p "$OUT"
report="| target | seconds | executions | corpus (seed -> end) | crashes | timeouts |\n|---|---|---|---|---|---|\n"
total_crashes=0
for t in "${TARGETS[@]}"; do
  dir=$OUT/$t
  rm -rf "$dir"
  mkdir -p "$dir/corpus" "$dir/crashes"
  cp "$ROOT/fuzz/corpus/$t/"* "$dir/corpus/"
  seeds=$(ls "$dir/corpus" | wc -l)
  set +e
  # the readers' own watchdog (SONICBOOM_READ_TIMEOUT_S) is off: libFuzzer times the inputs
  SONICBOOM_READ_TIMEOUT_S=0 ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$BUILD/bin/fuzz_$t" "$dir/corpus" -fork=1 -ignore_timeouts=1 -ignore_crashes=0 \
    -ignore_ooms=0 -max_total_time="$SECONDS_EACH" -max_len=262144 -timeout=10 \
    -rss_limit_mb=4096 -artifact_prefix="$dir/crashes/" >"$dir/log.txt" 2>&1
  set -e
  # fork mode's last progress line: "#N: cov: .. exec/s: .. oom/timeout/crash: a/b/c time: .."
  last=$(grep -E '^#[0-9]+: cov:' "$dir/log.txt" | tail -n 1)
  execs=$(echo "$last" | sed -E 's/^#([0-9]+):.*/\1/')
  crashes=$(ls "$dir/crashes" | grep -cv '^timeout-' || true)
  timeouts=$(ls "$dir/crashes" | grep -c '^timeout-' || true)
  total_crashes=$((total_crashes + crashes))
  end=$(ls "$dir/corpus" | wc -l)
  report+="| $t | $SECONDS_EACH | ${execs:-?} | $seeds -> $end | $crashes | $timeouts |\n"
done
printf "%b" "$report" | tee "$OUT/report.md"
echo "crashes: $total_crashes (logs in $OUT/<target>/log.txt; timeouts are inputs on which a library loops)"
[ "$total_crashes" -eq 0 ]
