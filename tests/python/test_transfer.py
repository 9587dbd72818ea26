"""Transfer operators between nested stores (`dicer transfer`, Store.transfer),
read back by independent readers: h5py + scipy for the CSR in HDF5,
Debian's petsc4py (MatLoad) for the PETSc binary file, numpy for the byte
layout of the 64-bit PETSc variant. Expectations come from outside dicer's
operator: the fine nodes' own coordinates (P reproduces linear functions
of them), the readers' matrix-vector products, and the two-grid solver's
iteration counts (examples/two_grid.py).
"""
import os
import sys

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

import dicer
from conftest import DATA, EXAMPLES

SPHERE = DATA / "cardinal_sphere.e"


@pytest.fixture(scope="module")
def levels(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("levels")
    out = {}
    for n in (2, 3, 4):
        out[n] = str(d / f"sphere{n}.dice.h5")
        cli.run("dice", SPHERE, "--interval", n, "-o", out[n], "--quiet")
    return out


def read_csr(path):
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == b"csr"
        P = sp.csr_matrix((f["data"][:], f["indices"][:], f["indptr"][:]), shape=tuple(f.attrs["shape"]))
        assert P.nnz == f.attrs["nnz"]
    return P


def test_hdf5_csr_is_read_by_scipy_and_interpolates(levels, cli, tmp_path):
    out = tmp_path / "P.h5"
    proc = cli.run("transfer", levels[2], levels[4], "-o", out, "--json")
    P = read_csr(out)
    with dicer.open(levels[2]) as c, dicer.open(levels[4]) as f:
        xc, xf = c.nodes(0, c.num_nodes), f.nodes(0, f.num_nodes)
        T = c.transfer(f)
        assert T.shape == P.shape == (f.num_nodes, c.num_nodes)
        assert T.nonzeros == P.nnz
        # Rows: at most 8 entries in (0, 1], summing to 1; a unit row per coarse node.
        assert P.has_sorted_indices  # ascending columns in every row, as CSR readers assume
        per_row = np.diff(P.indptr)
        assert per_row.min() >= 1 and per_row.max() <= 8
        assert P.data.min() > 0 and P.data.max() <= 1
        assert np.abs(np.asarray(P.sum(axis=1)).ravel() - 1).max() <= 1e-15
        unit = per_row == 1
        assert unit.sum() == c.num_nodes
        twins = P.indices[P.indptr[:-1][unit]]
        assert sorted(twins) == list(range(c.num_nodes))
        assert (xf[unit] == xc[twins]).all()  # coincident nodes, the same coordinates
        # Linear functions of the coordinates (these elements are straight).
        A = np.random.default_rng(1).normal(size=(3, 3))
        err = np.abs(P @ (xc @ A) - xf @ A).max()
        assert err <= 1e-12 * np.abs(xf @ A).max(), err
        # Matrix-free (the library, 1 and 2 threads) against scipy's product.
        rng = np.random.default_rng(2)
        x, y = rng.normal(size=P.shape[1]), rng.normal(size=P.shape[0])
        assert np.abs(T.apply(x) - P @ x).max() <= 1e-14 * np.abs(P @ x).max()
        assert (T.apply(x, threads=2) == T.apply(x)).all()
        assert np.abs(T.apply_transpose(y) - P.T @ y).max() <= 1e-13 * np.abs(P.T @ y).max()
        assert (T.apply_transpose(y, threads=2) == T.apply_transpose(y)).all()
    import json
    doc = json.loads(proc.stdout)
    assert doc["nested"] and doc["nonzeros"] == P.nnz and doc["bytes"] == os.path.getsize(out)


def test_a_mesh_files_columns_are_its_nodes_in_file_order(levels, cli, tmp_path):
    """COARSE given as the mesh file: P's columns are the file's nodes (node
    i of the Exodus file is column i-1), so P multiplies a nodal vector read
    from the file as a solver reads it. They were the nodes of the interval-1
    dicing (space-filling-curve order): P @ (coordinates in file order) was
    off by the mesh's size. The coordinates come from netCDF4, not dicer."""
    netCDF4 = pytest.importorskip("netCDF4")
    with netCDF4.Dataset(SPHERE) as nc:
        if "coord" in nc.variables:
            xc = np.asarray(nc.variables["coord"][:]).T
        else:
            xc = np.stack([np.asarray(nc.variables[f"coord{a}"][:]) for a in "xyz"], axis=1)
        if "node_num_map" in nc.variables:  # columns follow the file's node ids
            xc = xc[np.argsort(np.asarray(nc.variables["node_num_map"][:]), kind="stable")]
    cli.run("transfer", SPHERE, levels[4], "-o", tmp_path / "P.h5", "--quiet")
    P = read_csr(tmp_path / "P.h5")
    with h5py.File(tmp_path / "P.h5", "r") as f:
        assert b"mesh file" in f.attrs["columns"]
    with dicer.open(levels[4]) as fine:
        xf = fine.nodes(0, fine.num_nodes)
    assert P.shape == (len(xf), len(xc))
    assert np.abs(P @ xc - xf).max() <= 1e-12 * np.abs(xf).max()
    # P.bin without --format: PETSc's binary format (the extension says it), the same matrix.
    cli.run("transfer", SPHERE, levels[4], "-o", tmp_path / "P.bin", "--quiet")
    raw = (tmp_path / "P.bin").read_bytes()
    assert np.frombuffer(raw[:16], dtype=">i4").tolist() == [1211216, P.shape[0], P.shape[1], P.nnz]
    rows = np.frombuffer(raw[16:16 + 4 * P.shape[0]], dtype=">i4")
    cols = np.frombuffer(raw[16 + 4 * P.shape[0]:16 + 4 * (P.shape[0] + P.nnz)], dtype=">i4")
    assert (rows == np.diff(P.indptr)).all() and (cols == P.indices).all()


def test_hdf5_file_is_the_same_bytes_a_second_later(levels, cli, tmp_path):
    """Reproducible output: HDF5's object times (whole seconds) are off."""
    import time
    cli.run("transfer", levels[2], levels[4], "-o", tmp_path / "a.h5", "--quiet")
    time.sleep(1.1)
    cli.run("transfer", levels[2], levels[4], "-o", tmp_path / "b.h5", "--quiet")
    assert (tmp_path / "a.h5").read_bytes() == (tmp_path / "b.h5").read_bytes()


def test_petsc_file_is_read_by_matload_and_multiplies_like_scipy(levels, cli, tmp_path):
    PETSc = pytest.importorskip("petsc4py.PETSc")
    cli.run("transfer", levels[2], levels[4], "-o", tmp_path / "P.h5", "--quiet")
    cli.run("transfer", levels[2], levels[4], "--format", "petsc", "-o", tmp_path / "P.bin", "--quiet")
    P = read_csr(tmp_path / "P.h5")
    viewer = PETSc.Viewer().createBinary(str(tmp_path / "P.bin"), "r")
    M = PETSc.Mat().load(viewer)
    assert M.getSize() == P.shape
    indptr, indices, values = M.getValuesCSR()
    assert (indptr == P.indptr).all() and (indices == P.indices).all() and (values == P.data).all()
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=P.shape[1]), rng.normal(size=P.shape[0])
    vx, vy = PETSc.Vec().createWithArray(x), PETSc.Vec().createWithArray(y)
    out, out_t = M.createVecLeft(), M.createVecRight()
    M.mult(vx, out)
    M.multTranspose(vy, out_t)
    assert np.abs(out.getArray() - P @ x).max() <= 1e-14 * np.abs(P @ x).max()
    assert np.abs(out_t.getArray() - P.T @ y).max() <= 1e-13 * np.abs(P.T @ y).max()


