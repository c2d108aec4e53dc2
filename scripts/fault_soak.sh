#!/usr/bin/env bash
# A soak under faults: for SECONDS, runs generate, train, merge, import and features with random
# kill -9, a full disk (a 3 MB tmpfs, where it can be mounted) and two writers of one output, and
# after every step checks that
#   - every output under its final name is complete (`inspect` says so; a run has its model),
#   - every input is unchanged (sha256),
#   - no command crashed (a signal it was not sent, or exit 3: an internal error),
#   - every .partial left behind is resumed (the same command again finishes) or refused with
#     exit 1, never crashes.
# Prints a summary line per kind of step and the totals; exit 1 if any check failed.
#
#   scripts/fault_soak.sh [SECONDS=600] [WORK=/tmp/sonicboom-soak] [SEED=1]
# SONICBOOM overrides the binary (default build/bin/sonicboom).
set -u
SECONDS_TOTAL=${1:-600}
WORK=${2:-/tmp/sonicboom-soak}
RANDOM=${3:-1}
SB=$(readlink -f "${SONICBOOM:-build/bin/sonicboom}")
[ -x "$SB" ] || { echo "error: $SB: not built" >&2; exit 2; }
SHORT="--set audio.record_duration_s=0.6 --set audio.onset_time_s=0.25 -q --threads 1"
TINY="--set model.width=16 --set model.blocks=1 --set model.heads=2 --set train.batch_size=8"

rm -rf "$WORK" && mkdir -p "$WORK/in" "$WORK/out" "$WORK/disk" && cd "$WORK" || exit 2
# a copy of the binary: a rebuild during the soak must not be mistaken for a fault
cp "$SB" "$WORK/sonicboom" && SB="$WORK/sonicboom"
log() { echo "$*" >> soak.log; }

# fixtures: the inputs every step reads, and their checksums
$SB $SHORT generate --count 24 --out in/D.h5 || exit 2
$SB $SHORT generate --count 16 --shard 0 --num-shards 2 --out in/S0.h5 || exit 2
$SB $SHORT generate --count 16 --shard 1 --num-shards 2 --out in/S1.h5 || exit 2
$SB -q export --layout trial --in in/D.h5 --out in/TR || exit 2
find in -type f -print0 | sort -z | xargs -0 sha256sum > inputs.sha

# a tmpfs for full-disk steps where it can be mounted
DISK=""
if mount -t tmpfs -o size=3m tmpfs "$WORK/disk" 2>/dev/null; then
  DISK="$WORK/disk"
  trap 'umount -l "$WORK/disk" 2>/dev/null' EXIT
fi

declare -A RUNS KILLED CRASHES
INCOMPLETE=0; LOST=0; CRASHED=0; UNRESUMABLE=0; STEPS=0

# the command of a step kind writing OUT
command_for() {
  local kind=$1 out=$2
  case $kind in
    generate) echo "$SB $SHORT generate --count $((20 + RANDOM % 60)) --out $out" ;;
    train) echo "$SB $SHORT $TINY --set train.epochs=$((1 + RANDOM % 3)) train --data in/D.h5 --out $out" ;;
    merge) echo "$SB -q merge --out $out in/S0.h5 in/S1.h5" ;;
    import) echo "$SB -q import --layout trial --min-duration-s 0.5 --in in/TR --out $out" ;;
    features) echo "$SB $SHORT features --in in/D.h5 --out $out" ;;
  esac
}

# exit status of a command that was not killed: 0 or 1 (a refusal), anything else a crash
judge() {
  local status=$1 what=$2
  if [ "$status" -ne 0 ] && [ "$status" -ne 1 ]; then
    CRASHED=$((CRASHED + 1)); CRASHES[$what]=$(( ${CRASHES[$what]:-0} + 1 ))
    log "CRASH exit $status: $what"
  fi
}

