"""dicer, h5py and meshio in one interpreter, on the same store.

The module links dicer's HDF5 (Debian's Open MPI flavour, the one the Exodus
library needs); Debian's h5py links the serial HDF5. Two HDF5 libraries in
one process must not resolve each other's symbols: each extension sees its
own (sonames differ, both are loaded RTLD_LOCAL). This test makes both work
on one file at once, and meshio (which writes XDMF's heavy data through
h5py) round-trips a chunk.
"""
import re

import numpy as np
import pytest

import dicer
from conftest import bits

h5py = pytest.importorskip("h5py")
meshio = pytest.importorskip("meshio")
hdf5plugin = pytest.importorskip("hdf5plugin")  # the HDF Group's LZ4 filter (32004) for h5py


def loaded_hdf5_libraries():
    with open("/proc/self/maps") as f:
        return sorted({m.group(0) for m in re.finditer(r"libhdf5[_a-z]*\.so[.0-9]*", f.read())})


def test_two_hdf5_libraries_side_by_side(prism_store):
    s = dicer.open(prism_store)
    with h5py.File(prism_store, "r") as f:  # open in both at the same time
        libs = loaded_hdf5_libraries()
        assert any("openmpi" in lib for lib in libs), libs
        assert any("serial" in lib for lib in libs), libs
        # h5py reads the store's own datasets through the HDF Group's LZ4 plugin
        # (an independent decoder of our pages) ...
        assert f.attrs["format"] in (b"dicer-store", "dicer-store")
        assert int(f.attrs["fine_nodes"]) == s.num_nodes
        vertex_nodes = f["topology/vertex_nodes"][:]
        corners = f["topology/element_corners"][:]
        # ... and the coarse vertices it finds are dicer's fine nodes, bit for bit.
        owner, slot, fine_id = vertex_nodes[:, 0], vertex_nodes[:, 1], vertex_nodes[:, 2]
        xyz = corners.reshape(len(corners), -1, 3)[owner, slot]
        assert np.array_equal(bits(xyz), bits(s.nodes(fine_id)))
        # dicer keeps working with h5py's library loaded and the file open in it.
        assert s.sweep(threads=2)["nodes"] == s.num_nodes
    with h5py.File(prism_store, "r") as f:
        assert f["topology/element_corners"].shape[0] == s.info["coarse_elements"]


def test_meshio_round_trip(prism_store, tmp_path):
    """Chunk.to_meshio -> XDMF (HDF5 through h5py) and VTU -> read back: same mesh."""
    s = dicer.open(prism_store)
    c = s.chunk(1, 3)
    m = c.to_meshio()
    assert len(m.cells) == len(np.unique(c.block_ids))  # one cell block per element block
    assert sum(len(b.data) for b in m.cells) == c.num_elements
    for path in (tmp_path / "chunk.xdmf", tmp_path / "chunk.vtu"):
        meshio.write(path, m)
        back = meshio.read(path)
        assert np.array_equal(bits(back.points), bits(c.points))
        # Reassemble the elements in global id order from the per-block cell data.
        gid = np.concatenate(back.cell_data["GlobalElementId"]).astype(np.int64)
        conn = np.concatenate([b.data for b in back.cells]).astype(np.int64)
        order = np.argsort(gid)
        assert np.array_equal(gid[order], c.global_element_ids)
        assert np.array_equal(conn[order], c.cells)
        gnode = back.point_data["GlobalNodeId"].astype(np.int64)
        assert np.array_equal(gnode, c.global_node_ids)
        # And, through the global ids, the store's own elements.
        assert np.array_equal(gnode[conn[order]], s.elements(c.global_element_ids))
        blocks = np.concatenate(back.cell_data["BlockId"]).astype(np.int64)[order]
        assert np.array_equal(blocks, s.element_info(c.global_element_ids)["block"])
        assert all(b.type == "hexahedron" for b in back.cells)


def test_meshio_quads(shell_store, tmp_path):
    s = dicer.open(shell_store)
    m = s.chunk(0, 1).to_meshio()
    assert [b.type for b in m.cells] == ["quad"] * len(m.cells)
    meshio.write(tmp_path / "shell.vtu", m)
    back = meshio.read(tmp_path / "shell.vtu")
    assert sum(len(b.data) for b in back.cells) == s.num_elements
    assert len(back.points) == s.num_nodes


def test_meshio_reads_cli_exodus_export_like_to_meshio(cli, prism_store, tmp_path):
    """meshio reading the command's Exodus export sees the mesh to_meshio builds."""
    pytest.importorskip("netCDF4")
    s = dicer.open(prism_store)
    out = tmp_path / "whole.exo"
    cli.run("export", prism_store, "--format", "exodus", "-o", out, "--quiet")
    ex = meshio.read(out)
    c = s.chunk(0, 1)
    assert np.array_equal(bits(ex.points), bits(c.points))
    assert sum(len(b.data) for b in ex.cells) == c.num_elements


@pytest.mark.parametrize("first", ["coordx", "coordy"])
def test_exodus_with_a_coordinate_as_its_first_netcdf_variable(cli, tmp_path, first):
    """netCDF does not order variables; the Exodus library (5.14) reads no
    coordinate from a variable of id 0 and says nothing, so this file (2 x 2
    quads in the plane x = y + 5, written by netCDF4) was diced flat, x = 0
    everywhere. Every node must lie on the plane."""
    netCDF4 = pytest.importorskip("netCDF4")
    p = tmp_path / f"{first}_first.e"
    ys, zs = np.meshgrid([0, 0.5, 1], [0, 0.5, 1])
    y, z = ys.ravel(), zs.ravel()
    xyz = {"coordx": y + 5.0, "coordy": y, "coordz": z}
    d = netCDF4.Dataset(p, "w", format="NETCDF3_64BIT_OFFSET")
    for k, v in {"len_string": 33, "four": 4, "num_dim": 3, "num_nodes": 9, "num_elem": 4, "num_el_blk": 1,
                 "num_el_in_blk1": 4, "num_nod_per_el1": 4, "time_step": None}.items():
        d.createDimension(k, v)
    for name in [first] + [n for n in ("coordx", "coordy", "coordz") if n != first]:
        d.createVariable(name, "f8", ("num_nodes",))[:] = xyz[name]
    d.createVariable("eb_status", "i4", ("num_el_blk",))[:] = [1]
    v = d.createVariable("eb_prop1", "i4", ("num_el_blk",))
    v.setncattr("name", "ID")
    v[:] = [1]
    v = d.createVariable("connect1", "i4", ("num_el_in_blk1", "num_nod_per_el1"))
    v.elem_type = "SHELL4"
    v[:] = np.array([[i + 3 * j + 1, i + 3 * j + 2, i + 3 * j + 5, i + 3 * j + 4] for j in range(2) for i in range(2)])
    d.createVariable("time_whole", "f8", ("time_step",))
    d.api_version = np.float32(8.1)
    d.version = np.float32(8.1)
    d.floating_point_word_size = np.int32(8)
    d.file_size = np.int32(1)
    d.title = "quads"
    d.close()
    with netCDF4.Dataset(p) as f:
        assert list(f.variables)[0] == first
    store = tmp_path / "q.dice.h5"
    cli.run("dice", p, "--interval", "2", "-o", store, "--quiet")
    nodes = cli.json_lines("query", store, "--nodes", "0:25")
    assert len(nodes) == 25
    for n in nodes:
        x, yy, zz = n["xyz"]
        assert x == pytest.approx(yy + 5.0, abs=1e-12) and 0 <= yy <= 1 and 0 <= zz <= 1, n
