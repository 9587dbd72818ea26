"""Every function of the Python API against the dicer command on the same store.

The command and the module are two paths through the same library (argv
parsing, JSON printing, the cursors) vs (pybind11, numpy): coordinates and
ids must agree bit for bit. `query --json` writes the shortest decimal that
reads back to the same double, so json.loads gives the exact bits.
"""
import json
import os
import shutil

import numpy as np
import pytest

import dicer
from conftest import DATA, EXAMPLES, SOURCE, bits


def query_nodes(cli, store, a, b):
    rows = cli.json_lines("query", store, "--nodes", f"{a}:{b}")
    assert [r["id"] for r in rows] == list(range(a, b))
    return np.array([r["xyz"] for r in rows], dtype=np.float64).reshape(-1, 3)


def query_elements(cli, store, a, b):
    rows = cli.json_lines("query", store, "--elements", f"{a}:{b}")
    assert [r["id"] for r in rows] == list(range(a, b))
    return rows


@pytest.mark.parametrize("fixture", ["sphere_store", "prism_store", "shell_store", "graded_store"])
def test_info_is_the_cli_info(request, cli, fixture):
    path = request.getfixturevalue(fixture)
    with dicer.open(path) as s:
        assert s.info == cli.json("info", path)
        assert list(s.info) == list(cli.json("info", path))  # the documented key order too
        assert s.num_nodes == s.info["fine_nodes"] and s.num_elements == s.info["fine_elements"]