check_outputs() {
  local f
  for f in out/*.h5 disk/*.h5; do
    [ -e "$f" ] || continue
    if ! $SB --json inspect "$f" 2>/dev/null | grep -q '"complete":true'; then
      INCOMPLETE=$((INCOMPLETE + 1)); log "INCOMPLETE under its final name: $f"
    fi
  done
  for f in out/run*; do
    case $f in *.partial|*.lock|*.replaced) continue ;; esac
    [ -d "$f" ] || continue
    if [ ! -f "$f/model.json" ] && [ ! -f "$f/ensemble.json" ]; then
      INCOMPLETE=$((INCOMPLETE + 1)); log "INCOMPLETE run under its final name: $f"
    fi
  done
  if ! sha256sum --quiet -c inputs.sha > /dev/null 2>&1; then
    LOST=$((LOST + 1)); log "INPUT CHANGED after step $STEPS"
    find in -type f -print0 | sort -z | xargs -0 sha256sum > inputs.sha
  fi
}

end=$((SECONDS + SECONDS_TOTAL))
while [ $SECONDS -lt $end ]; do
  STEPS=$((STEPS + 1))
  kinds=(generate train merge import features concurrent)
  [ -n "$DISK" ] && kinds+=(fulldisk)
  kind=${kinds[$((RANDOM % ${#kinds[@]}))]}
  RUNS[$kind]=$(( ${RUNS[$kind]:-0} + 1 ))
  case $kind in
    concurrent)
      # two writers of one output: one finishes, the other refuses; never a mixed file
      out=out/C$((RANDOM % 3)).h5
      cmd=$(command_for generate "$out")
      $cmd --force >>soak.out 2>>soak.err & a=$!
      sleep 0.$((RANDOM % 9)); $cmd --force >>soak.out 2>>soak.err & b=$!
      wait $a; sa=$?; wait $b; sb=$?
      judge $sa concurrent; judge $sb concurrent
      ;;
    fulldisk)
      rm -rf disk/* 2>/dev/null
      head -c $(( (1500 + RANDOM % 1400) * 1024 )) /dev/zero > disk/fill 2>/dev/null
      sub=(generate merge import features)
      k=${sub[$((RANDOM % 4))]}
      $(command_for "$k" disk/F.h5) >>soak.out 2>>soak.err; judge $? "fulldisk $k"
      ;;
    *)
      # a step of one kind, killed at a random moment seven times in ten
      if [ "$kind" = train ]; then out=out/run$((RANDOM % 3)); else out=out/$kind$((RANDOM % 3)).h5; fi
      cmd=$(command_for "$kind" "$out")
      [ -e "$out" ] && cmd="$cmd --force"
      $cmd >>soak.out 2>>soak.err & pid=$!
      if [ $((RANDOM % 10)) -lt 7 ]; then
        # merge and import take under a second, generate and train seconds
        if [ "$kind" = merge ] || [ "$kind" = import ]; then
          sleep "0.$((RANDOM % 10))$((RANDOM % 10))"
        else
          sleep "$((RANDOM % 3)).$((RANDOM % 10))"
        fi
        if kill -9 $pid 2>/dev/null; then
          KILLED[$kind]=$(( ${KILLED[$kind]:-0} + 1 ))
        fi
        wait $pid 2>/dev/null
        # what the kill left is resumed or refused: the same command again (train: --resume)
        if [ -e "$out.partial" ]; then
          if [ "$kind" = train ]; then
            $SB $SHORT $TINY --set train.epochs=3 train --data in/D.h5 --out "$out" --resume >>soak.out 2>>soak.err
          else
            $cmd >>soak.out 2>>soak.err
          fi
          s=$?; judge $s "resume $kind"
          [ $s -eq 0 ] || [ $s -eq 1 ] || UNRESUMABLE=$((UNRESUMABLE + 1))
        fi
      else
        wait $pid; judge $? "$kind"
      fi
      ;;
  esac
  check_outputs
done

for kind in "${!RUNS[@]}"; do
  echo "$kind: ${RUNS[$kind]} steps, ${KILLED[$kind]:-0} killed, ${CRASHES[$kind]:-0} crashes"
done | sort
echo "steps $STEPS in ${SECONDS_TOTAL} s (full disk: ${DISK:-not mountable}); incomplete files under final names $INCOMPLETE; inputs changed $LOST; crashes $CRASHED; partials neither resumed nor refused $UNRESUMABLE"
[ $INCOMPLETE -eq 0 ] && [ $LOST -eq 0 ] && [ $CRASHED -eq 0 ] && [ $UNRESUMABLE -eq 0 ]
