#!/usr/bin/python3
"""Two-grid preconditioned CG with dicer's prolongation, on a real mesh.

    -laplace(u) = 1 in the domain of a coarse hex mesh, u = 0 on its boundary,
    Q1 (trilinear) finite elements on the mesh diced at interval n.

For each fine interval n the coarse level is the same mesh diced at n / 2;
`dicer transfer COARSE FINE -o P.h5` writes the prolongation P (CSR in
HDF5), read here with h5py + scipy. The two-grid preconditioner is the
symmetric cycle: `smooth` damped-Jacobi sweeps (omega 0.7), the coarse
correction P (P^T A P)^-1 P^T on the residual (Galerkin coarse matrix,
solved to 1e-12), the same sweeps again. Plain CG's iteration count grows
about 2x per halving of h (its condition number grows as h^-2); the
two-grid count stays nearly flat, which is what makes the hierarchy worth
having.

    /usr/bin/python3 examples/two_grid.py                    # cardinal_sphere.e, n = 2, 4, 8
    /usr/bin/python3 examples/two_grid.py --markdown         # the README's table

Run with PYTHONPATH=build/python (or after cmake --install); the dicer
command is $DICER_CLI, else build/dicer beside this folder, else dicer on PATH.
"""
import argparse
import os
import shutil
import subprocess
import tempfile
import time

import h5py
import numpy as np
import scipy.sparse as sp

import dicer

HERE = os.path.dirname(os.path.abspath(__file__))
SPHERE = os.path.join(HERE, "cardinal_sphere.e")

# VTK HEX8 corners in the reference cube, and the corners of each face.
CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
FACES = np.array([[0, 3, 7, 4], [1, 2, 6, 5], [0, 1, 5, 4], [3, 2, 6, 7], [0, 1, 2, 3], [4, 5, 6, 7]])


def dicer_cli():
    for p in (os.environ.get("DICER_CLI"), os.path.join(HERE, "..", "build", "dicer"), shutil.which("dicer")):
        if p and os.path.exists(p):
            return p
    raise SystemExit("two_grid.py: the dicer command was not found (set DICER_CLI)")


def shape(xi):
    """Trilinear shape functions and their gradients at reference points xi (q, 3): (q, 8), (q, 8, 3)."""
    f = np.where(CORNERS[None], xi[:, None, :], 1 - xi[:, None, :])  # (q, 8, 3) per-axis factors
    d = np.where(CORNERS[None], 1.0, -1.0)                            # their derivatives
    N = f.prod(axis=2)
    dN = np.stack([d[..., k] * np.delete(f, k, axis=2).prod(axis=2) for k in range(3)], axis=2)
    return N, dN


def assemble(points, cells):
    """Q1 stiffness matrix and load vector (f = 1), 2x2x2 Gauss points."""
    g = 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3.0)
    xi = np.array([[a, b, c] for c in g for b in g for a in g])
    N, dN = shape(xi)
    X = points[cells]                                            # (e, 8, 3)
    J = np.matmul(X.transpose(0, 2, 1)[:, None], dN[None])       # (e, q, 3, 3): dx_i / dxi_j
    det = np.linalg.det(J)
    if (det <= 0).any():
        raise SystemExit("two_grid.py: an inverted element")
    G = np.matmul(dN[None], np.linalg.inv(J))                    # (e, q, 8, 3): physical gradients
    w = det / 8.0                                                # Gauss weights 1/8 on the unit cube
    Gs = (G * np.sqrt(w)[:, :, None, None]).transpose(0, 2, 1, 3).reshape(len(cells), 8, -1)
    Ke = np.matmul(Gs, Gs.transpose(0, 2, 1))                    # sum over q of w G G^T
    be = w @ N                                                   # (e, 8)
    n = len(points)
    rows = np.repeat(cells, 8, axis=1).ravel()
    cols = np.tile(cells, (1, 8)).ravel()
    A = sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))
    b = np.bincount(cells.ravel(), weights=be.ravel(), minlength=n)
    return A, b


def boundary_nodes(cells, n):
    """Nodes on faces that only one hex has."""
    faces = np.sort(cells[:, FACES].reshape(-1, 4), axis=1)
    uniq, count = np.unique(faces, axis=0, return_counts=True)
    mask = np.zeros(n, bool)
    mask[uniq[count == 1].ravel()] = True
    return mask


def mesh_of(store):
    whole = store.chunk(0, 1)  # one chunk: local node numbering == global ids
    assert (np.asarray(whole.global_node_ids) == np.arange(whole.num_nodes)).all()
    return np.array(whole.points), np.array(whole.cells)


