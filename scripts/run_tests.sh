#!/usr/bin/env bash
# Install, build and run the whole test suite.
#   DICER_SANITIZE=1 bash scripts/run_tests.sh   ASan+UBSan build in build-asan/
#   DICER_KERNEL_CLONES=avx2 bash scripts/run_tests.sh
#       Release build in build-avx2/ whose kernels stop at their AVX2 clones:
#       what a machine without AVX-512 runs, tested on one that has it
#   DICER_CXX=clang bash scripts/run_tests.sh
#       Release build in build-clang/ with Debian's clang (installed): the
#       compiler the fuzz build needs, and C++20 that GCC alone accepts
#       breaks it (a lambda capturing a structured binding, Clang < 16)
set -euo pipefail
cd "$(dirname "$0")/.."
extra=(ccache)
[ "${DICER_CXX:-}" = clang ] && extra+=(clang)
bash scripts/install_deps.sh "${extra[@]}"
# The Release and AVX2-clone builds differ only in the kernel sources
# (CMakeLists.txt, DICER_KERNEL_CLONES): through ccache the second compiles
# those alone (.ci/run runs both on a fresh machine). The paths under the
# checkout are hashed relative to it, so build/ and build-avx2/ share.
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
cache=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
if [ "${DICER_CXX:-}" = clang ]; then
  cmake -S . -B build-clang -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
    -DDICER_BUILD_BENCH=OFF >/dev/null
  cmake --build build-clang -j"$(nproc)"
  cd build-clang
elif [ "${DICER_SANITIZE:-0}" = 1 ]; then
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DDICER_SANITIZE=ON -DDICER_BUILD_BENCH=OFF >/dev/null
  cmake --build build-asan -j"$(nproc)"
  cd build-asan
elif [ -n "${DICER_KERNEL_CLONES:-}" ]; then
  dir="build-${DICER_KERNEL_CLONES}"
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release -DDICER_KERNEL_CLONES="$DICER_KERNEL_CLONES" -DDICER_BUILD_BENCH=OFF \
    "${cache[@]}" >/dev/null
  cmake --build "$dir" -j"$(nproc)"
  cd "$dir"
else
  bash scripts/build.sh "${cache[@]}"
  cd build
fi
ctest --output-on-failure -j"$(nproc)"
