#!/usr/bin/env bash
# Library-level MPI checks under mpirun -n P: exchange_check (the exchanged
# sharing maps equal the single process's), examples/laplacian_mpi (a
# distributed operator equals the one-process one) and transfer_check (the
# prolongation and its transpose over ranks equal one process's, bit for
# bit), on real meshes.
# usage: mpi_programs.sh P DICER EXCHANGE_CHECK LAPLACIAN WORKDIR DATA_DIR TRANSFER_CHECK
set -euo pipefail
P=$1 dicer=$2 exchange=$3 laplacian=$4 work=$5 data=$6 transfer=$7
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
run() { timeout 300 mpirun -q --oversubscribe -n "$P" "$@"; }
rm -rf "$work"; mkdir -p "$work"; cd "$work"
"$dicer" dice "$data/cardinal_sphere.e" --interval 3 -o sphere.dice.h5 --quiet
"$dicer" dice "$data/libmesh_cylinder_shell.exo" --interval 2 -o shell.dice.h5 --quiet
run "$exchange" sphere.dice.h5 shell.dice.h5
run "$laplacian" sphere.dice.h5
"$dicer" dice "$data/cardinal_sphere.e" --interval 6 -o sphere6.dice.h5 --quiet
"$dicer" dice "$data/libmesh_cylinder_shell.exo" --interval 4 -o shell4.dice.h5 --quiet
run "$transfer" sphere.dice.h5 sphere6.dice.h5 shell.dice.h5 shell4.dice.h5
