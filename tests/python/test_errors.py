"""Errors: each kind raises its dicer.Error subclass with the CLI's one-line message.

Each case runs the same bad input through the dicer command and through the
module: the class must be the one the command's exit status names, and
str(error) the line the command prints after "error: ".
"""
import json
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import dicer
from conftest import DATA, EXAMPLES, write_box_msh

KIND_OF_EXIT = {2: dicer.UsageError, 3: dicer.BadInputError, 4: dicer.UnsupportedError, 5: dicer.IoError,
                6: dicer.IdOverflowError, 7: dicer.GeometryError, 8: dicer.CorruptError}


def same_error(cli, cli_args, call):
    code, message = cli.error(*cli_args)
    with pytest.raises(dicer.Error) as e:
        call()
    assert type(e.value) is KIND_OF_EXIT[code], (code, e.value)
    assert str(e.value) == message
    assert e.value.exit_code == code
    return e.value


def test_hierarchy():
    for cls in KIND_OF_EXIT.values():
        assert issubclass(cls, dicer.Error)
    assert issubclass(dicer.UsageError, ValueError)
    assert issubclass(dicer.IdOverflowError, OverflowError)
    assert dicer.IdOverflowError.__name__ == "IdOverflowError"  # does not shadow the builtin OverflowError
    assert not issubclass(dicer.InternalError, dicer.Error)
    assert dicer.CorruptError.kind == "corrupt" and dicer.CorruptError.exit_code == 8


def test_missing_mesh(cli, tmp_path):
    missing = tmp_path / "nope.exo"
    same_error(cli, ["dice", missing, "-o", tmp_path / "o.h5"], lambda: dicer.dice(missing, tmp_path / "o.h5"))
    same_error(cli, ["info", missing], lambda: dicer.open(missing))


def test_directory_and_same_file(cli, tmp_path):
    same_error(cli, ["info", tmp_path], lambda: dicer.open(tmp_path))
    mesh = tmp_path / "m.e"
    mesh.write_bytes((DATA / "cardinal_sphere.e").read_bytes())
    same_error(cli, ["dice", mesh, "-o", mesh], lambda: dicer.dice(mesh, mesh))
    assert mesh.read_bytes() == (DATA / "cardinal_sphere.e").read_bytes()
    same_error(cli, ["dice", mesh, "-o", tmp_path], lambda: dicer.dice(mesh, tmp_path))


def test_bad_input_file(cli, tmp_path):
    bad = tmp_path / "bad.msh"
    bad.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0\n")
    same_error(cli, ["dice", bad, "-o", tmp_path / "o.h5"], lambda: dicer.dice(bad, tmp_path / "o.h5"))
    assert not (tmp_path / "o.h5").exists()


def test_unsupported_elements(cli, tmp_path):
    tet = tmp_path / "tet.msh"
    tet.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
                   "$EndNodes\n$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndElements\n")
    same_error(cli, ["dice", tet, "-o", tmp_path / "o.h5"], lambda: dicer.dice(tet, tmp_path / "o.h5"))


def test_bad_intervals(cli, tmp_path):
    s = DATA / "cardinal_sphere.e"
    o = tmp_path / "o.h5"
    same_error(cli, ["dice", s, "-o", o, "--interval", 0], lambda: dicer.dice(s, o, interval=0))
    same_error(cli, ["dice", s, "-o", o, "--interval", 1 << 50], lambda: dicer.dice(s, o, interval=1 << 50))
    same_error(cli, ["dice", s, "-o", o, "--interval", 1 << 20], lambda: dicer.dice(s, o, interval=1 << 20))
    same_error(cli, ["dice", s, "-o", o, "--block-interval", "99=2"], lambda: dicer.dice(s, o, block_intervals={99: 2}))
    same_error(cli, ["dice", s, "-o", o, "--sheet-interval", "9999=2"], lambda: dicer.dice(s, o, sheet_intervals={9999: 2}))
    same_error(cli, ["dice", s, "-o", o, "--size", "-1"], lambda: dicer.dice(s, o, size=-1.0))
    plan = tmp_path / "plan.json"
    plan.write_text('{"global": 2, "colour": "red"}')
    same_error(cli, ["dice", s, "-o", o, "--intervals-file", plan], lambda: dicer.dice(s, o, intervals_file=plan))
    with pytest.raises(dicer.UsageError):
        dicer.dice(s, o, interval=2.5)  # not a whole number: refused, never rounded
    with pytest.raises(dicer.UsageError):
        dicer.dice(s, o, interval=True)
    for flag in (True, np.bool_(True)):  # numpy's bool as Python's
        with pytest.raises(dicer.UsageError, match="--size: .* is not a finite number"):
            dicer.dice(s, o, size=flag)
    # Past Python's 4300-digit str() limit: named by size, not a ValueError.
    with pytest.raises(dicer.IdOverflowError, match="--interval: an integer of 16610 bits does not fit in 64 bits"):
        dicer.dice(s, o, interval=10**5000)
    with pytest.raises(dicer.IdOverflowError, match="--sheet-interval 0=<an integer of 16610 bits>: an integer of"):
        dicer.dice(s, o, sheet_intervals={0: 10**5000})
    assert not o.exists()


