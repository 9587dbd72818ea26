#!/usr/bin/python3
"""Independent reader for dicer's VTKHDF (UnstructuredGrid 1.0) files.

Usage: /usr/bin/python3 vtkhdf_check.py FILE.vtkhdf

Reads FILE with VTK's own vtkHDFReader (python3-vtk9, not dicer's code),
one piece at a time: UpdatePiece(k, P, 0) with P the number of partitions in
the file, so that piece k is exactly partition k; then the whole file at once
(piece 0 of 1, all partitions appended). It also opens the file with h5py
for the attributes and dataset shapes.

Prints one JSON object; each piece is on a line of its own:
  {"file": ..., "vtk_version": "9.1.0", "partitions": P,
   "pieces": [
  {"piece": k, "points": N, "cells": C, "points_type": "double",
   "cell_types": [sorted distinct VTK types], "block_ids": [sorted distinct],
   "element_ids": [min, max], "offsets_ok": true,
   "samples": [[GlobalNodeId, x, y, z], ...]},
   ...],
   "whole": {"points": ..., "cells": ...},
   "h5": {"version": [1, 0], "type": "UnstructuredGrid", "shapes": {NAME: [dims], ...}}}
Coordinates are JSON numbers written with Python's repr (shortest text
that reads back to the same double), so they compare bit for bit.

Exit status: 0 on success, 77 when vtk or h5py cannot be imported (the test
skips, or fails under CI), 1 when the reader rejects the file or reports an
error or a warning (9.1 only warns about a Version it does not know).
Note: 9.1 infers the data set type from the datasets present and does not
read the Type attribute; the C++ test checks that attribute's form itself.
"""
import json
import sys

try:
    import h5py
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
except ImportError as exc:  # pragma: no cover - environment without the readers
    print(f"vtkhdf_check: cannot import the readers: {exc}", file=sys.stderr)
    sys.exit(77)


def sample_indices(n, count=7):
    if n == 0:
        return []
    return sorted({(n - 1) * i // (count - 1) for i in range(count)})


def describe_piece(grid, piece):
    npts = grid.GetNumberOfPoints()
    ncells = grid.GetNumberOfCells()
    pd = grid.GetPointData()
    cd = grid.GetCellData()
    gid = pd.GetArray("GlobalNodeId")
    eid = cd.GetArray("GlobalElementId")
    bid = cd.GetArray("BlockId")
    if gid is None or eid is None or bid is None:
        raise RuntimeError(f"piece {piece}: GlobalNodeId, GlobalElementId or BlockId missing")
    types = vtk_to_numpy(grid.GetCellTypesArray()) if ncells else []
    # Every cell's point ids must be in range and its size must match its type.
    sizes = {9: 4, 12: 8}
    offsets_ok = True
    ids = vtk.vtkIdList()
    for c in sample_indices(ncells, 50):
        grid.GetCellPoints(c, ids)
        want = sizes.get(grid.GetCellType(c))
        if want is None or ids.GetNumberOfIds() != want or any(
            not 0 <= ids.GetId(i) < npts for i in range(ids.GetNumberOfIds())
        ):
            offsets_ok = False
    samples = []
    for i in sample_indices(npts):
        x, y, z = grid.GetPoint(i)
        samples.append([int(gid.GetValue(i)), x, y, z])
    eids = vtk_to_numpy(eid) if ncells else []
    return {
        "piece": piece,
        "points": npts,
        "cells": ncells,
        "points_type": grid.GetPoints().GetData().GetDataTypeAsString() if npts else "",
        "cell_types": sorted({int(t) for t in types}),
        "block_ids": sorted({int(b) for b in (vtk_to_numpy(bid) if ncells else [])}),
        "element_ids": [int(eids.min()), int(eids.max())] if ncells else [],
        "offsets_ok": offsets_ok,
        "samples": samples,
    }


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    path = sys.argv[1]
    with h5py.File(path, "r") as f:
        root = f["VTKHDF"]
        version = [int(v) for v in root.attrs["Version"]]
        type_attr = root.attrs["Type"]
        type_name = type_attr.decode("ascii") if isinstance(type_attr, bytes) else str(type_attr)
        shapes = {}
        root.visititems(lambda name, obj: shapes.__setitem__(name, list(obj.shape)) if isinstance(obj, h5py.Dataset) else None)
        partitions = int(root["NumberOfPoints"].shape[0])

    errors = []

    def on_error(_obj, _event):
        errors.append("vtkHDFReader reported an error")

    def on_warning(_obj, _event):
        errors.append("vtkHDFReader reported a warning (e.g. an unsupported version)")

    reader = vtk.vtkHDFReader()
    reader.AddObserver("ErrorEvent", on_error)
    reader.AddObserver("WarningEvent", on_warning)
    reader.SetFileName(path)
    pieces = []
    for k in range(partitions):
        reader.UpdatePiece(k, partitions, 0)
        if errors:
            raise RuntimeError(f"piece {k}: {errors[0]}")
        grid = reader.GetOutputDataObject(0)
        if grid is None or not grid.IsA("vtkUnstructuredGrid"):
            raise RuntimeError(f"piece {k}: reader output is not a vtkUnstructuredGrid")
        pieces.append(describe_piece(grid, k))

    whole_reader = vtk.vtkHDFReader()
    whole_reader.AddObserver("ErrorEvent", on_error)
    whole_reader.AddObserver("WarningEvent", on_warning)
    whole_reader.SetFileName(path)
    whole_reader.Update()
    if errors:
        raise RuntimeError(f"whole file: {errors[0]}")
    whole = whole_reader.GetOutputDataObject(0)

    out = [
        "{" + f'"file": {json.dumps(path)}, "vtk_version": {json.dumps(vtk.vtkVersion.GetVTKVersion())}, '
        f'"partitions": {partitions},',
        '"pieces": [',
        ",\n".join(json.dumps(p) for p in pieces),
        "],",
        '"whole": ' + json.dumps({"points": whole.GetNumberOfPoints(), "cells": whole.GetNumberOfCells()}) + ",",
        '"h5": ' + json.dumps({"version": version, "type": type_name, "shapes": shapes}),
        "}",
    ]
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Exception as exc:  # the reader rejected the file: a test failure, not a skip
        print(f"vtkhdf_check: {exc}", file=sys.stderr)
        sys.exit(1)
