#!/usr/bin/env bash
# ThreadSanitizer run of the concurrent code paths.
#
# Covers: every page-cache test (PageCache*: concurrent misses of one page,
# loader errors fanned out to waiters, 8 threads of random pins, concurrent
# sweeps with the background read-ahead worker, and the single-threaded
# tests, which still exercise the worker thread), plus every test whose name
# contains "Concurrent" (e.g. concurrent readers of one store).
# Not covered: the rest of the suite (single-threaded; see run_tests.sh with
# DICER_SANITIZE=1 for ASan+UBSan over everything).
#
# Builds target dicer_tests only, Debug, -DDICER_SANITIZE_THREAD=ON, into
# build-tsan/. Exits non-zero if the build fails, a test fails, or TSan
# reports anything (halt_on_error=1 stops at the first report).
#   bash scripts/run_tsan.sh                 all of the above
#   bash scripts/run_tsan.sh --gtest_repeat=20   extra gtest flags pass through
#   DICER_JOBS=1 bash scripts/run_tsan.sh    limit build parallelism
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=Debug -DDICER_SANITIZE_THREAD=ON -DDICER_BUILD_BENCH=OFF >/dev/null
cmake --build build-tsan --target dicer_tests -j"${DICER_JOBS:-$(nproc)}"
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ${TSAN_OPTIONS:-}"
build-tsan/tests/dicer_tests --gtest_filter='PageCache*:*Concurrent*' "$@"
