#!/usr/bin/env bash
# Crash safety, measured: sends SIGKILL, SIGINT, SIGTERM and SIGHUP to
# `dicer dice` and `dicer export` (msh, exodus, vtkhdf) at TRIALS uniformly
# random moments each and checks after every signal that
#   - the file under the final name is the pre-existing one, byte for byte,
#     or (the signal came after the rename) a complete new one;
#   - nothing else sits in the folder: for SIGKILL, apart from the killed
#     process's own temporary `.NAME.tmp-PID` (it cannot clean up; counted,
#     then removed before the next trial); for SIGINT, SIGTERM and SIGHUP,
#     nothing at all (dicer removes its temporary and exits);
#   - the exit status is 128 + the signal (137, 130, 143, 129), or 0 when
#     the command finished first (then the new file must be complete); a
#     signal that finds the new file in place may still end the process
#     (128 + signal), but dicer must not say "nothing written" then.
# Each trial is classified by what the folder shows afterwards: before the
# temporary file existed, during writing (temporary present, or for the
# catchable signals the old file intact with exit 128 + signal), after the
# rename (new file in place, process stopped), or finished before the signal.
#
#   bash scripts/crash_safety.sh [TRIALS=50] [SIGNALS="KILL INT TERM HUP"]
#   SEED=n for a fixed sequence; DICER=path for another binary (default
#   build/dicer). The test suite runs a short version (CrashSafety,
#   tests/CMakeLists.txt: 2 trials per command and signal).
#
# Exit status: 0 when no trial violated the contract, 1 otherwise.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
TRIALS=${1:-50}
SIGNALS=${2:-KILL INT TERM HUP}
[[ "$TRIALS" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [TRIALS>0] [SIGNALS]" >&2; exit 2; }
declare -A SIGNUM=([KILL]=9 [INT]=2 [TERM]=15 [HUP]=1)
for sig in $SIGNALS; do [[ -n ${SIGNUM[$sig]:-} ]] || { echo "unknown signal $sig (KILL INT TERM HUP)" >&2; exit 2; }; done
RANDOM=${SEED:-$$}

DICER=${DICER:-$ROOT/build/dicer}
if [[ ! -x "$DICER" ]]; then
  echo "build/dicer missing: building it with scripts/build.sh" >&2
  bash scripts/build.sh >&2 || exit 2
fi
MESH=$ROOT/tests/data/vtkdata_disk_out_ref.ex2
NEW_DICE_ELEMENTS=$((7472 * 343))   # interval 7

WORK=$(mktemp -d "${TMPDIR:-/tmp}/dicer_crash.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/pristine"
# A private copy of the binary: build/ is shared, and a relink during the run
# would make a trial fail to start (exit 126) rather than test anything.
cp "$DICER" "$WORK/dicer" && DICER=$WORK/dicer

sha() { sha256sum "$1" | cut -d' ' -f1; }
now_us() { echo $(( $(date +%s%N) / 1000 )); }
rand_u30() { echo $(( (RANDOM << 15) | RANDOM )); }

# Stores: OLD (interval 2) is what sits under the final names before each
# trial; SRC (interval 4) is what the killed exports write, so an old export
# and a new one are always distinguishable.
"$DICER" dice "$MESH" --interval 2 -o "$WORK/pristine/old.dice.h5" >/dev/null || exit 2
"$DICER" dice "$MESH" --interval 4 -o "$WORK/pristine/src.dice.h5" >/dev/null || exit 2
SRC=$WORK/pristine/src.dice.h5
declare -A EXT=([msh]=msh [exodus]=exo [vtkhdf]=vtkhdf)
declare -A DETERMINISTIC
for fmt in msh exodus vtkhdf; do
  "$DICER" export "$WORK/pristine/old.dice.h5" --format $fmt -o "$WORK/pristine/old.${EXT[$fmt]}" --quiet || exit 2
  "$DICER" export "$SRC" --format $fmt -o "$WORK/pristine/ref.${EXT[$fmt]}" --quiet || exit 2
done

# Are the writers deterministic? Every export must be: the same store
# exported a second later is the same bytes (the VTKHDF writer turns off
# HDF5's object times, which would otherwise differ). A store is not, by
# design: each has its own uuid.
sleep 1.1
for fmt in msh exodus vtkhdf; do
  "$DICER" export "$SRC" --format $fmt -o "$WORK/pristine/again.${EXT[$fmt]}" --quiet || exit 2
  if [[ $(sha "$WORK/pristine/again.${EXT[$fmt]}") == $(sha "$WORK/pristine/ref.${EXT[$fmt]}") ]]; then
    DETERMINISTIC[$fmt]=yes
  else
    DETERMINISTIC[$fmt]=no
  fi
  rm -f "$WORK/pristine/again.${EXT[$fmt]}"
done
"$DICER" dice "$MESH" --interval 7 -o "$WORK/pristine/a.dice.h5" >/dev/null || exit 2
"$DICER" dice "$MESH" --interval 7 -o "$WORK/pristine/b.dice.h5" >/dev/null || exit 2
sleep 1.1
"$DICER" dice "$MESH" --interval 7 -o "$WORK/pristine/b.dice.h5" >/dev/null || exit 2
if [[ $(sha "$WORK/pristine/a.dice.h5") == $(sha "$WORK/pristine/b.dice.h5") ]]; then DETERMINISTIC[dice]=yes; else DETERMINISTIC[dice]=no; fi
rm -f "$WORK/pristine/a.dice.h5" "$WORK/pristine/b.dice.h5"

# Is FILE a complete new output of kind KIND?
complete_new() {
  local kind=$1 file=$2
  case $kind in
    dice)
      "$DICER" verify "$file" --quiet >/dev/null 2>&1 || return 1
      "$DICER" info "$file" --json 2>/dev/null | grep -q "\"fine_elements\":$NEW_DICE_ELEMENTS[,}]" ;;
    msh|exodus|vtkhdf)
      [[ $(sha "$file") == $(sha "$WORK/pristine/ref.${EXT[$kind]}") ]] ;;
  esac
}

# Runs the command once to completion, returns its wall time in microseconds.
time_run() {
  local t0 t1
  t0=$(now_us)
  "$@" >/dev/null 2>&1
  t1=$(now_us)
  echo $((t1 - t0))
}

declare -A BEFORE DURING AFTER FINISHED VIOL LEFTOVER DUR_US
TOTAL_VIOL=0

command_for() {  # KIND DIR NAME -> the array CMD
  local kind=$1 dir=$2 name=$3
  if [[ $kind == dice ]]; then
    CMD=("$DICER" dice "$MESH" --interval 7 -o "$dir/$name")
  else
    CMD=("$DICER" export "$SRC" --format "$kind" -o "$dir/$name" --quiet)
  fi
}

run_kind() {
  local kind=$1 sig=$2 dir=$WORK/$1 name old key=$1/$2
  local signum=${SIGNUM[$sig]}
  mkdir -p "$dir"
  if [[ $kind == dice ]]; then
    name=out.dice.h5; old=$WORK/pristine/old.dice.h5
  else
    name=out.${EXT[$kind]}; old=$WORK/pristine/old.${EXT[$kind]}
  fi
  command_for "$kind" "$dir" "$name"
  local -a cmd=("${CMD[@]}")
  local old_sha; old_sha=$(sha "$old")
  # Duration: median of three complete runs (once per command).
  if [[ -z ${DUR_US[$kind]:-} ]]; then
    local d1 d2 d3
    d1=$(time_run "${cmd[@]}"); d2=$(time_run "${cmd[@]}"); d3=$(time_run "${cmd[@]}")
    DUR_US[$kind]=$(printf '%s\n' "$d1" "$d2" "$d3" | sort -n | sed -n 2p)
  fi
  local span=$((DUR_US[$kind] * 12 / 10))
  BEFORE[$key]=0; DURING[$key]=0; AFTER[$key]=0; FINISHED[$key]=0; VIOL[$key]=0; LEFTOVER[$key]=0
  for ((t = 1; t <= TRIALS; t++)); do
    rm -rf "${dir:?}"/* "$dir"/.[!.]* 2>/dev/null
    cp "$old" "$dir/$name"
    local delay_us=$(( $(rand_u30) % (span + 1) ))
    local delay; delay=$(printf '%d.%06d' $((delay_us / 1000000)) $((delay_us % 1000000)))
    # A background job of a script starts with SIGINT ignored: reset, so
    # the command sees the signals a terminal or a batch system sends.
    env --default-signal=INT,TERM,HUP "${cmd[@]}" >/dev/null 2>"$WORK/trial.err" &
    local pid=$!
    sleep "$delay"
    kill -"$sig" "$pid" 2>/dev/null
    { wait "$pid"; } 2>/dev/null
    local rc=$?
    local problems=() temp_seen=0 entry
    # Every entry of the folder: the final name, the killed writer's own
    # temporary (SIGKILL only), or a violation.
    shopt -s nullglob dotglob
    for entry in "$dir"/*; do
      entry=${entry##*/}
      if [[ $entry == "$name" ]]; then continue
      elif [[ $sig == KILL && $entry == ".$name.tmp-$pid" ]]; then temp_seen=1
      elif [[ $entry == ".$name.tmp-$pid" ]]; then problems+=("temporary $entry left after SIG$sig")
      else problems+=("stray file $entry")
      fi
    done
    shopt -u nullglob dotglob
    local phase
    if [[ ! -f "$dir/$name" ]]; then
      problems+=("nothing under the final name")
      phase=BEFORE
    elif [[ $(sha "$dir/$name") == "$old_sha" ]]; then
      if ((temp_seen)) || [[ $sig != KILL && $rc == $((128 + signum)) ]]; then phase=DURING; else phase=BEFORE; fi
      ((rc == 0)) && problems+=("exited 0 but the old file is still in place")
    else
      if complete_new "$kind" "$dir/$name"; then :; else problems+=("final file is neither the old one nor a complete new one"); fi
      if ((temp_seen)); then phase=DURING; problems+=("temporary left beside a renamed file")
      elif ((rc == 0)); then phase=FINISHED
      else
        phase=AFTER
        grep -q 'nothing written' "$WORK/trial.err" && problems+=("the new file is in place, yet dicer said: $(cat "$WORK/trial.err")")
      fi
    fi
    ((rc != 0 && rc != 128 + signum)) && problems+=("exit status $rc (expected $((128 + signum)) or 0)")
    case $phase in
      BEFORE) BEFORE[$key]=$((BEFORE[$key] + 1)) ;;
      DURING) DURING[$key]=$((DURING[$key] + 1)) ;;
      AFTER) AFTER[$key]=$((AFTER[$key] + 1)) ;;
      FINISHED) FINISHED[$key]=$((FINISHED[$key] + 1)) ;;
    esac
    ((temp_seen)) && LEFTOVER[$key]=$((LEFTOVER[$key] + 1))
    if ((${#problems[@]})); then
      VIOL[$key]=$((VIOL[$key] + 1)); TOTAL_VIOL=$((TOTAL_VIOL + 1))
      printf 'VIOLATION %s SIG%s trial %d (signal at %s s, exit %d): %s\n' "$kind" "$sig" "$t" "$delay" "$rc" \
        "$(IFS=';'; echo "${problems[*]}")"
      cp "$dir/$name" "$WORK/violation_${kind}_${sig}_$t" 2>/dev/null
    fi
  done
  rm -rf "${dir:?}"
}

for kind in dice msh exodus vtkhdf; do
  for sig in $SIGNALS; do
    echo "SIG$sig to $kind, $TRIALS times..." >&2
    run_kind "$kind" "$sig"
  done
done

echo
echo "crash safety: $TRIALS trials per command and signal, each at a uniform random moment in [0, 1.2 x run time]"
printf '%-8s %-7s %8s %8s %8s %8s %8s %9s %9s %10s\n' command signal run_ms before during after finished leftover violations byte-determ
for kind in dice msh exodus vtkhdf; do
  for sig in $SIGNALS; do
    key=$kind/$sig
    printf '%-8s %-7s %8d %8d %8d %8d %8d %9d %9d %10s\n' "$kind" "SIG$sig" $((DUR_US[$kind] / 1000)) "${BEFORE[$key]}" \
      "${DURING[$key]}" "${AFTER[$key]}" "${FINISHED[$key]}" "${LEFTOVER[$key]}" "${VIOL[$key]}" "${DETERMINISTIC[$kind]}"
  done
done
cat <<'EOF2'
  before: stopped before the temporary existed (old file intact)
  during: stopped while writing (SIGKILL: temporary .NAME.tmp-PID present; SIGINT/TERM/HUP:
          exit 128 + signal, temporary removed), old file intact
  after:  stopped after the rename (a complete new file in place; never "nothing written")
  finished: the run ended before the signal (complete new file, exit 0)
  leftover: temporaries SIGKILL left behind (removed between trials; any other is a violation)
  new files: dice = `verify --quiet` exit 0 + interval-7 element count; msh, exodus,
  vtkhdf = sha256 of a reference export
  (byte-determ: whether two runs a second apart give the same bytes; every export must)
EOF2
for fmt in msh exodus vtkhdf; do
  if [[ ${DETERMINISTIC[$fmt]} != yes ]]; then
    echo "violation: two $fmt exports of one store a second apart differ"
    TOTAL_VIOL=$((TOTAL_VIOL + 1))
  fi
done
if ((TOTAL_VIOL)); then
  echo "FAILED: $TOTAL_VIOL violation(s)"
  exit 1
fi
echo "OK: no violation"
