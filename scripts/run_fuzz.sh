#!/usr/bin/env bash
# libFuzzer runs of dicer's input-facing code (clang from Debian, ASan + UBSan).
#
#   bash scripts/run_fuzz.sh TARGET SECONDS [extra libFuzzer args]
#   bash scripts/run_fuzz.sh fuzz_msh 600
#   bash scripts/run_fuzz.sh fuzz_page 600 -jobs=2 -workers=2
#   bash scripts/run_fuzz.sh fuzz_store 600 -max_len=512
#   DICER_JOBS=1 bash scripts/run_fuzz.sh ...     limit build parallelism
#
# Targets (bodies in tests/fuzz/fuzz_entries.cpp, shared with the
# FuzzRegressions tests of dicer_tests):
#   fuzz_msh    the MSH reader path: bytes -> file -> read_coarse_mesh (MSH 2.2
#               and 4.1, ASCII and binary, then validate_coarse_mesh); a mesh of
#               <= 2000 elements is then diced at interval 1 and verified
#               (counts, id round trips, bit identity). Inputs with netCDF/HDF5
#               magic (the Exodus reader, i.e. netCDF's parser) are skipped.
#   fuzz_exodus the Exodus reader path through Debian's netCDF and Exodus
#               libraries: bytes -> file -> read_coarse_mesh (our netCDF
#               header check, the Exodus layout audit, the getters, then
#               validate_coarse_mesh); small meshes are diced and verified as
#               in fuzz_msh. Only netCDF classic/64-bit offset/CDF-5 inputs
#               ("CDF" 1, 2, 5) are read; HDF5-based netCDF-4 files are not
#               fuzzed (HDF5 1.10 does not survive damaged metadata).
#               Seeds: tests/data/cardinal_sphere.e (CUBIT, CDF-2) and three
#               small files written with the Exodus library (two hexes with
#               named block, side set, node set and id maps, as CDF-2 and, via
#               python3-netCDF4, CDF-5; two SHELL4 quads with a BAR2 block and
#               an edge side set, CDF-1 "normal model" with the combined
#               coord variable).
#   fuzz_page   the page decoder: filter 32004 (LZ4) layout + Fletcher32, via
#               store::decode_page; once as given, once with the size field and
#               checksum fixed up (reaches the LZ4 layout and data checks), and
#               an encode_page/decode_page round trip that must be exact.
#   fuzz_store  the store opener, two kinds of input:
#               - a whole file (it starts with the HDF5 signature): written as
#                 is and read like a store (read_store, a fill_block sweep,
#                 node/element queries, read_store_sets). Everything is
#                 fuzzed, HDF5's own metadata included (superblock, object
#                 headers, chunk indexes, attributes); only dicer::Error may
#                 come out. Seeds: three small real stores (whole_*.dice.h5).
#               - otherwise a list of 5-byte edits (LE32 offset, XOR byte)
#                 applied only inside the byte ranges of the chunks (the LZ4
#                 pages) of a small real store (cardinal_sphere.e at interval
#                 2) built at start-up; any data that comes back must be
#                 bit-identical to the pristine store (unless an edit left a
#                 page's Fletcher32 valid: a checksum collision).
# Every target: only dicer::Error may escape; any other exception
# (std::bad_alloc included), sanitizer report, leak, timeout (> 10 s) or RSS
# over 2 GiB is a crash.
#
# Build: clang, -DDICER_FUZZ=ON, RelWithDebInfo at -O1 with assertions on,
# into build-fuzz/ (libraries with -fsanitize=fuzzer-no-link,address,undefined,
# targets linked with -fsanitize=fuzzer,address,undefined).
# Corpus: libFuzzer writes new inputs to build-fuzz/corpus/TARGET/ (not
# committed); tests/fuzz/corpus/TARGET/ is the small committed seed corpus,
# passed as a read-only second corpus. Crashes go to build-fuzz/crashes/TARGET/.
# A crash, once fixed, is copied to tests/fuzz/regressions/TARGET/ where the
# FuzzRegressions tests of dicer_tests replay it (with the seed corpus).
# Reproduce one input: build-fuzz/fuzz_msh path/to/crash-file
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ $# -lt 2 ]]; then
  sed -n '2,/^set -euo/p' "$0" | sed '$d' >&2
  exit 2
fi
target=$1
seconds=$2
shift 2
case "$target" in
  fuzz_msh | fuzz_exodus | fuzz_page | fuzz_store) ;;
  *) echo "unknown target '$target' (fuzz_msh, fuzz_exodus, fuzz_page, fuzz_store)" >&2; exit 2 ;;
esac
cmake -S . -B build-fuzz -DDICER_FUZZ=ON -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DDICER_BUILD_TESTS=OFF -DDICER_BUILD_BENCH=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" >/dev/null
cmake --build build-fuzz --target "$target" -j"${DICER_JOBS:-$(nproc)}"
corpus=build-fuzz/corpus/$target
seeds=tests/fuzz/corpus/$target
crashes=build-fuzz/crashes/$target
mkdir -p "$corpus" "$crashes"
dirs=("$corpus")
[[ -d "$seeds" ]] && dirs+=("$seeds")
# Leaks are checked (detect_leaks=1); UBSan aborts on the first report.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"
# fuzz_store: HDF5's own allocations that it never frees are not ours (see the file).
if [[ $target == fuzz_store ]]; then
  export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/tests/fuzz/lsan_hdf5.supp}"
fi
exec "build-fuzz/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
  -artifact_prefix="$crashes/" -print_final_stats=1 "$@" "${dirs[@]}"
