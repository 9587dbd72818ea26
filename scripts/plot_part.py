#!/usr/bin/python3
"""The part picture of the README: a CAD part's coarse all-hex mesh beside
the fine mesh dicer makes from it on the CAD (as in figures 3 and 5 of the
Dicer paper), and, for contrast, the same dicing onto the coarse facets.

Everything drawn is dicer's own output, read through the Python package:
`dicer.mesh_coarse` (Gmsh, transfinite), `dicer.dice(..., geometry=CAD)`
and `Store.chunk(0, 1)`; the boundary quads of the hexes are drawn with
matplotlib (software rendering, no display needed).

usage: PYTHONPATH=build/python /usr/bin/python3 scripts/plot_part.py
           [--cad examples/bend.brep] [--interval 8] [--out docs/part.png]
"""
import argparse
import os
import tempfile

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import dicer  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Faces of a VTK HEX8, each ordered to face outwards of a right-handed hex.
HEX_FACES = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
BLOCK_COLORS = ["#7fa7d6", "#e3b36b", "#8cc084", "#d88c9a", "#b3a3d9"]


def boundary(chunk):
    """(quads as point rows, block index of each): faces used by one hex only."""
    cells = np.asarray(chunk.cells)
    faces = cells[:, HEX_FACES].reshape(-1, 4)
    owner = np.repeat(np.asarray(chunk.block_index), 6)
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    keep = first[count == 1]
    return np.asarray(chunk.points)[faces[keep]], owner[keep]


def shade(quads, base_colors, light=(0.35, -0.5, 0.8)):
    n = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    lam = np.clip(n @ (np.asarray(light) / np.linalg.norm(light)), 0, 1)
    rgb = np.array([matplotlib.colors.to_rgb(c) for c in base_colors])
    return np.clip(rgb * (0.45 + 0.55 * lam)[:, None], 0, 1)


def draw(ax, store, title, edge_width):
    quads, block = boundary(store.chunk(0, 1))
    colors = shade(quads, [BLOCK_COLORS[b % len(BLOCK_COLORS)] for b in block])
    ax.add_collection3d(Poly3DCollection(quads, facecolors=colors, edgecolors="#202020", linewidths=edge_width))
    pts = quads.reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo, zoom=1.15)
    ax.view_init(elev=32, azim=-58)
    ax.set_axis_off()
    ax.set_title(title, fontsize=11)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cad", default=os.path.join(ROOT, "examples", "bend.brep"))
    ap.add_argument("--size", type=float, default=0.7, help="mesh-coarse --size")
    ap.add_argument("--interval", type=int, default=6)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "part.png"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        coarse_msh = dicer.mesh_coarse(args.cad, os.path.join(tmp, "coarse.msh"), size=args.size)
        coarse = dicer.dice(coarse_msh, os.path.join(tmp, "coarse.dice.h5"), interval=1)
        flat = dicer.dice(coarse_msh, os.path.join(tmp, "flat.dice.h5"), interval=args.interval)
        fine = dicer.dice(coarse_msh, os.path.join(tmp, "fine.dice.h5"), interval=args.interval, geometry=args.cad)
        fig = plt.figure(figsize=(16, 6))
        name = os.path.basename(args.cad)
        panels = [
            (coarse, f"coarse mesh: {coarse.num_elements:,} hexes\n(dicer mesh-coarse {name}, transfinite)", 0.6),
            (flat, f"diced at interval {args.interval} onto the coarse facets\n({flat.num_elements:,} hexes)", 0.15),
            (fine, f"diced at interval {args.interval} on the CAD (dice --geometry)\n"
                   f"{fine.num_elements:,} hexes; store {fine.info['store_bytes'] / 1024:.0f} KiB", 0.15),
        ]
        for i, (store, title, width) in enumerate(panels):
            draw(fig.add_subplot(1, 3, i + 1, projection="3d"), store, title, width)
        fig.suptitle(f"{name}: coarse all-hex mesh and its diced fine mesh (colours: the three volumes' blocks)",
                     fontsize=12)
        fig.subplots_adjust(left=0, right=1, bottom=0, top=0.86, wspace=0)
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
