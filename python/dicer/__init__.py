"""dicer: huge implicit fine meshes, regenerated on demand from one HDF5 store.

    import dicer
    store = dicer.dice("part.exo", "part.dice.h5", interval=8)
    store = dicer.open("part.dice.h5", cache_mb=64)
    store.info                      # dict, the keys of `dicer info --json`
    xyz = store.nodes(0, 1000)      # float64 (1000, 3), bit-equal to `dicer query`
    conn = store.elements([5, 17])  # int64 (2, 8), VTK/Exodus HEX8 order
    for ids, points, conn in store.blocks(): ...   # one batch per coarse element
    for n0, points, e0, conn in store.batches(): ...  # slabs, consecutive ids, each node once
    chunk = store.chunk(3, 16)      # chunk 3 of 16, local numbering, global ids
    mesh = chunk.to_meshio()        # a meshio.Mesh, one cell block per element block
    store.sweep(threads=2)          # as `dicer sweep --json`
    P = coarse.transfer(fine)       # prolongation to a nested store: P.apply(x), P.apply_transpose(y)

Errors are dicer.Error subclasses named after the library's error kinds
(UsageError, BadInputError, UnsupportedError, IoError, IdOverflowError,
GeometryError, CorruptError, CancelledError); str(e) is the one line the
dicer command prints after "dicer COMMAND: error: " (an argument is named
by its command-line option: interval= is "--interval"), and e.exit_code is
the status it exits with. UsageError is also a ValueError, IdOverflowError also
an OverflowError. A bug in dicer raises dicer.InternalError.
"""

import os as _os
import shutil as _shutil
import stat as _stat
import subprocess as _subprocess
import warnings as _warnings

from . import _core
from ._core import (  # noqa: F401  (the public names)
    Batch,
    IdBatch,
    BadInputError,
    CancelledError,
    Chunk,
    CorruptError,
    Error,
    GeometryError,
    IdOverflowError,
    InternalError,
    IoError,
    Partition,
    Store,
    Transfer,
    UnsupportedError,
    UsageError,
    STORE_FORMAT_VERSION,
)
from ._paths import DICER_CAD_CANDIDATES as _DICER_CAD_CANDIDATES

__version__ = _core.__version__

__all__ = [
    "dice", "open", "mesh_coarse", "Store", "Transfer", "Chunk", "Partition", "Batch", "IdBatch", "Error", "UsageError", "BadInputError",
    "UnsupportedError", "IoError", "IdOverflowError", "GeometryError", "CorruptError", "CancelledError",
    "InternalError", "DicerWarning", "STORE_FORMAT_VERSION",
]


class DicerWarning(UserWarning):
    """What dicer accepted but reports: reader quirks, interval conflicts."""


# ---- argument checks, worded as the dicer command words them (cli/common.cpp)

def _file_kind(mode):
    if _stat.S_ISDIR(mode):
        return "a directory"
    if _stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if _stat.S_ISSOCK(mode):
        return "a socket"
    if _stat.S_ISCHR(mode):
        return "a character device"
    if _stat.S_ISBLK(mode):
        return "a block device"
    return "a special file"


def _path(p):
    # str, bytes or os.PathLike, as os.fsdecode reads them: a name that is
    # not UTF-8 (legal on Linux) comes as a str with surrogate escapes, and
    # goes to the library as os.fsencode's bytes, the file's own name.
    return _os.fsdecode(_os.fspath(p))


def _shown(text):
    # A str for messages: surrogate escapes (a path that is not UTF-8) as
    # U+FFFD, as the library's messages show such bytes; they cannot be
    # encoded for the library, and print badly.
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def _check_name(path, role):
    # The command's words for an empty name (cli/common.cpp); a NUL byte
    # cannot be in a file name (os.stat would raise ValueError).
    if path == "":
        raise UsageError(f"{role}: the file name is empty")
    if "\0" in path:
        raise UsageError(f"{role}: a file name cannot hold a NUL byte ({_shown(path)!r})")