def test_query_out_of_range(cli, sphere_store):
    s = dicer.open(sphere_store)
    n, e = s.num_nodes, s.num_elements
    same_error(cli, ["query", sphere_store, "--nodes", f"{n - 1}:{n + 1}"], lambda: s.nodes(n - 1, n + 1))
    same_error(cli, ["query", sphere_store, "--elements", f"0:{e + 1}"], lambda: s.elements(0, e + 1))
    same_error(cli, ["query", sphere_store, "--node", n], lambda: s.nodes(n, n + 1))
    with pytest.raises(dicer.UsageError, match=f"node id {n} is out of range"):
        s.nodes([0, n])  # random access: the library's own words, FineMesh::node
    with pytest.raises(dicer.UsageError, match="element id -1 is out of range"):
        s.elements([-1])
    with pytest.raises(dicer.UsageError):
        s.nodes([1.5])
    with pytest.raises(dicer.UsageError):
        s.nodes(np.zeros((2, 2), dtype=np.int64))
    with pytest.raises(dicer.UsageError):
        s.nodes(10, 5)
    same_error(cli, ["export", sphere_store, "--format", "msh", "--chunk", "3/3", "-o", "x.msh"],
               lambda: s.chunk(3, 3))
    same_error(cli, ["export", sphere_store, "--format", "msh", "--chunk", "0/1000", "-o", "x.msh"],
               lambda: s.chunk(0, 1000))
    same_error(cli, ["sweep", sphere_store, "--threads", 0], lambda: s.sweep(threads=0))
    # Ids past 64 bits and a chunk that is not (k, n) are dicer's errors,
    # named (they were a TypeError and a RuntimeError from pybind11).
    for call in (s.element_neighbors, s.node_elements):
        with pytest.raises(dicer.IdOverflowError, match=r"\(id\): \"9223372036854775808\" does not fit in 64 bits"):
            call(2**63)
        with pytest.raises(dicer.UsageError, match="is not a whole number"):
            call(1.5)
        # numpy's bool has __index__ (True would be id 1), as Python's has.
        for flag in (True, np.bool_(True)):
            with pytest.raises(dicer.UsageError, match=r"\(id\): \"True\" is not a whole number"):
                call(flag)
        # str() of an int past 4300 digits raises ValueError: the message
        # names its size instead (10**5000 needs 16610 bits).
        with pytest.raises(dicer.IdOverflowError, match=r"\(id\): an integer of 16610 bits does not fit in 64 bits"):
            call(10**5000)
    with pytest.raises(dicer.IdOverflowError, match="an integer of 16610 bits does not fit"):
        s.nodes(10**5000, 10**5000 + 1)
    # A long value is quoted in 57 characters and "...", never splitting one
    # (C++ and Python cut alike).
    with pytest.raises(dicer.UsageError) as e:
        s.chunk("\u00e9" * 70, 1)
    assert '"' + "\u00e9" * 57 + '..."' in str(e.value) and "\ufffd" not in str(e.value), str(e.value)
    with pytest.raises(dicer.UsageError) as e:
        dicer.dice(DATA / "cardinal_sphere.e", "x.dice.h5", interval="\u00e9" * 70)
    assert '"' + "\u00e9" * 57 + '..."' in str(e.value), str(e.value)
    # A long value is quoted in 60 characters.
    with pytest.raises(dicer.UsageError, match=r'chunk: "\[0, 0, 0, 0, .{44}\.\.\." is not \(k, n\)'):
        s.batches(chunk=[0] * 100)
    assert np.array_equal(s.element_neighbors(np.int64(0)), s.element_neighbors(0))
    for bad in (3, "0/2", (0,), (0, 1, 2)):
        with pytest.raises(dicer.UsageError, match="is not \\(k, n\\), two whole numbers"):
            next(iter(s.blocks(chunk=bad)))
        with pytest.raises(dicer.UsageError, match="is not \\(k, n\\), two whole numbers"):
            s.batches(chunk=bad)
    with pytest.raises(dicer.UsageError, match="chunk \\(k, n\\): k: \"a\" is not a whole number"):
        s.blocks(chunk=("a", 2))
    assert [b.coarse_element for b in s.blocks(chunk=[1, 2])] == [b.coarse_element for b in s.blocks(chunk=(1, 2))]
    same_error(cli, ["info", sphere_store, "--cache-mb", 0], lambda: dicer.open(sphere_store, cache_mb=0))


