"""How narrow can the cut sizes of a space-filling tessellation be? The profile sizes that planar
cuts show of the most regular 3D tessellations (the BCC lattice's truncated octahedra, Kelvin's
foam; the FCC lattice's rhombic dodecahedra), turned at random, beside method structure's cells
(a relaxed hard-core seed set, osmap_cli.solid.structure.cells) and the exemplar's 2D profiles.
The cells are built at the exemplar's cell density with its wall width (particles.sources_from)
and cut by axis slices and diagonal planes (particles.cut_stats); the figure compared is the
spread of the profile diameters, the 90th percentile over the median (samples/cells: 1.11 at
128 px, 1.17 at 64 px): a 2D picture of polygons can be narrower than any section of a 3D
tessellation.

    python bench/solid_cells_bound.py [--side 96] [--seeds 1,2,3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def lattice(kind: str, spacing: float, side: int, rng) -> np.ndarray:
    """Seeds of a BCC or FCC lattice of one seed per spacing^3 voxels, turned at random,
    covering a (side,)*3 box."""
    basis = {"bcc": [(0, 0, 0), (0.5, 0.5, 0.5)],
             "fcc": [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]}[kind]
    a = spacing * len(basis) ** (1.0 / 3.0)  # the cubic cell holds len(basis) seeds
    reach = int(np.ceil(side * 1.8 / a)) + 1
    g = np.arange(-reach, reach + 1)
    cube = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pts = (cube[:, None, :] + np.array(basis)[None]).reshape(-1, 3) * a
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    pts = pts @ rot.T + side / 2.0 + rng.uniform(0, a, 3)
    keep = ((pts > -a) & (pts < side + a)).all(1)
    return pts[keep]


def spread(owner: np.ndarray) -> dict:
    from osmap_cli.solid.structure import particles as pt

    stats = pt.cut_stats(owner >= 0, False).figures()
    return {"d50": stats["d50"], "d90": stats["d90"], "spread": stats["d90"] / stats["d50"],
            "fraction": stats["fraction"]}


def main(argv=None) -> int:
    from osmap_cli.imageio import read_image
    from osmap_cli.solid.structure import cells as cl
    from osmap_cli.solid.structure import particles as pt
    from osmap_cli.solid.structure.analysis import analyse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=96)
    ap.add_argument("--seeds", default="1,2,3")
    args = ap.parse_args(argv)
    repo = Path(__file__).resolve().parent.parent
    image = read_image(repo / "samples" / "cells.png").pixels
    found = analyse(image)
    q = found.profiles.scaled(1.0 / found.reader.factor).quantiles()
    gap = pt.sources_from(image, found.reader.working_mask(image), found.profiles).gap
    print(f"samples/cells at {image.shape[0]} px: d50 {q[1]:.2f} px, d90 {q[3]:.2f} px, "
          f"spread {q[3] / q[1]:.3f}, walls {gap:.2f} px, wall fraction "
          f"{1 - found.profiles.fraction:.2f}")
    # the exemplar's cell density: a Voronoi cell of regular seeds cut at random shows about
    # 0.69 V^(2/3) of area (cells.initial_params)
    area = np.pi / 4.0 * q[1] ** 2 / found.profiles.fraction
    spacing = (area / 0.69) ** 0.5
    side = args.side
    print("| tessellation | seed | d50 px | d90 px | spread d90 / d50 | wall fraction |")
    print("|---|---|---|---|---|---|")
    for seed in (int(s) for s in args.seeds.split(",")):
        rng = np.random.default_rng(seed)
        rows = []
        for kind in ("bcc", "fcc"):
            pts = lattice(kind, spacing, side, rng)
            owner, wall = cl.laguerre((side,) * 3, pts, np.zeros(len(pts)), False)
            rows.append((kind.upper() + " lattice", np.where(wall > gap / 2, owner, -1)))
        count = int(round(side ** 3 / spacing ** 3))
        params = cl.CellParams(density=1.0)
        centres, weights = cl.seeds((side,) * 3, count, params, seed, True)
        owner, wall = cl.laguerre((side,) * 3, centres, weights, True)
        rows.append(("relaxed hard-core (method structure)", np.where(wall > gap / 2, owner, -1)))
        for name, labels in rows:
            s = spread(labels)
            print(f"| {name} | {seed} | {s['d50']:.2f} | {s['d90']:.2f} | {s['spread']:.3f} | "
                  f"{1 - s['fraction']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