@pytest.mark.parametrize("fixture", ["sphere_store", "prism_store", "shell_store", "graded_store"])
def test_nodes_range_bit_equal_to_query(request, cli, fixture):
    path = request.getfixturevalue(fixture)
    s = dicer.open(path)
    n = s.num_nodes
    for a, b in [(0, 200), (n // 2 - 50, n // 2 + 50), (n - 150, n)]:
        got = s.nodes(a, b)
        assert got.shape == (b - a, 3) and got.dtype == np.float64
        assert np.array_equal(bits(got), bits(query_nodes(cli, path, a, b)))


def test_nodes_by_ids_equal_ranges(sphere_store):
    s = dicer.open(sphere_store)
    all_nodes = s.nodes(0, s.num_nodes)
    ids = np.random.default_rng(7).integers(0, s.num_nodes, 500)
    assert np.array_equal(bits(s.nodes(ids)), bits(all_nodes[ids]))
    assert np.array_equal(bits(s.nodes(list(ids[:3]))), bits(all_nodes[ids[:3]]))
    assert s.nodes([]).shape == (0, 3) and s.nodes(5, 5).shape == (0, 3)


def test_kept_coarse_tables_give_the_same_nodes(sphere_store):
    # The default 64 MiB cache keeps the sphere's coarse tables resident
    # (read_store); 4 MiB keeps none, nor does keep_tables=False. The same
    # bits every way.
    ids = np.random.default_rng(11).integers(0, 10**9, 2000)
    got = {}
    for mb, keep in ((64, True), (4, True), (64, False)):
        s = dicer.open(sphere_store, cache_mb=mb, keep_tables=keep)
        got[mb, keep] = s.nodes(ids % s.num_nodes)
        kept = s.cache_stats()["kept_bytes"]
        assert (kept > 0) == (mb == 64 and keep), (mb, keep, kept)
        assert kept <= mb * 2**20 // 4
    assert np.array_equal(bits(got[64, True]), bits(got[4, True]))
    assert np.array_equal(bits(got[64, True]), bits(got[64, False]))
    with pytest.raises(dicer.UsageError, match="keep_tables"):
        dicer.open(sphere_store, keep_tables="no")


def test_cache_stats_time_the_page_loads(sphere_store):
    # A fresh store's sweep loads pages, so it spent time loading them.
    s = dicer.open(sphere_store, read_ahead=0)
    s.sweep(threads=1)
    st = s.cache_stats()
    assert st["pages_read"] > 0
    assert st["load_seconds"] > 0
    # No read-ahead and one thread: every load was a miss's, nobody waited.
    assert st["demand_load_seconds"] == st["load_seconds"]
    assert st["load_wait_seconds"] == 0


@pytest.mark.parametrize("fixture", ["sphere_store", "prism_store", "shell_store", "graded_store"])
def test_elements_equal_to_query(request, cli, fixture):
    path = request.getfixturevalue(fixture)
    s = dicer.open(path)
    e = s.num_elements
    corners = 8 if s.mode == "volume" else 4
    for a, b in [(0, 120), (e - 120, e)]:
        rows = query_elements(cli, path, a, b)
        got = s.elements(a, b)
        assert got.shape == (b - a, corners) and got.dtype == np.int64
        assert got.tolist() == [r["nodes"] for r in rows]
        info = s.element_info(a, b)
        assert info["block"].tolist() == [r["block"] for r in rows]
        assert info["coarse_element"].tolist() == [r["coarse_element"] for r in rows]
        assert info["ijk"].tolist() == [r["ijk"] for r in rows]
        ids = np.arange(b - 1, a - 1, -1)  # by ids, reversed: random access, not the cursor
        assert s.elements(ids).tolist() == got[::-1].tolist()


def test_graded_store_reports_its_gradings(graded_store):
    with dicer.open(graded_store) as s:
        g = s.info["sheet_gradings"]
        assert g[0]["kind"] == "geometric" and g[0]["ratio"] == 1.4 and g[0]["start"] > 0
        assert g[1] == {"kind": "dual", "ratio": 1.3}
        assert g[2]["kind"] == "geometric" and g[2]["ratio"] == 0.7
        assert all(x is None for x in g[3:])


def test_box_equals_query_box(cli, prism_store):
    s = dicer.open(prism_store)
    lo, hi = s.nodes(0, s.num_nodes).min(0), s.nodes(0, s.num_nodes).max(0)
    mid = (lo + hi) / 2
    box = ",".join(repr(float(v)) for v in [*lo, *mid])
    want = [r["id"] for r in cli.json_lines("query", prism_store, "--box", box)]
    got = s.elements_in_box(lo.tolist(), mid.tolist())
    assert got.tolist() == want and 0 < len(want) < s.num_elements


def test_locate_equals_query_points(cli, sphere_store, tmp_path):
    """Store.locate against `dicer query --points`: the same ids and xi bit
    for bit, element centroids found in their element, outside points -1."""
    s = dicer.open(sphere_store)
    conn = s.elements(0, 40)
    pts = s.nodes(conn.ravel()).reshape(40, 8, 3).mean(axis=1)
    pts = np.vstack([pts, [[1e6, 0, 0]]])
    ids, xi = s.locate(pts, threads=2)
    assert ids[:40].tolist() == list(range(40)) and ids[40] == -1
    assert np.all((xi[:40] > 0) & (xi[:40] < 1))
    f = tmp_path / "p.txt"
    f.write_text("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in pts.tolist()))
    rows = cli.json_lines("query", sphere_store, "--points", str(f))
    assert [r["element"] for r in rows] == ids.tolist()
    assert np.array_equal(bits(np.array([r["xi"] for r in rows])), bits(xi))
    # The same points as .npy (float64), and a refused shape.
    np.save(tmp_path / "p.npy", pts)
    rows = cli.json_lines("query", sphere_store, "--points", str(tmp_path / "p.npy"))
    assert [r["element"] for r in rows] == ids.tolist()
    np.save(tmp_path / "bad.npy", pts[:, :2])
    code, msg = cli.error("query", sphere_store, "--points", str(tmp_path / "bad.npy"))
    assert code == 3 and "must have shape (n, 3)" in msg
    # Hand-made headers: each key read as its own value (a '<f8' in another
    # field passed for the dtype; a missing fortran_order read as Fortran
    # order; shape (-1, 3) and counts the file cannot hold read as huge).
    def npy(header, payload=b""):
        text = header + " " * (63 - (10 + len(header)) % 64) + "\n"
        return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode() + payload
    two = np.zeros((2, 3)).tobytes()
    cases = [("{'descr': '<f8', 'shape': (2, 3), }", two, "has no 'fortran_order'"),
             ("{'descr': '<f8', 'fortran_order': False, 'shape': (-1, 3), }", two, "not (-1,3)"),
             ("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000, 3), }", two,
              "shape (1000000000000, 3) needs 1000000000000 x 24 bytes; the file holds 48")]
    for k, (header, payload, says) in enumerate(cases):
        (tmp_path / f"h{k}.npy").write_bytes(npy(header, payload))
        code, msg = cli.error("query", sphere_store, "--points", str(tmp_path / f"h{k}.npy"))
        assert code == 3 and says in msg, (header, msg)
    f4 = np.zeros((2, 3), dtype="<f4").tobytes()
    (tmp_path / "ok.npy").write_bytes(npy("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), "
                                          "'note': \"'descr': '<f8'\"}", f4))
    assert len(cli.json_lines("query", sphere_store, "--points", str(tmp_path / "ok.npy"))) == 2
    # max_distance would be ignored on a volume store: refused, as the
    # command line refuses --max-distance.
    with pytest.raises(dicer.UsageError, match="is a volume store"):
        s.locate(pts, max_distance=0.5)
    code, msg = cli.error("query", sphere_store, "--points", str(f), "--max-distance", "0.5")
    assert code == 2 and "is a volume store" in msg
    # Before any point is read: an empty file too (it exited 0).
    (tmp_path / "none.txt").write_text("")
    code, msg = cli.error("query", sphere_store, "--points", str(tmp_path / "none.txt"), "--max-distance", "0.5")
    assert code == 2 and "is a volume store" in msg


def test_locate_on_a_surface_is_the_nearest_quad(cli, shell_store, tmp_path):
    """A surface store: Store.locate gives the nearest fine quad, its xi and
    the distance. Checked against numpy: the bilinear map of the quad's
    nodes at xi lies at that distance from the point, and no quad has a
    node much nearer (a lower bound that needs no closest-point solver);
    the CLI prints the same bits; max_distance cuts."""
    s = dicer.open(shell_store)
    rng = np.random.default_rng(3)
    conn = s.elements(0, s.num_elements)
    nodes = s.nodes(np.arange(s.num_nodes))
    lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    pts = lo + (hi - lo) * rng.uniform(-0.2, 1.2, size=(60, 3))
    ids, xi, dist = s.locate(pts, threads=2)
    assert xi.shape == (60, 2) and dist.shape == (60,) and np.all(ids >= 0)
    assert np.all((xi >= 0) & (xi <= 1))
    x = nodes[conn[ids]]  # (60, 4, 3), QUAD4 order
    u, v = xi[:, :1], xi[:, 1:]
    at = (1 - u) * (1 - v) * x[:, 0] + u * (1 - v) * x[:, 1] + u * v * x[:, 2] + (1 - u) * v * x[:, 3]
    assert np.allclose(np.linalg.norm(at - pts, axis=1), dist, rtol=0, atol=1e-9)
    # Every node is a point of the surface: none is nearer than the answer.
    nearest_node = np.min(np.linalg.norm(nodes[None, :, :] - pts[:, None, :], axis=2), axis=1)
    assert np.all(dist <= nearest_node + 1e-12)
    f = tmp_path / "p.txt"
    f.write_text("".join(f"{a!r} {b!r} {c!r}\n" for a, b, c in pts.tolist()))
    rows = cli.json_lines("query", shell_store, "--points", str(f))
    assert [r["element"] for r in rows] == ids.tolist()
    assert np.array_equal(bits(np.array([r["xi"] for r in rows])), bits(xi))
    assert np.array_equal(bits(np.array([r["distance"] for r in rows])), bits(dist))
    limit = float(np.median(dist))
    ids2, _, dist2 = s.locate(pts, max_distance=limit)
    assert np.array_equal(ids2 >= 0, dist <= limit) and np.array_equal(ids2[dist <= limit], ids[dist <= limit])
    assert np.all(np.isinf(dist2[ids2 < 0])) and np.array_equal(dist2[ids2 >= 0], dist[ids2 >= 0])
    rows = cli.json_lines("query", shell_store, "--points", str(f), "--max-distance", repr(limit))
    assert [r["element"] for r in rows] == ids2.tolist()
    assert all((r["distance"] is None) == (r["element"] < 0) for r in rows)  # a miss: no distance (inf)
    code, msg = cli.error("query", shell_store, "--point", "0,0,0", "--max-distance", "-1")
    assert code == 2 and "--max-distance" in msg


def test_element_neighbors_equal_query(cli, sphere_store):
    s = dicer.open(sphere_store)
    for e in (0, 17, s.num_elements - 1):
        want = cli.json("query", sphere_store, "--element-neighbors", e)["neighbors"]
        assert s.element_neighbors(e).tolist() == want
    for n in (0, 5, s.num_nodes - 1):
        want = cli.json("query", sphere_store, "--node-elements", n)["elements"]
        assert s.node_elements(n).tolist() == want and len(want) >= 1


def test_sweep_equals_cli_sweep(cli, sphere_store):
    s = dicer.open(sphere_store)
    for threads in (1, 2):
        want = cli.json("sweep", sphere_store, "--threads", threads)
        got = s.sweep(threads=threads)
        assert list(got) == list(want)
        for k in ("nodes", "elements", "checksum", "threads"):
            assert got[k] == want[k], k


def test_dice_from_python_equals_cli_dice(cli, tmp_path):
    """dicer.dice vs dicer dice with every interval option: same store content."""
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps({"global": 2, "blocks": {"2": 3}}))
    args = dict(interval=2, block_intervals={1: 2}, sheet_intervals={0: 4}, intervals_file=plan)
    with pytest.warns(dicer.DicerWarning, match="using the largest"):  # file's block 2 vs block 1
        py = dicer.dice(DATA / "cardinal_prism.exo", tmp_path / "py.dice.h5", **args)
    cli.run("dice", DATA / "cardinal_prism.exo", "-o", tmp_path / "cli.dice.h5", "--quiet", "--interval", 2,
            "--block-interval", "1=2", "--sheet-interval", "0=4", "--intervals-file", plan)
    c = dicer.open(tmp_path / "cli.dice.h5")
    assert py.info == c.info
    assert py.info["sheet_intervals"][0] == 4
    assert py.sweep()["checksum"] == cli.json("sweep", tmp_path / "cli.dice.h5")["checksum"]
    # size= goes through the same resolution as --size.
    by_size = dicer.dice(DATA / "cardinal_sphere.e", tmp_path / "size.dice.h5", size=0.2)
    cli.run("dice", DATA / "cardinal_sphere.e", "-o", tmp_path / "size_cli.dice.h5", "--quiet", "--size", "0.2")
    assert by_size.info["sheet_intervals"] == cli.json("info", tmp_path / "size_cli.dice.h5")["sheet_intervals"]


def test_dice_grading_and_entities_from_python_equal_cli(cli, tmp_path):
    """sheet_bias, sheet_dual_bias, block_bias, entity_bias and entity_intervals
    are the command's options (they came only through intervals_file)."""
    mesh = DATA / "cardinal_sphere.e"
    kw = dict(interval=4, sheet_bias={0: 1.4, 2: "first:0.05"}, sheet_dual_bias={1: 1.3}, block_bias={1: "0.8"})
    with pytest.warns(dicer.DicerWarning, match="sheet"):  # block 1's bias loses to the sheet biases, said
        py = dicer.dice(mesh, tmp_path / "py.dice.h5", **kw)
    cli.run("dice", mesh, "-o", tmp_path / "cli.dice.h5", "--quiet", "--interval", 4, "--sheet-bias", "0=1.4",
            "--sheet-bias", "2=first:0.05", "--sheet-dual-bias", "1=1.3", "--block-bias", "1=0.8")
    c = dicer.open(tmp_path / "cli.dice.h5")
    assert py.info == c.info
    g = py.info["sheet_gradings"]
    assert g[0]["ratio"] == 1.4 and g[1] == {"kind": "dual", "ratio": 1.3} and g[3]["ratio"] == 0.8
    assert py.sweep()["checksum"] == c.sweep()["checksum"]
    # Entities: the MSH file's classification, keyed "DIM:TAG" or (DIM, TAG).
    msh = DATA / "firedrake_cube_hex.msh"
    a = dicer.dice(msh, tmp_path / "e1.dice.h5", entity_intervals={(2, 1): 3}, entity_bias={"2:1": 1.2})
    cli.run("dice", msh, "-o", tmp_path / "e2.dice.h5", "--quiet", "--entity-interval", "2:1=3",
            "--entity-bias", "2:1=1.2")
    b = dicer.open(tmp_path / "e2.dice.h5")
    assert a.info == b.info and a.num_elements > 768  # some sheets of the 768 hexes got 3
    assert a.sweep()["checksum"] == b.sweep()["checksum"]
    # Errors in the command's words.
    with pytest.raises(dicer.UsageError, match=r'--sheet-bias 0=x: "x" is not a finite number'):
        dicer.dice(mesh, tmp_path / "bad.dice.h5", sheet_bias={0: "x"})
    with pytest.raises(dicer.UsageError, match="sheet 0 also has a --sheet-bias"):
        dicer.dice(mesh, tmp_path / "bad.dice.h5", sheet_bias={0: 1.2}, sheet_dual_bias={0: 1.2})
    with pytest.raises(dicer.UsageError, match=r"an entity is \"DIM:TAG\" or \(DIM, TAG\)"):
        dicer.dice(mesh, tmp_path / "bad.dice.h5", entity_intervals={2: 3})
    with pytest.raises(dicer.UsageError, match="is not DIM:TAG"):
        dicer.dice(msh, tmp_path / "bad.dice.h5", entity_bias={"4:1": 1.2})
    with pytest.raises(dicer.UsageError, match="is not a finite number"):
        dicer.dice(mesh, tmp_path / "bad.dice.h5", block_bias={1: True})
    assert not (tmp_path / "bad.dice.h5").exists()


def test_dice_bias_spaces_the_fine_nodes_by_the_series(tmp_path):
    """One unit hex at interval 3 or 4: the graded axis holds the series'
    partial sums (1:2:4 for R = 2; first:0.1 solves 0.1 (1 + R + R^2) = 1;
    dual 2 at interval 4 makes cells 1:2:2:1), the other axes stay even."""
    from conftest import write_box_msh
    box = write_box_msh(tmp_path / "one.msh", 1, 1, 1)
    r = (-1 + 37 ** 0.5) / 2
    cases = [(3, dict(sheet_bias={0: 2.0}), [0, 1 / 7, 3 / 7, 1]),
             (3, dict(sheet_bias={0: "first:0.1"}), [0, 0.1, 0.1 + 0.1 * r, 1]),
             (4, dict(sheet_dual_bias={1: 2}), [0, 1 / 6, 1 / 2, 5 / 6, 1])]
    for k, (n, kw, want) in enumerate(cases):
        s = dicer.dice(box, tmp_path / f"b{k}.dice.h5", interval=n, **kw)
        pts = s.nodes(0, s.num_nodes)
        even = np.linspace(0, 1, n + 1)
        graded = 0
        for axis in range(3):
            got = np.unique(np.round(pts[:, axis], 12))
            assert len(got) == n + 1, (kw, axis, got)
            if np.allclose(got, even):
                continue
            mirrored = np.sort(1 - np.array(want))
            assert np.allclose(got, want) or np.allclose(got, mirrored), (kw, axis, got)
            graded += 1
        assert graded == 1, kw


def hex27_msh(path, bend):
    """One HEX27 (MSH type 12) on the unit cube, nodes in Gmsh's order, its
    top bulging by `bend` (second-order nodes only: the corners stay)."""
    ref = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1),
           (0, -1, -1), (-1, 0, -1), (-1, -1, 0), (1, 0, -1), (1, -1, 0), (0, 1, -1), (1, 1, 0), (-1, 1, 0),
           (0, -1, 1), (-1, 0, 1), (1, 0, 1), (0, 1, 1), (0, 0, -1), (0, -1, 0), (-1, 0, 0), (1, 0, 0),
           (0, 1, 0), (0, 0, 1), (0, 0, 0)]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", "27"]
    for k, (a, b, c) in enumerate(ref):
        x, y, z = (a + 1) / 2, (b + 1) / 2, (c + 1) / 2
        z += bend * (1 - a * a) * (1 - b * b) * z
        lines.append(f"{k + 1} {x!r} {y!r} {z!r}")
    lines += ["$EndNodes", "$Elements", "1", "1 12 2 1 1 " + " ".join(str(k + 1) for k in range(27)), "$EndElements"]
    path.write_text("\n".join(lines) + "\n")


