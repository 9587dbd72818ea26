#!/usr/bin/env bash
# The same dicer binary under `mpirun -n P` against the single process, on
# real meshes (run by ctest for P = 1..4, sanitizer builds 1, 2, 4; --oversubscribe beyond the cores):
#   sweep        the same checksum and counts
#   query        --box --count the same number
#   verify       the same JSON report
#   export       Nemesis files with the same data as --chunks P --nemesis;
#                one VTKHDF file with the same datasets as --chunks P
#   dice         --geometry: the CAD work shared out, the single process's
#                store; a CAD that does not fit: exit 7, one message
#   errors       a store damaged where only one rank reads: every rank ends
#                with exit 8, one message, no hang; a full disk (a small
#                tmpfs, as root) under every export format: exit 5, one
#                message, no hang, the old file intact, nothing left; a rank
#                reading another store of the same name: exit 3; ranks given
#                other command lines: exit 2
# usage: mpi_cli.sh DICER P WORKDIR DATA_DIR
set -euo pipefail
dicer=$1 P=$2 work=$3 data=$4
py=/usr/bin/python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
# No stray python environment for Debian's python.
unset PYTHONPATH PYTHONHOME
run() { timeout 120 mpirun -q --oversubscribe -n "$P" "$dicer" "$@"; }
fail() { echo "mpi_cli (P=$P): $*" >&2; exit 1; }
rm -rf "$work"; mkdir -p "$work"; cd "$work"

"$dicer" dice "$data/cardinal_prism.exo" --interval 3 -o prism.dice.h5 --quiet
"$dicer" dice "$data/libmesh_cylinder_shell.exo" --interval 3 -o shell.dice.h5 --quiet
# A row of four hexes split at x = 2 (the layer of vertices there written
# twice): verify's report then carries coincident-node warnings and counts
# that the parts must merge as one process finds them, wherever P cuts.
$py - > split.msh <<'PY'
nodes, elems = [], []
nid = lambda i, j, k, dup: 1 + i + 5 * (j + 2 * k) + (100 if dup else 0)
for dup in (0, 1):
    for k in range(2):
        for j in range(2):
            for i in range(5):
                if not dup or i == 2:
                    nodes.append("%d %d %d %d" % (nid(i, j, k, dup), i, j, k))