def _check_input(path, role):
    _check_name(path, role)
    # stat, never open: opening a FIFO without a writer blocks for ever.
    try:
        st = _os.stat(path)
    except OSError as e:
        raise IoError(f"{_shown(path)}: cannot open: {_os.strerror(e.errno)}") from None
    if not _stat.S_ISREG(st.st_mode):
        raise UsageError(f"{_shown(path)}: {role} is {_file_kind(st.st_mode)}, not a regular file")


def _check_output(path, role, inputs):
    _check_name(path, role)
    try:
        out = _os.stat(path)
    except OSError:
        return  # a new file: nothing to protect
    if _stat.S_ISDIR(out.st_mode):
        raise UsageError(f"{_shown(path)}: {role} is a directory; give the name of the file to write")
    if not _stat.S_ISREG(out.st_mode):
        raise UsageError(f"{_shown(path)}: {role} is {_file_kind(out.st_mode)}; "
                         "dicer writes a temporary file and renames it over the output")
    for p, in_role in inputs:
        try:
            st = _os.stat(p)
        except OSError:
            continue
        if (st.st_dev, st.st_ino) == (out.st_dev, out.st_ino):
            raise UsageError(f"{_shown(path)}: {role} is the same file as {in_role} ({_shown(p)}); "
                             "writing it would destroy the input")


def _text(value):
    # A value as a message shows it, at most 60 characters; None where str()
    # raises: an int past Python's digit limit (4300), a user's __str__.
    try:
        text = str(value)
    except Exception:
        return None
    return text if len(text) <= 60 else text[:57] + "..."


def _quoted(value):
    text = _text(value)
    if text is not None:
        return f'"{text}"'
    if isinstance(value, int):
        return f"an integer of {value.bit_length()} bits"
    return f"a {type(value).__name__}"


def _is_bool(value):
    # Python's bool and numpy's (numpy.bool_; numpy.bool in numpy 2).
    t = type(value)
    return isinstance(value, bool) or (t.__module__ == "numpy" and t.__name__ in ("bool_", "bool"))


def _whole(what, value):
    # bool is an int in Python; an interval of True is a mistake, not 1.
    if _is_bool(value) or not isinstance(value, int):
        try:
            import numpy
            if isinstance(value, numpy.integer):
                return int(value)
        except ImportError:
            pass
        raise UsageError(f"{what}: {_quoted(value)} is not a whole number")
    if not -(1 << 63) <= value < (1 << 63):
        raise IdOverflowError(f"{what}: {_quoted(value)} does not fit in 64 bits")
    return value


def _finite(what, value):
    # float("0.5") would take a string: a number is asked for, as --size's
    # value is one on the command line only because argv is text.
    if isinstance(value, (str, bytes)):
        raise UsageError(f"{what}: {_quoted(value)} is not a finite number (a number, not a string)")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{what}: {_quoted(value)} is not a finite number") from None
    if v != v or v in (float("inf"), float("-inf")) or _is_bool(value):
        raise UsageError(f"{what}: {_quoted(value)} is not a finite number")
    return v


def _pairs(what, mapping, key, value=None, noun="interval"):
    if mapping is None:
        return []
    try:
        items = list(mapping.items() if hasattr(mapping, "items") else mapping)
    except TypeError:
        raise UsageError(f"{what}: {_quoted(mapping)} is not a mapping of KEY to {noun}") from None
    out = []
    label = lambda v: _text(v) or f"<{_quoted(v)}>"
    for item in items:
        try:
            k, n = item
        except (TypeError, ValueError):
            raise UsageError(f"{what}: {_quoted(item)} is not a (KEY, {noun}) pair") from None
        shown = f"{what} {label(k)}={label(n)}"
        out.append((key(shown, k), (value or _whole)(shown, n)))
    return out


def _no_nul(what, text):
    # A NUL would end the C++ reading early, or the argv of dicer-cad.
    if "\0" in text:
        raise UsageError(f"{what}: {text!r} holds a NUL character")
    return text