def test_second_order_dice_from_python_equals_cli(cli, tmp_path):
    """dicer.dice applies a second-order mesh's quadratic geometry as `dicer dice` does."""
    hex27_msh(tmp_path / "bent.msh", 0.2)
    hex27_msh(tmp_path / "flat.msh", 0.0)
    py = dicer.dice(tmp_path / "bent.msh", tmp_path / "py.dice.h5", interval=4)
    cli.run("dice", tmp_path / "bent.msh", "-o", tmp_path / "cli.dice.h5", "--quiet", "--interval", 4)
    c = dicer.open(tmp_path / "cli.dice.h5")
    assert py.info == c.info
    assert py.info["source_order"] == 2
    assert py.sweep()["checksum"] == c.sweep()["checksum"]
    flat = dicer.dice(tmp_path / "flat.msh", tmp_path / "flat.dice.h5", interval=4)
    assert flat.sweep()["checksum"] != py.sweep()["checksum"]
    # The top's centre node (fine node of the top face's middle) bulges by the bend.
    top = py.nodes(0, py.num_nodes)
    assert np.isclose(top[:, 2].max(), 1.2)


def test_dice_reports_interval_conflicts(tmp_path):
    """Invariant 5: a conflict is reported, never silent (a warning and Store.notes)."""
    with pytest.warns(dicer.DicerWarning):
        s = dicer.dice(DATA / "cardinal_prism.exo", tmp_path / "c.dice.h5", block_intervals={1: 2, 2: 5})
    assert s.notes, "two blocks asked for different intervals on a shared sheet"