def test_scalar_arguments_are_dicer_errors(sphere_store, tmp_path):
    # Each was pybind11's TypeError ("incompatible function arguments"), or
    # True taken as 1 and None as False; now the CLI's words, as for ids.
    s = dicer.open(sphere_store)
    for call in (lambda: s.chunk(0.0, 4), lambda: s.partition(0.5, 2), lambda: s.chunk_ranges(2.0),
                 lambda: s.sweep(threads=2.0), lambda: s.locate([[0, 0, 0]], threads=1.5),
                 lambda: s.batches(slab_points=1.0), lambda: s.chunk(True, 4), lambda: s.sweep(threads=True)):
        with pytest.raises(dicer.UsageError, match="is not a whole number"):
            call()
    with pytest.raises(dicer.IdOverflowError, match="does not fit in 64 bits"):
        s.chunk(0, 2**64)
    for lo, text in (("abc", "is not 3 numbers"), ([0, 0], "is not 3 numbers"), ([0, 0, True], "is not a number")):
        with pytest.raises(dicer.UsageError, match="elements_in_box: lo: .* " + text):
            s.elements_in_box(lo, [1, 1, 1])
    for pts in ([["a", "b", "c"]], "abc"):
        with pytest.raises(dicer.UsageError, match="locate: points must be an \\(n, 3\\) array of numbers"):
            s.locate(pts)
    assert np.array_equal(s.elements_in_box(np.zeros(3), (1, 1, 1)), s.elements_in_box([0, 0, 0], [1, 1, 1]))
    for bad in ("no", None, 1):
        with pytest.raises(dicer.UsageError, match="connectivity: must be True or False"):
            s.blocks(connectivity=bad)
    assert repr(s.chunk(np.int64(0), np.int32(2))) == repr(s.chunk(0, 2))
    b = next(s.blocks(connectivity=np.bool_(False)))
    assert f"{len(b.element_ids)} elements>" in repr(b)  # the repr counted connectivity rows: 0
    P = s.transfer(dicer.open(sphere_store))  # a store is nested in itself
    for call in (P.apply, P.apply_transpose):
        with pytest.raises(dicer.UsageError, match="threads: \"2.0\" is not a whole number"):
            call(np.zeros(s.num_nodes), threads=2.0)


def test_max_distance_is_read_as_the_command_reads_it(cli, tmp_path):
    skin = tmp_path / "skin.dice.h5"
    dicer.dice(DATA / "libmesh_cylinder_shell.exo", skin, interval=2)
    s = dicer.open(skin)
    for bad in (float("inf"), float("nan"), True, 10**400, "1"):
        with pytest.raises(dicer.UsageError, match="--max-distance: .* is not a finite number"):
            s.locate([[0, 0, 0]], max_distance=bad)
    same_error(cli, ["query", skin, "--point", "0,0,0", "--max-distance", "inf"],
               lambda: s.locate([[0, 0, 0]], max_distance=float("inf")))


