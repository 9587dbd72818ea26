#!/usr/bin/env bash
# Installs the built dicer into a temporary prefix, builds tests/package
# against it with find_package(dicer), runs it on a real mesh.
set -euo pipefail
build=$1 src=$2 mesh=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/package" -B "$tmp/build" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/build" >/dev/null
out=$("$tmp/build/consumer" "$mesh")
echo "consumer printed: $out"
# 256 hexes at interval 2: 2048 elements (8 per hex).
[ "${out#* }" = "2048" ]