def test_dice_with_geometry_equals_cli(cli, tmp_path, monkeypatch):
    """geometry= runs dicer-cad, as `dicer dice --geometry` does: identical nodes."""
    cyl = EXAMPLES / "cylinder.brep"
    coarse = tmp_path / "cyl.msh"
    cli.run("mesh-coarse", cyl, "--size", "0.8", "-o", coarse)
    # A grading option too: dicer-cad gets it as the command's words.
    py = dicer.dice(coarse, tmp_path / "py.dice.h5", interval=2, geometry=cyl, sheet_bias={0: 1.5})
    cli.run("dice", coarse, "--geometry", cyl, "--interval", 2, "--sheet-bias", "0=1.5", "-o",
            tmp_path / "cli.dice.h5", "--quiet")
    assert py.info["sheet_gradings"][0]["ratio"] == 1.5
    c = dicer.open(tmp_path / "cli.dice.h5")
    assert np.array_equal(bits(py.nodes(0, py.num_nodes)), bits(c.nodes(0, c.num_nodes)))
    assert py.sweep()["checksum"] == c.sweep()["checksum"]
    flat = dicer.dice(coarse, tmp_path / "flat.dice.h5", interval=2)
    assert not np.array_equal(bits(flat.nodes(0, flat.num_nodes)), bits(py.nodes(0, py.num_nodes))), \
        "geometry must move the boundary nodes onto the cylinder"
    # Relative names starting with '-' reach dicer-cad as names, not options
    # (dice("-c.msh", ...) worked without geometry= and failed with it).
    monkeypatch.chdir(tmp_path)
    shutil.copy(coarse, "-c.msh")
    shutil.copy(cyl, "-cyl.brep")
    dashed = dicer.dice("-c.msh", "-out.dice.h5", interval=2, geometry="-cyl.brep", sheet_bias={0: 1.5})
    assert np.array_equal(bits(dashed.nodes(0, dashed.num_nodes)), bits(py.nodes(0, py.num_nodes)))
    assert dicer.mesh_coarse("-cyl.brep", "-m.msh", size=0.8) == "-m.msh" and os.path.isfile("-m.msh")