def test_mapping_arguments_and_file_names(sphere_store, tmp_path):
    mesh, out = DATA / "cardinal_sphere.e", tmp_path / "x.dice.h5"
    with pytest.raises(dicer.UsageError, match='--sheet-interval: "0" is not a \\(KEY, interval\\) pair'):
        dicer.dice(mesh, out, sheet_intervals=[0, 2])
    with pytest.raises(dicer.UsageError, match='--sheet-interval: "5" is not a mapping'):
        dicer.dice(mesh, out, sheet_intervals=5)
    with pytest.raises(dicer.UsageError, match="-o: the file name is empty"):
        dicer.dice(mesh, "")
    with pytest.raises(dicer.UsageError, match="-o: a file name cannot hold a NUL byte"):
        dicer.dice(mesh, str(tmp_path / "a\0b.dice.h5"))
    with pytest.raises(dicer.UsageError, match="MESH: the file name is empty"):
        dicer.dice("", out)
    assert not out.exists()
    # A DICER_CAD that cannot run is dicer's IoError (was FileNotFoundError
    # or PermissionError from subprocess).
    for bad in (str(tmp_path / "nowhere"), str(tmp_path)):
        os.environ["DICER_CAD"] = bad
        try:
            with pytest.raises(dicer.IoError, match="cannot run: .*set DICER_CAD"):
                dicer.dice(mesh, out, geometry=EXAMPLES / "cylinder.brep")
        finally:
            del os.environ["DICER_CAD"]
    assert not out.exists()
    # A numpy block id is an id, as interval=np.int64(2) is an interval.
    a = dicer.dice(mesh, tmp_path / "a.dice.h5", block_intervals={np.int64(1): 2})
    b = dicer.dice(mesh, tmp_path / "b.dice.h5", block_intervals={1: 2})
    assert a.num_elements == b.num_elements


