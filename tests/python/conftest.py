"""Shared fixtures: the dicer command, the bundled meshes, stores diced once per session.

ctest (tests/python/CMakeLists.txt) sets DICER_CLI, DICER_CAD, DICER_SOURCE_DIR
and PYTHONPATH=build/python; run by hand the same way:

    cd build && env -u PYTHONPATH DICER_CLI=$PWD/dicer DICER_CAD=$PWD/dicer-cad \\
        DICER_SOURCE_DIR=$PWD/.. PYTHONPATH=$PWD/python /usr/bin/python3 -m pytest ../tests/python
"""
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

SOURCE = Path(os.environ.get("DICER_SOURCE_DIR", Path(__file__).resolve().parents[2]))
DATA = SOURCE / "tests" / "data"
EXAMPLES = SOURCE / "examples"


def _cli_path():
    p = os.environ.get("DICER_CLI")
    if not p:
        pytest.fail("DICER_CLI is not set (run through ctest, or see conftest.py)")
    return p


class Cli:
    """The dicer command, run as a user would: argv in, stdout/stderr/exit status out."""

    def __init__(self, path):
        self.path = path

    def run(self, *args, check=True):
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        proc = subprocess.run([self.path, *map(str, args)], capture_output=True, text=True, env=env)
        if check and proc.returncode != 0:
            raise AssertionError(f"dicer {' '.join(map(str, args))} exited {proc.returncode}: {proc.stderr}")
        return proc

    def json(self, *args):
        return json.loads(self.run(*args, "--json").stdout)

    def json_lines(self, *args):
        return [json.loads(line) for line in self.run(*args, "--json").stdout.splitlines()]

    def error(self, *args):
        """(exit status, the message after 'dicer CMD: error: ') of a failing command."""
        proc = self.run(*args, check=False)
        assert proc.returncode != 0, f"dicer {args} succeeded"
        last = [ln for ln in proc.stderr.splitlines() if ln.strip()][-1]
        return proc.returncode, last.split(": error: ", 1)[1]


@pytest.fixture(scope="session")
def cli():
    return Cli(_cli_path())


@pytest.fixture(scope="session")
def sphere_store(tmp_path_factory, cli):
    """A real CUBIT sphere (256 hexes) diced by the command line at interval 3."""
    out = tmp_path_factory.mktemp("sphere") / "sphere.dice.h5"
    cli.run("dice", DATA / "cardinal_sphere.e", "--interval", 3, "-o", out, "--quiet")
    return out


@pytest.fixture(scope="session")
def prism_store(tmp_path_factory, cli):
    """Two stacked prisms, 2 blocks, 11 named side sets: blocks and sets get exercised."""
    out = tmp_path_factory.mktemp("prism") / "prism.dice.h5"
    cli.run("dice", DATA / "cardinal_prism.exo", "--interval", 2, "--block-interval", "1=3", "-o", out, "--quiet")
    return out


@pytest.fixture(scope="session")
def shell_store(tmp_path_factory, cli):
    """An all-quad surface mesh (libMesh cylinder shell)."""
    out = tmp_path_factory.mktemp("shell") / "shell.dice.h5"
    cli.run("dice", DATA / "libmesh_cylinder_shell.exo", "--interval", 3, "-o", out, "--quiet")
    return out


@pytest.fixture(scope="session")
def graded_store(tmp_path_factory, cli):
    """The sphere with graded sheets: geometric from a node, reversed (R < 1), dual."""
    out = tmp_path_factory.mktemp("graded") / "graded.dice.h5"
    cli.run("dice", DATA / "cardinal_sphere.e", "--interval", 4, "--sheet-bias", "0=1.4", "--sheet-bias", "2=0.7",
            "--sheet-dual-bias", "1=1.3", "-o", out, "--quiet")
    return out


def bits(a):
    """float64 array -> its 64-bit patterns, so equality is bit equality (-0.0 != 0.0)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def write_box_msh(path, nx, ny, nz, size=1.0):
    """A structured nx*ny*nz box of hexes as Gmsh MSH 2.2 ASCII (for big, fast stores)."""
    def vid(i, j, k):
        return 1 + i + (nx + 1) * (j + (ny + 1) * k)

    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str((nx + 1) * (ny + 1) * (nz + 1))]
    for k in range(nz + 1):
        for j in range(ny + 1):
            for i in range(nx + 1):
                lines.append(f"{vid(i, j, k)} {i * size} {j * size} {k * size}")
    lines += ["$EndNodes", "$Elements", str(nx * ny * nz)]
    e = 0
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                e += 1
                c = [vid(i, j, k), vid(i + 1, j, k), vid(i + 1, j + 1, k), vid(i, j + 1, k),
                     vid(i, j, k + 1), vid(i + 1, j, k + 1), vid(i + 1, j + 1, k + 1), vid(i, j + 1, k + 1)]
                lines.append(f"{e} 5 2 1 1 " + " ".join(map(str, c)))
    lines += ["$EndElements", ""]
    Path(path).write_text("\n".join(lines))
    return path