@pytest.mark.parametrize("fixture", ["prism_store", "shell_store"])
def test_chunks_equal_cli_vtkhdf_export(request, cli, tmp_path, fixture):
    """Store.chunk(k, n) against `dicer export --format vtkhdf --chunk k/n`, read by h5py."""
    h5py = pytest.importorskip("h5py")
    path = request.getfixturevalue(fixture)
    s = dicer.open(path)
    n = 3
    for k in range(n):
        out = tmp_path / f"c{k}.vtkhdf"
        cli.run("export", path, "--format", "vtkhdf", "--chunk", f"{k}/{n}", "-o", out, "--quiet")
        c = s.chunk(k, n)
        with h5py.File(out, "r") as f:
            g = f["VTKHDF"]
            assert np.array_equal(bits(g["Points"][:]), bits(c.points))
            assert np.array_equal(g["PointData/GlobalNodeId"][:], c.global_node_ids)
            assert np.array_equal(g["CellData/GlobalElementId"][:], c.global_element_ids)
            assert np.array_equal(g["CellData/BlockId"][:], c.block_ids)
            assert np.array_equal(g["Connectivity"][:], c.cells.ravel())


@pytest.mark.parametrize("fixture", ["sphere_store", "prism_store", "shell_store", "graded_store"])
def test_chunks_tile_the_mesh_with_global_ids(request, fixture):
    """Chunk arrays against the store's own random access, and the chunks against each other."""
    s = dicer.open(request.getfixturevalue(fixture))
    n = 4
    seen = np.zeros(s.num_elements, dtype=np.int64)
    owned = np.zeros(s.num_nodes, dtype=np.int64)
    for k in range(n):
        c = s.chunk(k, n)
        assert np.array_equal(bits(c.points), bits(s.nodes(c.global_node_ids)))
        assert np.array_equal(c.global_node_ids[c.cells], s.elements(c.global_element_ids))
        assert np.array_equal(c.block_ids, s.element_info(c.global_element_ids)["block"])
        seen[c.global_element_ids] += 1
        mine = c.node_owner == k
        owned[c.global_node_ids[mine]] += 1
        r = c.range
        assert np.array_equal(c.global_node_ids[mine], np.arange(r["node_begin"], r["node_end"]))
        assert not c.points.flags.writeable  # a view into the chunk, not a copy
    assert (seen == 1).all() and (owned == 1).all()


