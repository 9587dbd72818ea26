#!/usr/bin/env bash
# Corruption, measured: flips TRIALS random bytes (one per trial, xor a random
# nonzero mask) in the pages of a store of tests/data/cardinal_sphere.e at
# interval 4, reads each damaged copy back through the public API (every
# block with connectivity, every node and element by cursor, every table
# row, the sets) and counts the outcomes: identical (slack byte), Corrupt
# error (and whether it names the dataset and page), other error, page not
# read (a dataset no public read path touches; HDF5's own Fletcher32 check
# refuses it), DIFFERENT DATA (must be 0).
#
#   bash scripts/corruption.sh [TRIALS=1000]        (SEED=n, default 1; VERBOSE=1 lists every trial)
#
# Exit status: 0 when no trial read different data, 1 otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
TRIALS=${1:-1000}
SEED=${SEED:-1}
[[ "$TRIALS" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [TRIALS>0]" >&2; exit 2; }
if [[ ! -f build/CMakeCache.txt ]]; then
  bash scripts/build.sh >&2
fi
cmake --build build --target dicer corrupt_trials -j"$(nproc)" >/dev/null
WORK=$(mktemp -d "${TMPDIR:-/tmp}/dicer_corrupt.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
build/dicer dice tests/data/cardinal_sphere.e --interval 4 -o "$WORK/sphere.dice.h5" >/dev/null
args=("$WORK/sphere.dice.h5" "$TRIALS" "$SEED")
[[ -n "${VERBOSE:-}" ]] && args+=(--verbose)
echo "corruption: $TRIALS one-byte flips in the pages of cardinal_sphere.e diced at interval 4"
TMPDIR=$WORK build/tests/corrupt_trials "${args[@]}"