def test_petsc_64_bit_layout(levels, cli, tmp_path):
    """--petsc-int 64: PETSc's layout with 8-byte big-endian ints, read here field by field."""
    cli.run("transfer", levels[3], levels[3], "-o", tmp_path / "P.h5", "--quiet")  # equal intervals: identity
    cli.run("transfer", levels[2], levels[4], "-o", tmp_path / "Q.h5", "--quiet")
    cli.run("transfer", levels[2], levels[4], "--format", "petsc", "--petsc-int", "64", "-o", tmp_path / "Q.bin", "--quiet")
    I = read_csr(tmp_path / "P.h5")
    assert (I != sp.identity(I.shape[0], format="csr")).nnz == 0
    Q = read_csr(tmp_path / "Q.h5")
    raw = (tmp_path / "Q.bin").read_bytes()
    head = np.frombuffer(raw, ">i8", 4)
    assert list(head) == [1211216, Q.shape[0], Q.shape[1], Q.nnz]
    at = 32
    lengths = np.frombuffer(raw, ">i8", Q.shape[0], at)
    at += 8 * Q.shape[0]
    cols = np.frombuffer(raw, ">i8", Q.nnz, at)
    at += 8 * Q.nnz
    vals = np.frombuffer(raw, ">f8", Q.nnz, at)
    assert at + 8 * Q.nnz == len(raw)
    assert (lengths == np.diff(Q.indptr)).all() and (cols == Q.indices).all() and (vals == Q.data).all()