@pytest.mark.parametrize("fixture", ["sphere_store", "shell_store"])
def test_blocks_cover_every_node_and_element_once(request, fixture):
    s = dicer.open(request.getfixturevalue(fixture))
    nodes = s.nodes(0, s.num_nodes)
    node_seen = np.zeros(s.num_nodes, dtype=np.int64)
    elem_seen = np.zeros(s.num_elements, dtype=np.int64)
    batches = s.blocks()
    assert len(batches) == s.num_coarse_elements
    for b in batches:
        ids, xyz, conn = b  # unpacks as (node ids, coordinates, connectivity)
        assert np.array_equal(bits(xyz), bits(nodes[ids]))
        assert np.array_equal(ids[b.owned], ids[ids >= b.node_first])
        node_seen[ids[b.owned]] += 1
        assert np.array_equal(conn, s.elements(b.element_ids))
        elem_seen[b.element_ids] += 1
    assert (node_seen == 1).all() and (elem_seen == 1).all()


def test_blocks_of_a_chunk_are_the_chunk(sphere_store):
    s = dicer.open(sphere_store)
    for k in range(3):
        c = s.chunk(k, 3)
        elems = np.concatenate([b.element_ids for b in s.blocks(chunk=(k, 3))])
        assert np.array_equal(elems, c.global_element_ids)
        nodes_only = list(s.blocks(chunk=(k, 3), connectivity=False))
        assert all(b.connectivity.shape == (0, 8) for b in nodes_only)


