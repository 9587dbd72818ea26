"""Store.partition(comm) under mpirun (tests/python/CMakeLists.txt runs this
file with mpirun -n 2 and -n 3): the partition exchanged over MPI equals
the one computed in one process, and an error on one rank is raised on
every rank instead of leaving the others waiting."""
import os
import shutil
import tempfile

import numpy as np
import pytest
from mpi4py import MPI

import dicer
from conftest import DATA, bits

comm = MPI.COMM_WORLD


def dice_on(rank, name):
    """The prism diced by the package on `rank` alone, in a folder of its
    own: its path there, None elsewhere (the dicer command, started from
    inside an MPI rank, would see mpirun's environment and try to join the
    job). A failure fails every rank instead of leaving the others waiting
    in a collective."""
    path, error = None, None
    if comm.rank == rank:
        path = os.path.join(tempfile.mkdtemp(), name)
        try:
            dicer.dice(DATA / "cardinal_prism.exo", path, interval=2).close()
        except Exception as e:  # noqa: BLE001 - reported on every rank below
            error = f"{type(e).__name__}: {e}"
    errors = [x for x in comm.allgather(error) if x]
    if errors:
        pytest.fail(f"rank {rank} could not dice {name}: {errors[0]}")
    return path


@pytest.fixture(scope="module")
def store_path():
    path = comm.bcast(dice_on(0, "prism.dice.h5"), root=0)
    yield path
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(os.path.dirname(path))


def test_partition_over_mpi_equals_in_process(store_path):
    assert comm.size > 1, "run under mpirun -n 2 or more"
    s = dicer.open(store_path)
    p = s.partition(comm)
    q = s.partition(comm.rank, comm.size)
    assert (p.rank, p.size, p.num_owned, p.element_begin) == (q.rank, q.size, q.num_owned, q.element_begin)
    assert np.array_equal(p.node_global, q.node_global)
    assert np.array_equal(p.node_owner, q.node_owner)
    assert np.array_equal(bits(p.points), bits(q.points))
    assert np.array_equal(p.connectivity, q.connectivity)
    assert p.neighbors == q.neighbors
    assert all(np.array_equal(a, b) for a, b in zip(p.shared_nodes, q.shared_nodes))
    # The ranks' owned nodes tile the mesh, in rank order.
    owned = comm.allgather((p.node_global[0] if p.num_owned else None, p.num_owned))
    assert sum(n for _, n in owned) == s.num_nodes
    begins = [b for b, n in owned if n]
    assert begins == sorted(begins) and begins[0] == 0


def test_an_error_on_one_rank_is_raised_on_every_rank(store_path):
    s = dicer.open(store_path)
    if comm.rank == comm.size - 1:
        s.close()  # only this rank fails
    with pytest.raises(dicer.UsageError) as e:
        s.partition(comm)
    if comm.rank == comm.size - 1:
        assert "closed" in str(e.value)
    else:
        assert f"rank {comm.size - 1} failed" in str(e.value)
    # The communicator is still usable: nobody was left waiting.
    assert comm.allreduce(1) == comm.size


def test_ranks_that_opened_other_stores_are_refused(store_path):
    """A rank whose store is another dicing (node-local copies that differ)
    made a partition that did not fit the others': BadInputError naming it
    on that rank, the same kind on the others, nobody left waiting."""
    other = dice_on(1, "other.dice.h5")
    try:
        s = dicer.open(other or store_path)
        with pytest.raises(dicer.BadInputError) as e:
            s.partition(comm)
        if comm.rank == 1:
            assert "rank 1 read another store than rank 0" in str(e.value)
        else:
            assert "rank 1 failed" in str(e.value)
        s.close()
        assert comm.allreduce(1) == comm.size
    finally:
        if other:
            shutil.rmtree(os.path.dirname(other))


def test_not_a_communicator(store_path):
    s = dicer.open(store_path)
    with pytest.raises(dicer.UsageError, match="mpi4py communicator"):
        s.partition(object())
    # Handles with py2f that are no communicator (they read as COMM_WORLD
    # or COMM_SELF through the Fortran handle) and a rank left out of a
    # split (MPI.COMM_NULL): refused on the rank, nothing collective started.
    for other in (MPI.MAX, MPI.INFO_NULL, MPI.REQUEST_NULL, MPI.GROUP_EMPTY, comm.Get_group()):
        with pytest.raises(dicer.UsageError, match="mpi4py communicator"):
            s.partition(other)
    part = comm.Split(0 if comm.rank == 0 else MPI.UNDEFINED, 0)
    if comm.rank == 0:
        assert s.partition(part).size == 1
    else:
        assert part == MPI.COMM_NULL
        with pytest.raises(dicer.UsageError, match="COMM_NULL"):
            s.partition(part)
    assert comm.allreduce(1) == comm.size


def test_poisson_under_mpirun_equals_one_process():
    """examples/poisson_dolfinx.py under mpirun: rank 0 runs dicer-cad (which
    must not take itself for a rank of the job), every rank hands DOLFINx its
    Store.partition(comm), and the errors equal the one-process solve."""
    pytest.importorskip("dolfinx")
    import sys

    from conftest import EXAMPLES
    sys.path.insert(0, str(EXAMPLES))
    import poisson_dolfinx

    workdir = comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0)
    try:
        rows = poisson_dolfinx.convergence(workdir, intervals=(1, 2), geometry=True, comm=comm)
        serial = None
        if comm.rank == 0:
            serial = poisson_dolfinx.convergence(workdir, intervals=(1, 2), geometry=True, comm=MPI.COMM_SELF)
        serial = comm.bcast(serial, root=0)
        assert [r[:3] for r in rows] == [r[:3] for r in serial]  # interval, hexes, unknowns
        for r, s in zip(rows, serial):
            assert abs(r[3] - s[3]) <= 1e-6 * s[3], (r, s)  # CG to 1e-10: the same error to ~7 digits
        assert 3.4 < rows[0][3] / rows[1][3] < 4.6
    finally:
        comm.Barrier()
        if comm.rank == 0:
            shutil.rmtree(workdir)