def read_csr(path):
    with h5py.File(path, "r") as f:
        return sp.csr_matrix((f["data"][:], f["indices"][:], f["indptr"][:]), shape=tuple(f.attrs["shape"]))


def cg(A, b, precondition=None, rtol=1e-8, maxiter=5000):
    """(P)CG from 0 until ||r|| <= rtol ||b||; returns (x, iterations)."""
    x = np.zeros_like(b)
    r = b.copy()
    z = precondition(r) if precondition else r
    p = z.copy()
    rz = r @ z
    stop = rtol * np.linalg.norm(b)
    for it in range(1, maxiter + 1):
        Ap = A @ p
        alpha = rz / (p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) <= stop:
            return x, it
        z = precondition(r) if precondition else r
        rz, rz_old = r @ z, rz
        p = z + (rz / rz_old) * p
    raise RuntimeError(f"CG did not converge in {maxiter} iterations")


def two_grid(A, P, smooth=2, omega=0.7):
    """The symmetric two-grid cycle as a preconditioner r -> M^-1 r. The
    coarse problem (Galerkin, P^T A P) is solved to 1e-12 by Jacobi-PCG:
    exact for this purpose, and cheaper here than a sparse LU of a 3D
    matrix (SuperLU's fill-in)."""
    inv_d = omega / A.diagonal()
    Ac = (P.T @ A @ P).tocsr()
    inv_dc = 1.0 / Ac.diagonal()

    def apply(r):
        x = np.zeros_like(r)
        for _ in range(smooth):
            x += inv_d * (r - A @ x)
        x += P @ cg(Ac, P.T @ (r - A @ x), lambda q: inv_dc * q, rtol=1e-12)[0]
        for _ in range(smooth):
            x += inv_d * (r - A @ x)
        return x

    return apply


def run(workdir, mesh=SPHERE, intervals=(2, 4, 8), smooth=2):
    """Rows (n, coarse n, unknowns, coarse unknowns, plain CG iterations,
    two-grid iterations, seconds, max |u_plain - u_two_grid|)."""
    cli = dicer_cli()
    stores = {}

    def store(n):
        if n not in stores:
            path = os.path.join(workdir, f"level{n}.dice.h5")
            subprocess.run([cli, "dice", mesh, "--interval", str(n), "-o", path, "--quiet"], check=True)
            stores[n] = path
        return stores[n]

    rows = []
    for n in intervals:
        if n % 2:
            raise SystemExit("two_grid.py: fine intervals must be even (the coarse level is n / 2)")
        t0 = time.perf_counter()
        fine, coarse = store(n), store(n // 2)
        P_path = os.path.join(workdir, f"P{n // 2}_{n}.h5")
        subprocess.run([cli, "transfer", coarse, fine, "-o", P_path, "--quiet"], check=True, capture_output=True)
        P = read_csr(P_path)
        with dicer.open(fine) as s:
            points, cells = mesh_of(s)
        with dicer.open(coarse) as s:
            cpoints, ccells = mesh_of(s)
        A, b = assemble(points, cells)
        inner = ~boundary_nodes(cells, len(points))
        cinner = ~boundary_nodes(ccells, len(cpoints))
        A_ii, b_i = A[inner][:, inner].tocsr(), b[inner]
        P_i = P[inner][:, cinner].tocsr()
        u_plain, it_plain = cg(A_ii, b_i)
        u_two, it_two = cg(A_ii, b_i, two_grid(A_ii, P_i, smooth))
        rows.append((n, n // 2, int(inner.sum()), int(cinner.sum()), it_plain, it_two, time.perf_counter() - t0,
                     float(np.abs(u_plain - u_two).max())))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh", default=SPHERE)
    ap.add_argument("--intervals", type=int, nargs="+", default=[2, 4, 8])
    ap.add_argument("--smooth", type=int, default=2, help="Jacobi sweeps before and after the coarse correction")
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = run(tmp, args.mesh, args.intervals, args.smooth)
    if args.markdown:
        print("| fine n | coarse n | unknowns | coarse unknowns | plain CG iterations | two-grid PCG iterations |")
        print("|---:|---:|---:|---:|---:|---:|")
        for n, nc, u, uc, a, t, _, _ in rows:
            print(f"| {n} | {nc} | {u:,} | {uc:,} | {a} | {t} |")
    else:
        print(f"{'n':>4} {'coarse':>6} {'unknowns':>10} {'coarse':>8} {'CG':>6} {'two-grid':>9} {'seconds':>8} {'max diff':>9}")
        for n, nc, u, uc, a, t, secs, d in rows:
            print(f"{n:>4} {nc:>6} {u:>10} {uc:>8} {a:>6} {t:>9} {secs:>8.1f} {d:>9.1e}")


if __name__ == "__main__":
    main()