def test_partition_in_one_process(prism_store):
    """Store.partition(rank, size): owned nodes first (one id range), ghosts after, symmetric maps."""
    s = dicer.open(prism_store)
    size = 3
    parts = [s.partition(r, size) for r in range(size)]
    begin = 0
    for p in parts:
        g = p.node_global
        assert np.array_equal(g[:p.num_owned], np.arange(begin, begin + p.num_owned))
        begin += p.num_owned
        assert (p.node_owner[:p.num_owned] == p.rank).all() and (p.node_owner[p.num_owned:] < p.rank).all()
        assert np.array_equal(bits(p.points), bits(s.nodes(g)))
        assert np.array_equal(bits(p.x), bits(p.points[:, 0]))
        els = np.arange(p.element_begin, p.element_begin + p.num_elements)
        assert np.array_equal(g[p.connectivity], s.elements(els))
        for nb, shared in zip(p.neighbors, p.shared_nodes):
            q = parts[nb]
            back = q.shared_nodes[q.neighbors.index(p.rank)]
            assert np.array_equal(g[shared], q.node_global[back])
    assert begin == s.num_nodes


# The sweep checksum of include/dicer/sweep.hpp, written here in numpy from
# the header's text (uint64 arithmetic wraps mod 2^64, as the C++ does).
_K = np.array([0x9e3779b97f4a7c15, 0xbf58476d1ce4e5b9, 0x94d049bb133111eb, 0xd6e8feb86659fd93,
               0xa0761d6478bd642f, 0xe7037ed1a0b428db, 0x8ebc6af09c88c6e3, 0x589965cc75374cc3,
               0x1d8e4e27c47d124f, 0x2545f4914f6cdd1d, 0x5851f42d4c957f2d, 0x14057b7ef767814f,
               0x9fb21c651e98df25], dtype=np.uint64)


def _mix(h):
    h = h ^ (h >> np.uint64(32))
    h = h * np.uint64(0xd6e8feb86659fd93)
    return h ^ (h >> np.uint64(32))


def _rotl(x, r):
    return (x << np.uint64(r)) | (x >> np.uint64(64 - r))


def _numpy_checksum(node_ids, xyz, element_ids, conn):
    with np.errstate(over="ignore"):
        b = np.ascontiguousarray(xyz).view(np.uint64)
        nodes = _mix((node_ids.astype(np.uint64) * _K[0]) ^ b[:, 0] ^ _rotl(b[:, 1], 21) ^ _rotl(b[:, 2], 42))
        h = element_ids.astype(np.uint64) * _K[4]
        for q in range(conn.shape[1]):
            h = h + conn[:, q].astype(np.uint64) * _K[5 + q]
        return int(nodes.sum(dtype=np.uint64)) + int(_mix(h).sum(dtype=np.uint64))


@pytest.mark.parametrize("fixture", ["sphere_store", "shell_store"])
def test_batches_are_consecutive_ids_with_the_bits_of_nodes_and_elements(request, fixture):
    s = dicer.open(request.getfixturevalue(fixture))
    nodes = s.nodes(0, s.num_nodes)
    elements = s.elements(0, s.num_elements)
    next_node = next_element = 0
    total = 0
    for slab in (1, 50, 1 << 16):
        next_node = next_element = 0
        for b in s.batches(slab_points=slab):
            n0, xyz, e0, conn = b
            assert n0 == next_node and e0 == next_element
            assert xyz.shape == (b.node_end - n0, 3) and conn.shape[0] == b.element_end - e0
            assert np.array_equal(bits(xyz), bits(nodes[n0:b.node_end]))
            assert np.array_equal(conn, elements[e0:b.element_end])
            next_node, next_element = b.node_end, b.element_end
            if slab == 1 << 16:
                total += _numpy_checksum(np.arange(n0, b.node_end), xyz, np.arange(e0, b.element_end), conn)
        assert (next_node, next_element) == (s.num_nodes, s.num_elements)
    # The checksum, computed independently from the documented formula, is the sweep's.
    assert "%016x" % (total % (1 << 64)) == s.sweep(threads=2)["checksum"]


