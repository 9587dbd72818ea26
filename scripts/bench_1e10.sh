#!/usr/bin/env bash
# The 10^10 run (bench/README.md, "10^10 fine elements"): dices
# tests/data/vtkdata_disk_out_ref.ex2 at interval 112 (1.05e10 fine
# elements), sweeps every fine node and element in 2 threads under a
# 256 MiB cache and answers 1e6 random node and element queries; writes
# bench/results/run_1e10.json, then refreshes the PNG and README tables.
# ~10-20 minutes on 2 cores (the sweep). Arguments go to bench_1e10.py
# (e.g. --interval 52 for a 1e9 rehearsal, --skip-sweep).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build-bench -DCMAKE_BUILD_TYPE=Release -DDICER_BUILD_TESTS=OFF >/dev/null
cmake --build build-bench -j1 --target dicer bench_side_by_side
/usr/bin/python3 scripts/bench_1e10.py "$@"
if [ -f bench/results/side_by_side.json ]; then
  /usr/bin/python3 scripts/bench_plot.py bench/results/side_by_side.json
fi
