#!/usr/bin/env bash
# Fuzzes the readers of untrusted files (fuzz/*_fuzz.cc: WAV, robot-log CSV, .npy, HDF5 dataset,
# YAML config) with libFuzzer under ASan + UBSan, SECONDS each, starting from a copy of the seed
# corpus (fuzz/corpus, left unchanged). Builds with Debian's clang-14 in build-fuzz/. Runs in
# libFuzzer's fork mode: every failing input (a crash: memory error, undefined behaviour, abort,
# leak; a timeout, 10 s; memory above 4 GB) is kept and the campaign goes on. The sanitizers write
# each report whole to OUT/<target>/reports/; each is put down to the code it happened in, ours
# or libhdf5's (whose format readers are not hardened against hostile files; docs/robustness.md),
# by its first stack frame outside the sanitizer runtime and libc. Prints a Markdown table
# (executions, corpus growth, crashes in our code, faults inside libhdf5, timeouts, out-of-memory
# inputs), writes it to OUT/report.md, and fails when our code crashed. The inputs land in
# OUT/<target>/crashes/ (crash-*, leak-*, timeout-*, oom-*). TARGETS="wav npy" picks targets.
#
# REPORT_ONLY=1 makes the table again from an earlier OUT without fuzzing.
#
# Usage: scripts/fuzz.sh [SECONDS=60] [OUT=build-fuzz/runs]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
SECONDS_EACH=${1:-60}
[ "$SECONDS_EACH" -ge 1 ] || { echo "fuzz.sh: SECONDS must be >= 1" >&2; exit 2; }
OUT=${2:-$ROOT/build-fuzz/runs}
BUILD=$ROOT/build-fuzz
read -r -a TARGETS <<<"${TARGETS:-wav robot_log npy dataset config}"
[ -n "${REPORT_ONLY:-}" ] || cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang-14 \
  -DCMAKE_CXX_COMPILER=clang++-14 -DSONICBOOM_FUZZ=ON -DSONICBOOM_BUILD_TESTS=OFF \
  -DSONICBOOM_BUILD_BENCH=OFF >/dev/null
[ -n "${REPORT_ONLY:-}" ] || cmake --build "$BUILD" -j"$(nproc)" --target "${TARGETS[@]/#/fuzz_}" >/dev/null
mkdir -p "$OUT"
report="| target | seconds | executions | corpus (seed -> end) | crashes in our code | faults inside libhdf5 | timeouts | out of memory |\n|---|---|---|---|---|---|---|---|\n"
total_crashes=0
for t in "${TARGETS[@]}"; do
  dir=$OUT/$t
  if [ -z "${REPORT_ONLY:-}" ]; then
    rm -rf "$dir"
    mkdir -p "$dir/corpus" "$dir/crashes" "$dir/reports"
    cp "$ROOT/fuzz/corpus/$t/"* "$dir/corpus/"
    set +e
    # the readers' own watchdog (SONICBOOM_READ_TIMEOUT_S) is off: libFuzzer times the inputs
    SONICBOOM_READ_TIMEOUT_S=0 \
      ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:log_path=$dir/reports/asan:suppressions=$ROOT/fuzz/asan_suppressions.txt" \
      LSAN_OPTIONS="suppressions=$ROOT/fuzz/lsan_suppressions.txt" \
      UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:log_path=$dir/reports/ubsan" \
      "$BUILD/bin/fuzz_$t" "$dir/corpus" -fork=1 -ignore_timeouts=1 -ignore_crashes=1 \
      -ignore_ooms=1 -max_total_time="$SECONDS_EACH" -max_len=262144 -timeout=10 \
      -rss_limit_mb=4096 -artifact_prefix="$dir/crashes/" >"$dir/log.txt" 2>&1
    set -e
  fi
  seeds=$(ls "$ROOT/fuzz/corpus/$t" | wc -l)
  # fork mode's last progress line: "#N: cov: .. exec/s: .. oom/timeout/crash: a/b/c time: .."
  last=$(grep -E '^#[0-9]+: cov:' "$dir/log.txt" | tail -n 1)
  execs=$(echo "$last" | sed -E 's/^#([0-9]+):.*/\1/')
  # each sanitizer report (a crash of a fork job) by the first stack frame outside the
  # sanitizer runtime and libc
  crashes=0
  library=0
  hung_in_library=0
  for r in "$dir/reports"/*; do
    [ -e "$r" ] || continue
    # a timeout: libFuzzer's alarm printed the stack of the input that ran too long
    if grep -q 'AlarmCallback' "$r"; then
      grep -E '^ +#[0-9]+ 0x' "$r" | grep -vE 'fuzzer::|libc\.so|__sanitizer' | head -n 1 |
        grep -q 'libhdf5' && hung_in_library=$((hung_in_library + 1))
      continue
    fi
    grep -qE 'ERROR: |runtime error' "$r" || continue
    frame=$(grep -E '^ +#[0-9]+ 0x' "$r" |
      grep -vE '__interceptor_|__sanitizer|__asan|__ubsan|__lsan|libc\.so|string/|sysdeps/|malloc|operator new' |
      head -n 1 || true)
    if echo "$frame" | grep -q 'libhdf5'; then library=$((library + 1)); else crashes=$((crashes + 1)); fi
  done
  timeouts=$(ls "$dir/crashes" | grep -c '^timeout-' || true)
  ooms=$(ls "$dir/crashes" | grep -c '^oom-' || true)
  total_crashes=$((total_crashes + crashes))
  end=$(ls "$dir/corpus" | wc -l)
  report+="| $t | $SECONDS_EACH | ${execs:-?} | $seeds -> $end | $crashes | $library | $timeouts ($hung_in_library in libhdf5) | $ooms |\n"
done
printf "%b" "$report" | tee "$OUT/report.md"
echo "crashes in our code: $total_crashes (logs in $OUT/<target>/log.txt)"
[ "$total_crashes" -eq 0 ]