def _entity_key(what, k):
    # "DIM:TAG" as on the command line, or (DIM, TAG).
    if isinstance(k, str):
        return _no_nul(what, k)
    if isinstance(k, (tuple, list)) and len(k) == 2:
        return f"{_whole(what, k[0])}:{_whole(what, k[1])}"
    raise UsageError(f"{what}: an entity is \"DIM:TAG\" or (DIM, TAG)")


def _bias(what, value):
    # A ratio, or the command line's text: "1.2@17", "first:0.01", "last:0.5@17".
    if isinstance(value, str):
        return _no_nul(what, value)
    return repr(_finite(what, value))


def _option_text(pairs):
    # The command line's KEY=VALUE words, read by the library's one parser
    # (parse_interval_options) with or without dicer-cad.
    return [f"{k}={v}" for k, v in pairs]


def _block_key(what, k):
    # A block is named by its id (any whole number, numpy's too) or its
    # name, as on the command line.
    if isinstance(k, str):
        return _no_nul(what, k)
    try:
        return str(_whole(what, k))
    except UsageError:
        raise UsageError(f"{what}: a block is an id or a name") from None


def _sheet_key(what, k):
    return _whole(what, k)


def _dicer_cad():
    exe = _os.environ.get("DICER_CAD")
    if exe:
        return exe
    for c in _DICER_CAD_CANDIDATES:
        if c and _os.access(c, _os.X_OK):
            return c
    found = _shutil.which("dicer-cad")
    if found:
        return found
    raise IoError("cannot find dicer-cad (the dicer command built with Gmsh) for geometry=; "
                  "install dicer or set DICER_CAD")


_KIND_BY_EXIT = {2: UsageError, 3: BadInputError, 4: UnsupportedError, 5: IoError, 6: IdOverflowError,
                 7: GeometryError, 8: CorruptError, 129: CancelledError, 130: CancelledError, 143: CancelledError}


# Variables by which a process knows mpirun (or srun, prterun) started it as
# a rank (mpi/session.cpp launched_by_mpirun). A script run under mpirun
# passes them to its children; dicer-cad would then try to join the job as
# a rank that mpirun never started and abort in MPI_Init, so they are not
# passed: dicer-cad runs as one plain process.
_MPI_LAUNCH_PREFIXES = ("OMPI_COMM_WORLD_", "PMIX_", "PMI_")


def _child_env():
    return {k: v for k, v in _os.environ.items() if not k.startswith(_MPI_LAUNCH_PREFIXES)}


def _arg(path):
    # A relative name that starts with '-' would be read as an option.
    return "./" + path if path.startswith("-") else path


def _run_dicer_cad(args):
    """Runs `dicer-cad ARGS`; its failure becomes the dicer.Error its exit status names."""
    exe = _dicer_cad()
    try:
        proc = _subprocess.run([exe] + args, stdin=_subprocess.DEVNULL, stdout=_subprocess.PIPE,
                               stderr=_subprocess.PIPE, text=True, errors="replace", env=_child_env())
    except OSError as e:
        raise IoError(f"{_shown(exe)}: cannot run: {_os.strerror(e.errno) if e.errno else e}; "
                      "set DICER_CAD to dicer-cad (the dicer command built with Gmsh)") from None
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    report = {"warning": [], "note": []}
    for ln in lines:
        for tag, found in report.items():
            if f": {tag}: " in ln:
                found.append(ln.split(f": {tag}: ", 1)[1])
    if proc.returncode == 0:
        return report["warning"], report["note"]
    last = lines[-1] if lines else f"dicer-cad exited with status {proc.returncode}"
    # "dicer dice: error: MESSAGE" -> MESSAGE, the library's own line.
    for marker in (": error: ", ": internal error: "):
        if marker in last:
            last = last.split(marker, 1)[1]
            break
    if proc.returncode == 70:
        raise InternalError(last)
    raise _KIND_BY_EXIT.get(proc.returncode, Error)(last)


# ---- the API

