#!/usr/bin/env bash
# The main job on a bundled real mesh: install, build, list sheets, dice,
# print the summary, query, verify, export; then CAD -> coarse mesh -> fine
# mesh on the CAD.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
bash scripts/build.sh
out=${DICER_EXAMPLE_OUT:-build/example}
mkdir -p "$out"
set -x
build/dicer sheets examples/cardinal_sphere.e | head -8
build/dicer dice examples/cardinal_sphere.e --interval 16 --sheet-interval 0=24 -o "$out/sphere.dice.h5"
build/dicer info "$out/sphere.dice.h5"
build/dicer query "$out/sphere.dice.h5" --element 123456 --json
build/dicer query "$out/sphere.dice.h5" --nodes 1000:1003 --json
build/dicer query "$out/sphere.dice.h5" --point 0.1,0.2,0.3 --json
build/dicer verify "$out/sphere.dice.h5" --stats
build/dicer footprint "$out/sphere.dice.h5"
build/dicer export "$out/sphere.dice.h5" --format vtkhdf --chunks 4 -o "$out/sphere.vtkhdf"
build/dicer export "$out/sphere.dice.h5" --format exodus --chunk 1/8 -o "$out/sphere_chunk1.exo"
build/dicer export "$out/sphere.dice.h5" --format msh --box -2,-2,-2,2,2,0 -o "$out/sphere_lower_half.msh"
build/dicer dice examples/dealii_step-49_example.msh --interval 8 -o "$out/plate.dice.h5"
build/dicer verify "$out/plate.dice.h5" --quiet
# CAD -> coarse all-hex mesh (Gmsh) -> fine mesh on the CAD, checked against it.
build/dicer mesh-coarse examples/cylinder.brep --size 0.8 -o "$out/cylinder.msh"
build/dicer dice "$out/cylinder.msh" --geometry examples/cylinder.brep --interval 12 -o "$out/cylinder.dice.h5"
build/dicer verify "$out/cylinder.dice.h5" --geometry examples/cylinder.brep --quiet
build/dicer footprint "$out/cylinder.dice.h5"
