#!/usr/bin/python3
"""Poisson on a diced cylinder, solved by DOLFINx (Debian's python3-dolfinx 0.5.2), Q1 hexes.

    -laplace(u) = f  in the cylinder r < 1, 0 < z < 2 (examples/cylinder.brep)
              u = 0  on its boundary
    u = (1 - x^2 - y^2) z (2 - z),   f = 4 z (2 - z) + 2 (1 - x^2 - y^2)

The exact solution vanishes on the *true* cylinder, not on the coarse mesh's
flat facets: the L2 error falls as h^2 (4x per halving, Q1) only when the
fine boundary nodes lie on the CAD (`dice --geometry`); on the coarse facets
it stalls at the facets' distance from the cylinder. Wrong connectivity or
orientation (inverted hexes) would not converge at all.

    /usr/bin/python3 examples/poisson_dolfinx.py                 # table: CAD vs facets, n = 1, 2, 4
    mpirun -n 2 /usr/bin/python3 examples/poisson_dolfinx.py     # the same, each rank reading its partition

Run with PYTHONPATH=build/python (or after cmake --install).
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

import dicer

HERE = os.path.dirname(os.path.abspath(__file__))
CYLINDER = os.path.join(HERE, "cylinder.brep")


def solve_store(store, comm, quadrature_degree=4, vtk_to_dolfinx=True):
    """Solves the problem on a diced store; returns (L2 error, fine elements, unknowns, seconds).
    vtk_to_dolfinx=False hands DOLFINx the VTK vertex order unconverted (the
    test's proof that a wrong element ordering does not converge)."""
    import dolfinx
    import dolfinx.fem.petsc
    import ufl
    from petsc4py import PETSc

    t0 = time.perf_counter()
    if comm.size == 1:
        whole = store.chunk(0, 1)  # one chunk: local node numbering == global ids
        x, cells = np.array(whole.points), np.array(whole.cells)
    else:
        # Rank r passes the nodes it owns (one global id range, ranks in
        # order: exactly DOLFINx's "rank r holds the next rows of x") and its
        # elements by global node id. Store.partition(comm) exchanges the
        # sharing over MPI (collective).
        part = store.partition(comm)
        x = np.array(part.points[:part.num_owned])
        cells = np.asarray(part.node_global)[np.asarray(part.connectivity)]
    # dicer gives VTK HEX8 order; DOLFINx numbers a hexahedron's vertices
    # as a tensor product.
    if vtk_to_dolfinx:
        cells = cells[:, dolfinx.cpp.io.perm_vtk(dolfinx.mesh.CellType.hexahedron, 8)]
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.hexahedron, 1))
    mesh = dolfinx.mesh.create_mesh(comm, cells, x, domain)

    V = dolfinx.fem.FunctionSpace(mesh, ("Lagrange", 1))
    X = ufl.SpatialCoordinate(mesh)
    r2 = X[0] ** 2 + X[1] ** 2
    exact = (1 - r2) * X[2] * (2 - X[2])
    f = 4 * X[2] * (2 - X[2]) + 2 * (1 - r2)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.dx(metadata={"quadrature_degree": quadrature_degree})
    a = ufl.inner(ufl.grad(u), ufl.grad(v)) * dx
    L = f * v * dx

    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dolfinx.mesh.exterior_facet_indices(mesh.topology)
    dofs = dolfinx.fem.locate_dofs_topological(V, tdim - 1, facets)
    bc = dolfinx.fem.dirichletbc(PETSc.ScalarType(0), dofs, V)
    problem = dolfinx.fem.petsc.LinearProblem(
        a, L, bcs=[bc],
        # BoomerAMG with the coarsening hypre's manual advises for 3D
        # (HMIS, extended+i interpolation): 7x faster to set up here than
        # the defaults, and it runs under mpirun as well.
        petsc_options={"ksp_type": "cg", "ksp_rtol": 1e-10, "pc_type": "hypre",
                       "pc_hypre_boomeramg_coarsen_type": "HMIS", "pc_hypre_boomeramg_interp_type": "ext+i",
                       "pc_hypre_boomeramg_strong_threshold": 0.5, "pc_hypre_boomeramg_P_max": 4,
                       "pc_hypre_boomeramg_agg_nl": 1})
    uh = problem.solve()
    reason = problem.solver.getConvergedReason()
    if reason <= 0:
        raise RuntimeError(f"CG did not converge (reason {reason})")

    error_form = dolfinx.fem.form((uh - exact) ** 2 * ufl.dx(metadata={"quadrature_degree": 6}))
    error = np.sqrt(comm.allreduce(dolfinx.fem.assemble_scalar(error_form)))
    elements = comm.allreduce(mesh.topology.index_map(tdim).size_local)
    unknowns = V.dofmap.index_map.size_global
    return error, elements, unknowns, time.perf_counter() - t0


def convergence(workdir, intervals=(1, 2, 4), coarse_size=0.8, geometry=True, comm=None, **solve_options):
    """Dices the cylinder at each interval and solves; rows of (n, elements, unknowns, error, seconds)."""
    if comm is None:
        from mpi4py import MPI
        comm = MPI.COMM_SELF
    coarse = os.path.join(workdir, f"cylinder_{coarse_size}.msh")
    if comm.rank == 0 and not os.path.exists(coarse):
        dicer.mesh_coarse(CYLINDER, coarse, size=coarse_size)
    rows = []
    for n in intervals:
        path = os.path.join(workdir, f"cylinder_{'cad' if geometry else 'facets'}_{n}.dice.h5")
        if comm.rank == 0:
            dicer.dice(coarse, path, interval=n, geometry=CYLINDER if geometry else None).close()
        comm.Barrier()
        with dicer.open(path) as store:
            error, elements, unknowns, seconds = solve_store(store, comm, **solve_options)
        rows.append((n, elements, unknowns, error, seconds))
    return rows


def rates(rows):
    """Error ratio between consecutive rows (4 for h^2 when the interval doubles)."""
    return [rows[i - 1][3] / rows[i][3] for i in range(1, len(rows))]


def main():
    from mpi4py import MPI
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--intervals", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--coarse-size", type=float, default=0.8)
    ap.add_argument("--markdown", action="store_true", help="print the README's table")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    with tempfile.TemporaryDirectory() as tmp:
        tmp = comm.bcast(tmp, root=0)
        results = {}
        for geometry in (True, False):
            results[geometry] = convergence(tmp, args.intervals, args.coarse_size, geometry, comm)
    if comm.rank != 0:
        return
    if args.markdown:
        print("| interval n | fine hexes | unknowns | L2 error, nodes on the CAD | ratio | L2 error, nodes on the coarse facets | ratio |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
    for i, (cad, flat) in enumerate(zip(results[True], results[False])):
        r_cad = f"{results[True][i - 1][3] / cad[3]:.2f}" if i else "-"
        r_flat = f"{results[False][i - 1][3] / flat[3]:.2f}" if i else "-"
        if args.markdown:
            print(f"| {cad[0]} | {cad[1]:,} | {cad[2]:,} | {cad[3]:.3e} | {r_cad} | {flat[3]:.3e} | {r_flat} |")
        else:
            print(f"n={cad[0]:3d} hexes={cad[1]:9d} unknowns={cad[2]:9d}  L2(CAD)={cad[3]:.3e} ratio {r_cad:>5}"
                  f"   L2(facets)={flat[3]:.3e} ratio {r_flat:>5}   ({cad[4]:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
