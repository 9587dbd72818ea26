#!/usr/bin/python3
"""Independent reader for dicer's LZ4 (32004) + Fletcher32 pages.

Usage: /usr/bin/python3 interop_check.py FILE.h5
       /usr/bin/python3 interop_check.py --write FILE.h5

Reads every dataset of FILE with h5py, decoding filter 32004 through the
hdf5plugin package (not dicer's code), and prints a JSON summary: an object
{"file": ..., "datasets": {NAME: SUMMARY, ...}} with one dataset per line, so
the C++ test can pick a line by name. SUMMARY holds dtype, shape, filters (the
dataset's pipeline), count, sum (exact for integers, math.fsum for floats),
first (up to 3 values), last, and digest: sum over i of (i + 1) * (the i-th
element's 64-bit pattern), modulo 2^64, for 8-byte element types.

With --write it instead creates FILE with pages written by the HDF Group's
LZ4 plugin (through hdf5plugin) in multi-block layouts, for dicer's decoder
to read: /x float64 arange(5000) * 0.25 (8000-byte chunks, LZ4 block size
3000: blocks of 3000, 3000, 2000 bytes), /noise int64 random (block size 3000,
every block stored raw), /mixed int64 (block size 4000: a compressed block of
zeros then a raw block of noise per chunk); all chunked by 1000 elements,
LZ4 then Fletcher32, with a partial last chunk.

Exit status: 0 on success, 77 when h5py/hdf5plugin cannot be imported (the
test skips), 1 when a dataset cannot be read (the test fails).
"""
import json
import math
import sys

try:
    import hdf5plugin  # noqa: F401  registers filter 32004 with HDF5
    import h5py
    import numpy as np
except ImportError as exc:  # pragma: no cover - environment without the readers
    print(f"interop_check: cannot import the independent readers: {exc}", file=sys.stderr)
    sys.exit(77)


def summarize(ds):
    data = ds[()]
    flat = np.ascontiguousarray(data).reshape(-1)
    if flat.dtype.kind == "f":
        total = math.fsum(float(x) for x in flat)
        to_py = float
    else:
        total = sum(int(x) for x in flat)
        to_py = int
    out = {
        "dtype": str(flat.dtype),
        "shape": list(ds.shape),
        "filters": sorted(str(k) for k in ds._filters.keys()),
        "count": int(flat.size),
        "sum": total,
        "first": [to_py(x) for x in flat[:3]],
        "last": to_py(flat[-1]) if flat.size else None,
    }
    if flat.dtype.itemsize == 8 and flat.size:
        bits = flat.view(np.uint64)
        weights = np.arange(1, flat.size + 1, dtype=np.uint64)
        with np.errstate(over="ignore"):
            out["digest"] = int(np.sum(bits * weights, dtype=np.uint64))
    return out


def write(path):
    rng = np.random.default_rng(1)
    noise = rng.integers(-(2**63), 2**63 - 1, size=2600, dtype=np.int64)
    mixed = rng.integers(-(2**63), 2**63 - 1, size=2700, dtype=np.int64)
    mixed[(np.arange(mixed.size) % 1000) < 500] = 0
    with h5py.File(path, "w") as f:
        f.create_dataset("x", data=np.arange(5000) * 0.25, chunks=(1000,), fletcher32=True,
                         **hdf5plugin.LZ4(nbytes=3000))
        f.create_dataset("noise", data=noise, chunks=(1000,), fletcher32=True, **hdf5plugin.LZ4(nbytes=3000))
        f.create_dataset("mixed", data=mixed, chunks=(1000,), fletcher32=True, **hdf5plugin.LZ4(nbytes=4000))
    return 0


def main(argv):
    if len(argv) == 3 and argv[1] == "--write":
        return write(argv[2])
    if len(argv) != 2:
        print("usage: interop_check.py [--write] FILE.h5", file=sys.stderr)
        return 2
    summaries = {}
    with h5py.File(argv[1], "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                summaries["/" + name] = summarize(obj)
        f.visititems(visit)
    print("{" + json.dumps("file") + ": " + json.dumps(argv[1]) + ", " + json.dumps("datasets") + ": {")
    items = sorted(summaries.items())
    for i, (name, summary) in enumerate(items):
        sep = "," if i + 1 < len(items) else ""
        print(json.dumps(name) + ": " + json.dumps(summary, sort_keys=True) + sep)
    print("}}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except Exception as exc:  # a read failure is the finding, not a crash
        print(f"interop_check: {type(exc).__name__}: {exc}", file=sys.stderr)
        sys.exit(1)