def open(path, cache_mb=64, read_ahead=4, keep_tables=True):  # noqa: A001  (dicer.open, as the brief names it)
    """Opens a store. Memory stays under cache_mb MiB of decoded pages plus a
    small constant, whatever the fine mesh size.

    keep_tables: the coarse tables that fit a quarter of a budget of 32 MiB
    or more stay resident once read (counted in cache_stats()["kept_bytes"]),
    so random queries read their rows without a pin; False lets every page
    be evicted (the CLI's --no-keep-tables)."""
    path = _path(path)
    _check_input(path, "STORE")
    if not _is_bool(keep_tables):
        raise UsageError("--no-keep-tables: keep_tables must be True or False, not %r" % (keep_tables,))
    return _core._open(_os.fsencode(path), _whole("--cache-mb", cache_mb), _whole("--read-ahead", read_ahead), bool(keep_tables))


def dice(mesh, out, interval=None, sheet_intervals=None, block_intervals=None, size=None,
         intervals_file=None, geometry=None, geometry_tol=None, cache_mb=64, entity_intervals=None,
         sheet_bias=None, sheet_dual_bias=None, block_bias=None, entity_bias=None):
    """Dices a coarse mesh (Exodus II or Gmsh MSH) into the store `out` and
    opens it, like `dicer dice MESH -o OUT ...`.

    interval: every sheet gets it; size: each sheet the smallest interval
    making its edges no longer than size; block_intervals: {block id or
    name: n} (a sheet touching several takes the largest); sheet_intervals:
    {sheet id: n}; entity_intervals: {"DIM:TAG" or (DIM, TAG): n}, the
    sheets with an edge on that curve (1), surface (2) or volume (3) of
    the MSH classification or the CAD; intervals_file: the JSON file of
    `dicer dice --intervals-file` (the arguments win over it). Precedence:
    sheet > block and entity (the largest) > size > interval > 1.

    Grading, as the command's bias options: sheet_bias {sheet: R},
    block_bias {block: R}, entity_bias {entity: R}, sheet_dual_bias
    {sheet: R}, where R is a ratio or the command line's text: "1.2@17"
    (from node 17 of the mesh file), "first:0.01", "last:0.5@17" (a dual
    bias takes a ratio or "first:h", its end cells). So
    sheet_bias={3: "1.2@17"} is --sheet-bias 3=1.2@17. Conflicts are
    reported as DicerWarning and kept in Store.notes.

    A second-order mesh (HEX20, HEX27, QUAD8, QUAD9) is diced on its
    quadratic edges and faces, as the command does (info["source_order"]
    is 2).

    geometry: a STEP or BREP model; the fine nodes then lie on it (the CAD
    wins over a second-order mesh's mid nodes). dicer's
    Python module does not link Gmsh (as the dicer command does not), so
    this runs `dicer-cad dice ...` (beside the dicer command, or $DICER_CAD)
    and opens what it wrote: the same bits as the command line.
    """
    mesh, out = _path(mesh), _path(out)
    inputs = [(mesh, "MESH")]
    _check_input(mesh, "MESH")
    if intervals_file is not None:
        intervals_file = _path(intervals_file)
        _check_input(intervals_file, "--intervals-file")
        inputs.append((intervals_file, "--intervals-file"))
    if geometry is not None:
        geometry = _path(geometry)
        _check_input(geometry, "--geometry")
        inputs.append((geometry, "--geometry"))
    _check_output(out, "-o", inputs)
    interval = None if interval is None else _whole("--interval", interval)
    size = None if size is None else _finite("--size", size)
    grading = "bias (a ratio or text)"
    options = {
        "block_interval": _option_text(_pairs("--block-interval", block_intervals, _block_key)),
        "sheet_interval": _option_text(_pairs("--sheet-interval", sheet_intervals, _sheet_key)),
        "entity_interval": _option_text(_pairs("--entity-interval", entity_intervals, _entity_key)),
        "sheet_bias": _option_text(_pairs("--sheet-bias", sheet_bias, _sheet_key, _bias, grading)),
        "sheet_dual_bias": _option_text(_pairs("--sheet-dual-bias", sheet_dual_bias, _sheet_key, _bias, grading)),
        "block_bias": _option_text(_pairs("--block-bias", block_bias, _block_key, _bias, grading)),
        "entity_bias": _option_text(_pairs("--entity-bias", entity_bias, _entity_key, _bias, grading)),
    }
    if geometry_tol is not None and geometry is None:
        raise UsageError("--geometry-tol needs --geometry CAD")
    cache_mb = _whole("--cache-mb", cache_mb)
    _core._check_open_options(cache_mb, 4)  # before the work, not after it

    if geometry is None:
        r = _core._dice(_os.fsencode(mesh), _os.fsencode(out), interval, size, options,
                        None if intervals_file is None else _os.fsencode(intervals_file))
        warns, notes = [f"{_shown(mesh)}: {w}" for w in r["warnings"]], r["notes"]
    else:
        args = ["dice", _arg(mesh), "-o", _arg(out), "--quiet", "--geometry", _arg(geometry)]
        if geometry_tol is not None:
            args += ["--geometry-tol", repr(_finite("--geometry-tol", geometry_tol))]
        if interval is not None:
            args += ["--interval", str(interval)]
        if size is not None:
            args += ["--size", repr(size)]  # repr: the shortest text that reads back to the same double
        for name, words in options.items():
            for w in words:
                args += ["--" + name.replace("_", "-"), w]
        if intervals_file is not None:
            args += ["--intervals-file", _arg(intervals_file)]
        warns, notes = _run_dicer_cad(args)
    for text in warns + notes:
        _warnings.warn(text, DicerWarning, stacklevel=2)
    store = open(out, cache_mb=cache_mb)
    store._set_report(warns, notes)
    return store



