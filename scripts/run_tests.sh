#!/usr/bin/env bash
# Install, build and run the whole test suite.
#   DICER_SANITIZE=1 bash scripts/run_tests.sh   ASan+UBSan build in build-asan/
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
if [ "${DICER_SANITIZE:-0}" = 1 ]; then
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DDICER_SANITIZE=ON -DDICER_BUILD_BENCH=OFF >/dev/null
  cmake --build build-asan -j"$(nproc)"
  cd build-asan
else
  bash scripts/build.sh
  cd build
fi
ctest --output-on-failure -j"$(nproc)"
