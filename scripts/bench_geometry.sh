#!/usr/bin/env bash
# Geometry-conforming dicing, measured: for a cylinder, a torus and a sphere
# in a box (CAD made by Gmsh's Python API, coarse mesh by `dicer mesh-coarse`)
# dice at intervals 2..32 with --geometry, and print per case: fine
# elements, dice seconds, bounding nodes, store bytes per fine element, bounding
# bytes per moved node, min scaled Jacobian over the curved elements and the
# largest distance to the CAD (verify --geometry, at the small intervals).
# Usage: bash scripts/bench_geometry.sh [OUTDIR]   (after scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build/bench_geometry}
mkdir -p "$out"
env -u PYTHONPATH -u PYTHONHOME /usr/bin/python3 - "$out" <<'PY'
import sys, gmsh
out = sys.argv[1]
gmsh.initialize(); gmsh.option.setNumber('General.Terminal', 0)
def make(name, build):
    gmsh.model.add(name); build(); gmsh.model.occ.synchronize(); gmsh.write(f'{out}/{name}.brep'); gmsh.model.remove()
make('cylinder', lambda: gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 2, 1))
make('torus', lambda: gmsh.model.occ.addTorus(0, 0, 0, 2, 0.7))
def sib():
    gmsh.model.occ.addBox(-2, -2, -2, 4, 4, 4, 1); gmsh.model.occ.addSphere(0, 0, 0, 1, 2)
    gmsh.model.occ.fragment([(3, 1)], [(3, 2)])
make('sphere_in_box', sib)
gmsh.finalize()
PY
printf "%-14s %4s %12s %8s %10s %10s %10s %8s %10s\n" case n fine_elems dice_s bound_nodes B/fine_el B/moved minSJ max_dist
for spec in cylinder:0.8:"2 4 8 16 32" torus:0.45:"2 4 8 16 32" sphere_in_box:0.5:"2 8 32"; do
  IFS=: read -r name size ns <<<"$spec"
  build/dicer mesh-coarse "$out/$name.brep" --size "$size" -o "$out/$name.msh" --quiet
  for n in $ns; do
    s="$out/$name-$n.dice.h5"
    t0=$(date +%s.%N)
    log=$(build/dicer dice "$out/$name.msh" --geometry "$out/$name.brep" --interval "$n" -o "$s")
    t1=$(date +%s.%N)
    sj=$(sed -n 's/.*min scaled Jacobian \([0-9.e-]*\).*/\1/p' <<<"$log")
    fp=$(build/dicer footprint "$s" --json)
    dist=-
    if [ "$n" -le 8 ]; then
      dist=$(build/dicer verify "$s" --geometry "$out/$name.brep" --json --quiet | sed -n 's/.*"max_distance":\([^,]*\).*/\1/p')
    fi
    FP="$fp" N="$n" NAME="$name" T="$(echo "$t1 - $t0" | bc)" SJ="$sj" D="$dist" env -u PYTHONPATH -u PYTHONHOME /usr/bin/python3 -c '
import json, os
f = json.loads(os.environ["FP"])
bn = max(f["bounding_nodes"], 1)
print("%-14s %4s %12d %8.2f %10d %10.4f %10.2f %8s %10s" % (os.environ["NAME"], os.environ["N"], f["fine_elements"],
      float(os.environ["T"]), f["bounding_nodes"], f["store_bytes"] / f["fine_elements"], f["bounding_bytes"] / bn,
      os.environ["SJ"], os.environ["D"]))'
    rm -f "$s"
  done
done