def test_check_names_the_sheet_and_refuses_other_meshes(levels, cli, tmp_path):
    ok = cli.run("transfer", levels[2], levels[4], "--check")
    assert ok.stdout.startswith("nested")
    bad = cli.run("transfer", levels[2], levels[3], "--check", check=False)
    assert bad.returncode == 1 and "not nested: sheet 0 has interval 3" in bad.stdout, bad.stdout
    # The coarse mesh file itself is the interval-1 level.
    assert cli.run("transfer", SPHERE, levels[3], "--check").returncode == 0
    # Not nested: no operator, nothing written.
    refused = cli.run("transfer", levels[2], levels[3], "-o", tmp_path / "P.h5", check=False)
    assert refused.returncode == 3 and "sheet 0" in refused.stderr and not (tmp_path / "P.h5").exists()
    other = str(tmp_path / "brick.dice.h5")
    cli.run("dice", DATA / "cardinal_brick.e", "--interval", 2, "-o", other, "--quiet")
    diff = cli.run("transfer", levels[2], other, "--check", check=False)
    assert diff.returncode == 3 and "not dicings of one coarse mesh" in diff.stderr, diff.stderr
    for args in ([], ["--check", "-o", tmp_path / "x.h5"], ["-o", tmp_path / "x.h5", "--format", "csv"],
                 ["-o", tmp_path / "x.bin", "--format", "petsc", "--petsc-int", "16"]):
        u = cli.run("transfer", levels[2], levels[4], *args, check=False)
        assert u.returncode == 2, (args, u.stderr)
    assert not list(tmp_path.glob("x.*")) and not list(tmp_path.glob(".x*"))


def test_two_grid_iterations_stay_flat_while_plain_cg_grows(tmp_path):
    sys.path.insert(0, str(EXAMPLES))
    import two_grid

    rows = two_grid.run(str(tmp_path), intervals=(2, 4, 8))
    plain = [r[4] for r in rows]
    tg = [r[5] for r in rows]
    # Plain CG grows ~2x per halving of h (33, 73, 155 when written); the
    # two-grid count by at most 2 per halving (7, 9, 10).
    assert all(b > 1.8 * a for a, b in zip(plain, plain[1:])), plain
    assert all(b - a <= 2 for a, b in zip(tg, tg[1:])) and max(tg) <= 1.5 * min(tg) and max(tg) < plain[0] / 3, tg
    assert all(r[7] < 1e-6 for r in rows)  # both solve the same system