def mesh_coarse(cad, out, size, surface=False, subdivide=False):
    """CAD (STEP/BREP) -> coarse all-hex (surface=True: all-quad) MSH 4.1 mesh,
    as `dicer mesh-coarse CAD --size H -o OUT`: run in dicer-cad (Gmsh).
    Returns the path written. What OpenCASCADE reported reading a damaged
    file comes as a DicerWarning (the model may be missing parts)."""
    cad, out = _path(cad), _path(out)
    _check_input(cad, "CAD")
    _check_output(out, "-o", [(cad, "CAD")])
    args = ["mesh-coarse", _arg(cad), "--size", repr(_finite("--size", size)), "-o", _arg(out), "--quiet"]
    for flag, value in (("--surface", surface), ("--subdivide", subdivide)):
        if not _is_bool(value):
            raise UsageError("%s: %s must be True or False, not %r" % (flag, flag[2:], value))
        if value:
            args.append(flag)
    warns, notes = _run_dicer_cad(args)
    for text in warns + notes:  # OpenCASCADE's complaints about the model among them
        _warnings.warn(text, DicerWarning, stacklevel=2)
    return out


# ---- meshio

_MESHIO_CELL = {8: "hexahedron", 4: "quad"}


def _chunk_to_meshio(self):
    """A meshio.Mesh of this chunk: one cell block per element block (in the
    order of the store's blocks), point data GlobalNodeId and NodeOwner, cell
    data GlobalElementId and BlockId (the names of dicer's VTKHDF export),
    and the node sets as point_sets."""
    import meshio
    import numpy as np

    cells = self.cells
    block_index = np.asarray(self.block_index)
    cell_blocks, global_ids, block_ids = [], [], []
    for b in np.unique(block_index):
        rows = np.flatnonzero(block_index == b)
        cell_blocks.append(meshio.CellBlock(_MESHIO_CELL[cells.shape[1]], np.ascontiguousarray(cells[rows])))
        global_ids.append(np.asarray(self.global_element_ids)[rows])
        block_ids.append(np.asarray(self.block_ids)[rows])
    point_sets = {}
    for s in self.node_sets:
        point_sets[s["name"] or f"nodeset_{s['id']}"] = s["node"]
    return meshio.Mesh(
        np.array(self.points),
        cell_blocks,
        point_data={"GlobalNodeId": np.array(self.global_node_ids), "NodeOwner": np.array(self.node_owner)},
        cell_data={"GlobalElementId": global_ids, "BlockId": block_ids},
        point_sets=point_sets,
    )


Chunk.to_meshio = _chunk_to_meshio