for e in range(4):
    c = lambda i, j, k: nid(i, j, k, i == 2 and e >= 2)
    corners = [c(e, 0, 0), c(e + 1, 0, 0), c(e + 1, 1, 0), c(e, 1, 0), c(e, 0, 1), c(e + 1, 0, 1), c(e + 1, 1, 1), c(e, 1, 1)]
    elems.append("%d 5 2 %d 1 %s" % (e + 1, 1 + e // 2, " ".join(map(str, corners))))
print("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n%s\n$EndNodes" % (len(nodes), "\n".join(nodes)))
print("$Elements\n%d\n%s\n$EndElements" % (len(elems), "\n".join(elems)))
PY
"$dicer" dice split.msh --interval 3 -o split.dice.h5 --quiet 2> /dev/null
# The split face at interval 3 holds 4 x 4 fine nodes, each twice: 32.
"$dicer" verify split.dice.h5 --json | grep -q '"coincident_interface":32,' || fail "split: verify does not find the 32 interface nodes"

for s in prism shell split; do
  one=$("$dicer" sweep $s.dice.h5 --json --threads 1)
  many=$(run sweep $s.dice.h5 --json --threads 1)
  field() { $py -c "import json,sys; print(json.loads(sys.argv[1])[sys.argv[2]])" "$1" "$2"; }
  for k in checksum nodes elements; do
    [ "$(field "$one" $k)" = "$(field "$many" $k)" ] || fail "sweep $s: $k differs: $one vs $many"
  done
  [ "$(field "$many" ranks)" = "$P" ] || fail "sweep $s: ranks"
  "$dicer" verify $s.dice.h5 --json > v1.json || fail "verify $s (single) failed"
  run verify $s.dice.h5 --json > vP.json || fail "verify $s under MPI failed"
  cmp -s v1.json vP.json || fail "verify $s: reports differ: $(cat v1.json) vs $(cat vP.json)"
done

# export --stats: one set of cache lines per rank, each saying whose (P > 1).
run export prism.dice.h5 -o stats.vtkhdf --quiet --stats 2> stats.txt
for ((r = 0; r < P; r++)); do
  want="dicer export: cache:"; [ "$P" = 1 ] || want="dicer export (rank $r of $P): cache:"
  [ "$(grep -cF "$want" stats.txt)" = 1 ] || fail "export --stats: no single line \"$want\": $(cat stats.txt)"
done
[ "$(grep -c ': cache:' stats.txt)" = "$P" ] || fail "export --stats: not one cache line per rank: $(cat stats.txt)"

a=$("$dicer" query prism.dice.h5 --box -10,-10,-1,10,10,0.5 --count)
b=$(run query prism.dice.h5 --box -10,-10,-1,10,10,0.5 --count)
[ "$a" = "$b" ] || fail "query --box --count: $a vs $b"
[ "$a" -gt 0 ] || fail "query --box --count: the box is empty ($a)"

run export prism.dice.h5 --format exodus -o mpi.e --quiet
"$dicer" export prism.dice.h5 --format exodus --chunks "$P" --nemesis -o one.e --quiet
$py - "$P" <<'PY'
import sys, netCDF4, numpy as np
P = int(sys.argv[1]); w = len(str(P))
for r in range(P):
    a = netCDF4.Dataset("mpi.e.%d.%0*d" % (P, w, r)); b = netCDF4.Dataset("one.e.%d.%0*d" % (P, w, r))
    assert set(a.variables) == set(b.variables), "rank %d: variables differ" % r
    for v in b.variables:
        if not np.array_equal(np.asarray(a.variables[v][:]), np.asarray(b.variables[v][:])):
            sys.exit("rank %d: %s differs" % (r, v))
PY
# The last rank's Nemesis file would be the store itself: refused (exit 2)
# on every rank before anything is written, the store left as it was.
self=self.e.$P.$(printf '%0*d' ${#P} $((P - 1)))
cp prism.dice.h5 "$self"
set +e; out=$(run export "$self" --format exodus -o self.e 2>&1); code=$?; set -e
[ "$code" = 2 ] || fail "export onto its own store: exit $code, expected 2: $out"
cmp -s prism.dice.h5 "$self" || fail "export onto its own store changed the store"
run export prism.dice.h5 --format vtkhdf -o mpi.vtkhdf --quiet
"$dicer" export prism.dice.h5 --format vtkhdf --chunks "$P" -o one.vtkhdf --quiet
h5diff mpi.vtkhdf one.vtkhdf || fail "VTKHDF files differ"
sleep 1.1  # HDF5 object times are in whole seconds; the writer records none
run export prism.dice.h5 --format vtkhdf -o mpi2.vtkhdf --quiet
cmp mpi.vtkhdf mpi2.vtkhdf || fail "two VTKHDF exports on $P ranks differ"
ls | grep -q '\.tmp-' && fail "temporaries left behind: $(ls)"

# dice --geometry: every rank dices the coarse mesh, places every P-th
# curve and face and checks every P-th coarse element; rank 0 writes the
# store one process writes. Compared dataset by dataset (every group; the
# root's uuid attribute differs by design) and by the sweep checksum.
$py - <<'PY'
import gmsh
gmsh.initialize(); gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("torus"); gmsh.model.occ.addTorus(0, 0, 0, 2, 0.7); gmsh.model.occ.synchronize(); gmsh.write("torus.brep")
gmsh.model.add("cylinder"); gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 2, 1); gmsh.model.occ.synchronize(); gmsh.write("cylinder.brep")
gmsh.finalize()
PY
"$dicer" mesh-coarse torus.brep --size 0.7 -o torus.msh --quiet
"$dicer" dice torus.msh --geometry torus.brep --interval 3 -o cad1.dice.h5 > cad1.txt
run dice torus.msh --geometry torus.brep --interval 3 -o cadP.dice.h5 > cadP.txt || fail "dice --geometry under MPI failed"
for g in $($py -c "import h5py; print(' '.join('/' + k for k in h5py.File('cad1.dice.h5', 'r').keys()))"); do
  h5diff cad1.dice.h5 cadP.dice.h5 "$g" > /dev/null || [ $? = 2 ] || fail "dice --geometry: $g differs from the single process's"
done
h5diff -c cad1.dice.h5 cadP.dice.h5 /geometry/bounding || fail "dice --geometry: moved nodes differ"
[ "$("$dicer" sweep cad1.dice.h5 --json | $py -c 'import json,sys; print(json.load(sys.stdin)["checksum"])')" = \
  "$("$dicer" sweep cadP.dice.h5 --json | $py -c 'import json,sys; print(json.load(sys.stdin)["checksum"])')" ] ||
  fail "dice --geometry: sweep checksums differ"
[ "$(sed 1d cad1.txt)" = "$(sed 1d cadP.txt)" ] || fail "dice --geometry: reports differ: $(cat cad1.txt) vs $(cat cadP.txt)"
# A CAD that does not fit: exit 7 on every rank, one message, no store.
set +e
out=$(run dice torus.msh --geometry cylinder.brep --interval 2 -o wrong.dice.h5 2>&1)
code=$?
set -e
[ "$code" = 7 ] || fail "dice with the wrong CAD: exit $code, expected 7: $out"
[ "$(printf '%s\n' "$out" | grep -c 'error')" = 1 ] || fail "dice with the wrong CAD: not one message: $out"
[ ! -e wrong.dice.h5 ] || fail "dice with the wrong CAD wrote a store"
# Rank 1 reading another coarse mesh under the same name: the ranks' shares
# of the CAD work would not fit together. Exit 3, one message, no store.
if [ "$P" = 2 ]; then  # rank 1 against rank 0: P = 2 says it all (and keeps CI short)
  mkdir -p cadother
  cp torus.brep cadother/
  cp split.msh cadother/torus.msh  # any valid mesh: the check comes before the CAD work
  printf '#!/bin/bash\n[ "$OMPI_COMM_WORLD_RANK" = 1 ] && cd cadother\nexec "%s" "$@"\n' "$dicer" > cadother.sh
  chmod +x cadother.sh
  set +e
  out=$(timeout 120 mpirun -q --oversubscribe -n "$P" ./cadother.sh dice torus.msh --geometry torus.brep --interval 2 \
        -o $PWD/mixed.dice.h5 2>&1)
  code=$?
  set -e
  [ "$code" = 3 ] || fail "dice --geometry, another mesh on rank 1: exit $code, expected 3: $out"
  [ "$(printf '%s\n' "$out" | grep -c 'error')" = 1 ] || fail "dice --geometry, another mesh on rank 1: $out"
  printf '%s\n' "$out" | grep -q 'rank 1 read other contents than rank 0' || fail "dice --geometry: $out"
  [ ! -e mixed.dice.h5 ] || fail "dice --geometry, another mesh on rank 1: wrote a store"
fi

# A page that one rank alone reads, damaged (Fletcher32 catches it): the
# corner coordinates of the middle elements (opening the store and planning
# the chunks read element rows, never corners). Every rank must end with
# the same code and one message, without hanging in a collective.
if [ "$P" -gt 1 ]; then
  cp prism.dice.h5 bad.dice.h5
  $py - <<'PY'
import h5py, numpy as np
f = h5py.File("bad.dice.h5", "r")
ds = f["topology/element_corners"]
info = ds.id.get_chunk_info(ds.id.get_num_chunks() // 2)
f.close()
with open("bad.dice.h5", "r+b") as raw:
    raw.seek(info.byte_offset + info.size // 2)
    b = raw.read(1)
    raw.seek(info.byte_offset + info.size // 2)
    raw.write(bytes([b[0] ^ 0x5A]))
PY
  set +e
  out=$(run sweep bad.dice.h5 --threads 1 2>&1)
  code=$?
  set -e
  [ "$code" = 8 ] || fail "damaged page: exit $code, expected 8: $out"
  [ "$(printf '%s\n' "$out" | grep -c 'error')" = 1 ] || fail "damaged page: not one message: $out"
fi
# One rank under a file size limit (ulimit -f 10 MB, the file ~30 MB): its
# write failed inside a collective HDF5 call and every rank hung. Now each
# rank checks its limit first: exit 5, one message, nothing left.
if [ "$P" -gt 1 ]; then
  "$dicer" dice "$data/cardinal_prism.exo" --interval 5 -o prism5.dice.h5 --quiet
  printf '#!/bin/bash\n[ "$OMPI_COMM_WORLD_RANK" = 1 ] && ulimit -f 10000\nexec "%s" "$@"\n' "$dicer" > limited.sh
  chmod +x limited.sh
  mkdir -p lim
  set +e
  out=$(timeout 120 mpirun -q --oversubscribe -n "$P" ./limited.sh export prism5.dice.h5 -o lim/x.vtkhdf --quiet 2>&1)
  code=$?
  set -e
  [ "$code" = 5 ] || fail "file size limit on rank 1: exit $code, expected 5: $out"
  printf '%s\n' "$out" | grep -q 'ulimit -f' || fail "file size limit on rank 1: no reason: $out"
  [ -z "$(ls -A lim)" ] || fail "file size limit on rank 1: left behind: $(ls -A lim)"
fi

# Ranks that read different stores under one name (node-local copies that
# differ): sweep and query gave a wrong answer with exit 0. Now exit 3, one
# message naming rank 1. Ranks given other command lines waited for each
# other for ever: exit 2, one message.
if [ "$P" = 2 ]; then  # as above: P = 2
  mkdir -p other
  "$dicer" dice "$data/cardinal_prism.exo" --interval 2 -o other/prism.dice.h5 --quiet
  printf '#!/bin/bash\n[ "$OMPI_COMM_WORLD_RANK" = 1 ] && cd other\nexec "%s" "$@"\n' "$dicer" > elsewhere.sh
  chmod +x elsewhere.sh
  for args in "sweep prism.dice.h5 --quiet" "query prism.dice.h5 --box -9,-9,-9,9,9,9 --count" "verify prism.dice.h5 --quiet"; do
    set +e
    out=$(timeout 120 mpirun -q --oversubscribe -n "$P" ./elsewhere.sh $args 2>&1)
    code=$?
    set -e
    [ "$code" = 3 ] || fail "$args, another store on rank 1: exit $code, expected 3: $out"
    [ "$(printf '%s\n' "$out" | grep -c 'error')" = 1 ] || fail "$args, another store on rank 1: not one message: $out"
    printf '%s\n' "$out" | grep -q 'rank 1 read another store than rank 0' || fail "$args: $out"
  done
  set +e
  out=$(timeout 120 mpirun -q --oversubscribe -n 1 "$dicer" sweep prism.dice.h5 --quiet : -n $((P - 1)) "$dicer" verify prism.dice.h5 --quiet 2>&1)
  code=$?
  set -e
  [ "$code" = 2 ] || fail "sweep on rank 0, verify on the others: exit $code, expected 2: $out"
  [ "$(printf '%s\n' "$out" | grep -c 'error')" = 1 ] || fail "other command lines: not one message: $out"
  printf '%s\n' "$out" | grep -q 'every rank must run the same command line' || fail "other command lines: $out"
fi

# A rename that fails on rank 1 (an immutable old piece) while the others
# rename theirs: the message says the set may mix new and old pieces.
if [ "$P" = 2 ] && [ "$(id -u)" = 0 ]; then
  mkdir -p imm
  run export prism.dice.h5 -o imm/a.e --quiet
  if chattr +i imm/a.e.$P.1 2> /dev/null; then
    set +e
    out=$(run export shell.dice.h5 -o imm/a.e --quiet 2>&1)
    code=$?
    set -e
    chattr -i imm/a.e.$P.1
    [ "$code" = 5 ] || fail "immutable piece on rank 1: exit $code, expected 5: $out"
    printf '%s\n' "$out" | grep -q 'may mix new and old pieces' || fail "immutable piece on rank 1: $out"
  fi
fi

# SIGTERM to one rank during a collective export: every rank ends with its
# code, 143 (the others said 130, "interrupted": the signal was the failed
# rank's alone), one message naming the signal, nothing left behind.
if [ "$P" -gt 1 ]; then
  mkdir -p sig
  mpirun -q --oversubscribe -n "$P" "$dicer" export prism5.dice.h5 -o sig/x.vtkhdf --deflate 9 --quiet > sig.log 2>&1 &
  mp=$!
  sleep 0.8
  victim=$(pgrep -P $mp -f 'dicer export' | sed -n 2p || true)
  [ -n "$victim" ] && kill -TERM "$victim"
  set +e
  wait $mp
  code=$?
  set -e
  if [ "$code" != 0 ]; then  # 0: the export finished before the signal
    [ "$code" = 143 ] || fail "SIGTERM to rank 1: exit $code, expected 143: $(cat sig.log)"
    [ "$(grep -c 'dicer export: error' sig.log)" -le 1 ] || fail "SIGTERM to rank 1: more than one message: $(cat sig.log)"
    ! grep -q 'dicer export: error' sig.log || grep -q 'SIGTERM' sig.log || fail "SIGTERM to rank 1: $(cat sig.log)"
    # (A signal after the rename, past dicer's handlers, ends a rank with
    # 143 beside the complete file; temporaries are what must not stay.)
    [ -z "$(ls -A sig | grep '^\.' || true)" ] || fail "SIGTERM to rank 1: left behind: $(ls -A sig)"
  fi
fi

# A full disk. The collective VTKHDF writer hung in HDF5's flush on 3 ranks
# (rank 0's metadata write failed before the barrier the others waited in);
# now rank 0 reserves the file's blocks first. Exodus failed at exit in
# HDF5's cleanup (MPI_Finalize), exit 139. The old file, or the old Nemesis
# set (OUT.P.r, which the ranks commit together), is left as it was.
if [ "$(id -u)" = 0 ]; then
  mkdir -p disk
  mount -t tmpfs -o size=300k tmpfs disk 2>/dev/null || echo "mpi_cli (P=$P): cannot mount a tmpfs: full-disk cases skipped" >&2
  if mountpoint -q disk; then
    trap 'umount disk 2>/dev/null || true' EXIT
    "$dicer" dice "$data/firedrake_cube_hex.msh" --interval 1 -o tiny.dice.h5 --quiet
    for f in out.vtkhdf out.e out.msh; do
      if [ $f = out.e ]; then
        "$dicer" export tiny.dice.h5 --chunks "$P" --nemesis -o disk/$f --quiet
      elif [ $f = out.msh ]; then
        for ((k = 0; k < P; k++)); do echo old $k > disk/$f.$P.$(printf '%0*d' ${#P} $k); done
      else
        echo old > disk/$f
      fi
      before=$(cd disk && md5sum $(ls))
      set +e
      out=$(run export prism.dice.h5 -o disk/$f --quiet 2>&1)
      code=$?
      set -e
      [ "$code" = 5 ] || fail "full disk, $f: exit $code, expected 5: $out"
      [ "$(printf '%s\n' "$out" | grep -c 'dicer export: error')" = 1 ] || fail "full disk, $f: not one message: $out"
      # (netCDF's create on a full disk may blame another errno: only the
      # VTKHDF reserve's reason is certain.)
      [ $f != out.vtkhdf ] || printf '%s\n' "$out" | grep -q 'No space left on device' || fail "full disk, $f: no reason: $out"
      [ "$(cd disk && md5sum $(ls))" = "$before" ] || fail "full disk, $f: old files changed or left behind: $(ls -A disk)"
      [ -z "$(ls -A disk | grep '^\.')" ] || fail "full disk, $f: temporaries left behind: $(ls -A disk)"
      rm -f disk/*
    done
    umount disk
    trap - EXIT
  fi
fi
echo "mpi_cli P=$P ok"