def test_arrays_kept_from_earlier_batches_and_blocks_stay_theirs(sphere_store):
    """Each batch's and block's arrays are the caller's, not views of buffers the
    iteration refills: collected first and compared after the whole pass (small
    slabs, so that there are many), they still hold their own ids' bits."""
    s = dicer.open(sphere_store)
    nodes = s.nodes(0, s.num_nodes)
    elements = s.elements(0, s.num_elements)
    kept = list(s.batches(slab_points=64))
    assert len(kept) > 10
    for b in kept:
        assert np.array_equal(bits(b.points), bits(nodes[b.node_begin:b.node_end]))
        assert np.array_equal(b.connectivity, elements[b.element_begin:b.element_end])
    kept[0].points[:] = np.nan  # the caller's to change, and no other batch's
    assert np.array_equal(bits(kept[1].points), bits(nodes[kept[1].node_begin:kept[1].node_end]))
    # Only a slice kept, the batch dropped: the slice keeps the buffer from
    # being handed to a later batch (the iterator recycles dead arrays' buffers).
    slices = [(b.node_begin, b.points[1:3], b.element_begin, b.connectivity[:2]) for b in s.batches(slab_points=64)]
    for n0, p, e0, c in slices:
        assert np.array_equal(bits(p), bits(nodes[n0 + 1:n0 + 1 + len(p)]))
        assert np.array_equal(c, elements[e0:e0 + len(c)])
    blocks = list(s.blocks())
    for b in blocks:
        assert np.array_equal(bits(b.points), bits(nodes[b.node_ids]))
        assert np.array_equal(b.connectivity, elements[b.element_ids])
    block_slices = [(b.node_ids[:3].copy(), b.points[:3]) for b in s.blocks()]
    for ids, p in block_slices:
        assert np.array_equal(bits(p), bits(nodes[ids]))


def test_the_python_benchmark_runs(sphere_store):
    """bench/bench_python.py (not timed here: only that it keeps working and
    reports every figure it documents)."""
    import subprocess
    import sys
    out = subprocess.run([sys.executable, str(SOURCE / "bench" / "bench_python.py"), str(sphere_store), "--rounds", "1"],
                         capture_output=True, text=True, check=True).stdout
    median = [line for line in out.splitlines() if line.startswith("median:")]
    assert len(median) == 1
    for k in ("batches", "copy", "blocks", "library"):
        assert (" %s " % k) in median[0]
    assert "batches / copy: median" in out and "blocks / copy: median" in out


def test_batches_of_a_chunk_are_the_chunks_elements(sphere_store):
    s = dicer.open(sphere_store)
    for k in range(3):
        r = s.chunk_ranges(3)[k]
        got = list(s.batches(chunk=(k, 3)))
        assert got[0].node_begin == r["node_begin"] and got[-1].node_end == r["node_end"]
        elems = np.concatenate([np.arange(b.element_begin, b.element_end) for b in got])
        assert np.array_equal(elems, s.chunk(k, 3).global_element_ids)
    with pytest.raises(dicer.UsageError):
        s.batches(slab_points=0)


def test_mesh_coarse_says_what_opencascade_reported(tmp_path):
    """OpenCASCADE's complaints about a STEP file reach Python in dicer's words:
    a warning when the file reads with a broken entity (they were lost: mesh_coarse
    dropped dicer-cad's warnings), the parser's line in the error when it cannot read."""
    gmsh = pytest.importorskip("gmsh")
    good = str(tmp_path / "box.step")
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 2, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.write(good)
    finally:
        gmsh.finalize()
    text = open(good).read()
    lines = text.splitlines(keepends=True)
    at = next(i for i, ln in enumerate(lines) if "APPLICATION_PROTOCOL_DEFINITION(" in ln)
    assert not lines[at + 1].startswith("#"), "the entity must go on on the next line"
    (tmp_path / "syntax.step").write_text("".join(lines[:at] + lines[at + 1:]))
    with pytest.warns(dicer.DicerWarning, match="OpenCASCADE reported problems reading it: .*Incorrect Syntax"):
        assert dicer.mesh_coarse(tmp_path / "syntax.step", tmp_path / "s.msh", size=0.5) == str(tmp_path / "s.msh")
    (tmp_path / "cut.step").write_text(text[: len(text) // 2])
    with pytest.raises(dicer.BadInputError, match=r"OpenCASCADE cannot read the CAD file: .*Line \d+") as e:
        dicer.mesh_coarse(tmp_path / "cut.step", tmp_path / "c.msh", size=0.5)
    assert "\x1b" not in str(e.value)
    assert not (tmp_path / "c.msh").exists()