def test_relative_names_in_messages_are_the_names_given(cli, sphere_store, tmp_path, monkeypatch):
    # The store is read by its absolute name (an os.chdir must not lose it);
    # messages said that name where `dicer` says the one given.
    monkeypatch.chdir(tmp_path)
    data = Path(sphere_store).read_bytes()
    Path("cut.dice.h5").write_bytes(data[: len(data) // 2])
    e = same_error(cli, ["info", "cut.dice.h5"], lambda: dicer.open("cut.dice.h5"))
    assert str(e).startswith("cut.dice.h5: "), str(e)
    Path("sphere.dice.h5").write_bytes(data)
    cli.run("dice", DATA / "cardinal_sphere.e", "--interval", 2, "-o", "two.dice.h5", "--quiet")
    fine, coarse = dicer.open("sphere.dice.h5"), dicer.open("two.dice.h5")  # 3 is no multiple of 2
    proc = cli.run("transfer", "two.dice.h5", "sphere.dice.h5", "--check", "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    message = json.loads(proc.stdout)["message"]
    assert coarse.nesting(fine)["message"] == message
    assert "sphere.dice.h5" in message and str(tmp_path) not in message, message


def test_closed_store(sphere_store):
    s = dicer.open(sphere_store)
    c = s.chunk(0, 2)
    s.close()
    assert s.closed
    with pytest.raises(dicer.UsageError, match="closed"):
        s.nodes(0, 1)
    assert c.points.shape[0] == c.num_nodes  # a chunk keeps the mesh it came from


def test_corrupt_store(cli, tmp_path, sphere_store):
    """A flipped byte in the middle of the file: the page checksum names it, the same way in both."""
    bad = tmp_path / "bad.dice.h5"
    data = bytearray(sphere_store.read_bytes())
    # The last ~quarter of the file is page data (metadata sits at the start);
    # flip bytes until the command reports corruption, then ask Python.
    for offset in range(len(data) * 3 // 4, len(data) - 64, 97):
        trial = bytearray(data)
        trial[offset] ^= 0xFF
        bad.write_bytes(trial)
        proc = cli.run("sweep", bad, "--threads", 1, check=False)
        if proc.returncode == 8:
            break
    else:
        pytest.fail("no flipped byte gave a corrupt-store error")
    e = same_error(cli, ["sweep", bad, "--threads", 1], lambda: dicer.open(bad).sweep(threads=1))
    assert "bad.dice.h5" in str(e)


def test_geometry_error_through_dicer_cad(cli, tmp_path):
    """A mesh that does not fit the CAD: dicer-cad's exit 7 becomes GeometryError with its message."""
    o = tmp_path / "o.h5"
    mesh, cad = DATA / "cardinal_sphere.e", EXAMPLES / "cylinder.brep"
    same_error(cli, ["dice", mesh, "--geometry", cad, "-o", o], lambda: dicer.dice(mesh, o, geometry=cad))
    assert not o.exists()
    with pytest.raises(dicer.UsageError):
        dicer.dice(mesh, o, geometry_tol=1e-3)


def test_ctrl_c_interrupts_a_long_chunk(tmp_path):
    """SIGINT while chunk() runs without the GIL: KeyboardInterrupt from inside
    the call (it returns early), not after it has finished."""
    store = dicer.dice(write_box_msh(tmp_path / "box.msh", 6, 6, 6), tmp_path / "box.dice.h5", interval=26)
    t0 = time.perf_counter()
    store.chunk(0, 1)  # 3.8e6 elements: the time of a whole call
    whole = time.perf_counter() - t0
    timer = threading.Timer(0.15 * whole, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            store.chunk(0, 1)
        interrupted = time.perf_counter() - t0
    finally:
        timer.cancel()
    assert interrupted < 0.6 * whole, (interrupted, whole)


def test_names_and_paths_that_are_not_utf8(cli, tmp_path):
    """Linux names are bytes. A store whose name, source path or block name
    is not UTF-8 opens and reports (info raised UnicodeDecodeError; a str
    path from os.listdir was a TypeError), block names read as the
    command's JSON gives them (U+FFFD), paths as os.fsdecode gives them, and
    an error naming such a path keeps its message (it came out empty)."""
    box = write_box_msh(tmp_path / "box.msh", 1, 1, 1)
    raw = Path(box).read_text().replace("$Nodes", '$PhysicalNames\n1\n3 1 "blNAMEk"\n$EndPhysicalNames\n$Nodes', 1)
    # A node no hex uses: the reader's warning names the file (a warning
    # naming such a path raised TypeError after the store was written).
    raw = raw.replace("$Nodes\n8\n", "$Nodes\n9\n", 1).replace("$EndNodes", "9 5 5 5\n$EndNodes", 1)
    mesh = os.path.join(os.fsencode(tmp_path), b"m\xff.msh")
    with open(mesh, "wb") as f:
        f.write(raw.encode().replace(b"NAME", b"\xfe"))
    out = os.path.join(os.fsencode(tmp_path), b"s\xff.dice.h5")
    with pytest.warns(dicer.DicerWarning) as caught:
        s = dicer.dice(os.fsdecode(mesh), os.fsdecode(out), interval=2)  # str with surrogate escapes
    assert any("m\ufffd.msh: dropped 1 node" in str(w.message) for w in caught), [str(w.message) for w in caught]
    assert s.path == os.fsdecode(out)
    assert repr(s).startswith("<dicer.Store ")
    info = s.info
    assert info["blocks"][0]["name"] == "bl\ufffdk"
    assert info["source"] == os.fsdecode(mesh)
    assert cli.json("info", os.fsdecode(out))["blocks"][0]["name"] == "bl\ufffdk"
    s.close()
    b = dicer.open(out)  # bytes
    assert b.path == os.fsdecode(out) and b.num_elements == 8
    assert b.chunk(0, 1).block_names == {1: "bl\ufffdk"}
    bad = os.path.join(os.fsencode(tmp_path), b"not\xffa.dice.h5")
    with open(bad, "wb") as f:
        f.write(b"not a store" * 100)
    with pytest.raises(dicer.BadInputError) as e:
        dicer.open(bad)
    assert "not\ufffda.dice.h5" in str(e.value), str(e.value)


def test_dice_grading_strings_with_a_nul_are_refused(tmp_path):
    """A NUL ended the C++ reading early ("1.2\\0junk" read as 1.2) and broke
    dicer-cad's argv (ValueError): a UsageError naming the option."""
    mesh = DATA / "cardinal_sphere.e"
    for kw in (dict(sheet_bias={0: "1.2\0junk"}), dict(block_intervals={"a\0b": 2}),
               dict(entity_intervals={"2:1\0": 3})):
        with pytest.raises(dicer.UsageError, match="holds a NUL character"):
            dicer.dice(mesh, tmp_path / "n.dice.h5", **kw)
    assert not (tmp_path / "n.dice.h5").exists()
