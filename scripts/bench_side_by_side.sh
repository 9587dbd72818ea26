#!/usr/bin/env bash
# The side-by-side harness in one command (bench/README.md, "Side by side"):
# builds dicer and bench_side_by_side in build-bench/ (Release, one job: the
# machine is shared), runs every tool in its own process
# (scripts/bench_side_by_side.py, ~10 minutes with the defaults), writes
# bench/results/side_by_side.json, then the PNG and the numbers table of
# bench/README.md (scripts/bench_plot.py).
# Arguments go to bench_side_by_side.py (e.g. --reps 1, --intervals 2,5).
# DICER_SBS_SMOKE=1: a tiny box and one repetition, seconds, writes to /tmp
# (checks the plumbing, numbers meaningless).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build-bench -DCMAKE_BUILD_TYPE=Release -DDICER_BUILD_TESTS=OFF >/dev/null
cmake --build build-bench -j1 --target dicer bench_side_by_side
if [ "${DICER_SBS_SMOKE:-0}" = 1 ]; then
  out=/tmp/dicer-sbs-smoke.json
  /usr/bin/python3 scripts/bench_side_by_side.py --box 4,5,8 --intervals 2,4 --coarser-box 2,2,5 --coarser-interval 4 --store-interval 4 --reps 1 --no-cylinder --out "$out" "$@"
  /usr/bin/python3 scripts/bench_plot.py "$out" --png /tmp/dicer-sbs-smoke.png --no-readme
  exit 0
fi
/usr/bin/python3 scripts/bench_side_by_side.py "$@"
/usr/bin/python3 scripts/bench_plot.py bench/results/side_by_side.json
