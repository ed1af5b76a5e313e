"""What a layered volume's band draw holds against the fitted layers, per seed: the bands that
cross the volume and, per slice family (x / y / z), the mean band width the middle slices show
over the width the fitted run lengths give on that family (1.00: the fit), and each phase's
share of the voxels over its fitted share. Structure only (no fill): seconds per volume.

    OSMAP_SHARED=/work/shared python bench/solid_layers_bands.py [--names wood_planks_horizontal]
        [--sides 64,128] [--seeds 1,2,3,4,5] [--wood-set]

--wood-set: the shipped wood_end / wood_side / wood_top as the x / y / z exemplars (rings).
The widths are read from the label changes along the slices' rows and columns: planar bands of
width w along u, normal n, cross n_i / w boundaries per voxel along axis i, so a family normal
to axis a shows (|n_b| + |n_c|) / (w sqrt(1 - n_a^2)) changes per pixel along its rows and
columns for bands w / sqrt(1 - n_a^2) wide on it. Rings report the width along u alone (a ring's
boundary crosses 4 / (pi w) rows and columns per voxel, on average over its turn).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
REPO = Path(__file__).resolve().parents[1]


def fitted_width(model) -> tuple[float, np.ndarray]:
    """(the chain's mean band width along u, each phase's share of u) of the fitted model."""
    means = np.array([float(np.mean(r)) for r in model.runs])
    t = np.asarray(model.transitions, np.float64)
    vals, vecs = np.linalg.eig(t.T)
    pi = np.real(vecs[:, np.argmin(np.abs(vals - 1))])
    pi = pi / pi.sum()  # how often each phase's band comes
    return float(pi @ means), pi * means / float(pi @ means)


def face_widths(labels: np.ndarray, normal) -> list[float]:
    """The mean band width (px) the slices of each family x, y, z show (their rows and
    columns' label changes; the middle half of the volume)."""
    n = np.abs(np.asarray(normal, np.float64))
    changes = [np.mean(np.diff(labels, axis=i) != 0) for i in range(3)]  # per voxel, axes z y x
    out = []
    for family in range(3):
        a = 2 - family  # the axis the family's slices are normal to
        others = [i for i in range(3) if i != a]
        rate = sum(changes[i] for i in others)
        along_u = sum(n[i] for i in others) / max(rate, 1e-9)
        out.append(along_u / np.sqrt(max(1 - n[a] ** 2, 1e-9)))
    return out


def main(argv=None) -> int:
    from solid_meters import load_exemplar

    from osmap_cli.imageio import read_image
    from osmap_cli.solid.structure import layers as ly
    from osmap_cli.solid.structure.method import build_structure, plan

    ap = argparse.ArgumentParser()
    ap.add_argument("--names", default="wood_planks_horizontal")
    ap.add_argument("--sides", default="64,128")
    ap.add_argument("--seeds", default="1,2,3,4,5")
    ap.add_argument("--wood-set", action="store_true")
    a = ap.parse_args(argv)
    print("| volume | seed | bands crossing | width on faces / fitted x / y / z | phase shares / "
          "fitted |")
    print("|---|---|---|---|---|")
    sets = []
    if a.wood_set:
        wood = [read_image(REPO / "samples" / f"wood_{n}.png").pixels for n in
                ("end", "side", "top")]
        sets.append(("wood set", wood, np.arange(3), None))
    else:
        for name in a.names.split(","):
            for side in (int(s) for s in a.sides.split(",")):
                sets.append((f"{name} {side}^3", [load_exemplar(name, side)],
                             np.zeros(3, np.int64), side))
    for label, images, ex_of_axis, side in sets:
        found = plan(images, ex_of_axis, structure="layers")
        model = found.model
        mean, shares = fitted_width(model)
        sides = [side] if side else [int(s) for s in a.sides.split(",")]
        for size in sides:
            shape = (size, size, size)
            for seed in (int(s) for s in a.seeds.split(",")):
                built = build_structure(found, shape, seed, False)
                bands = ly.layer_bands(shape, model, seed, False)
                lo, hi = float(bands.u.min()), float(bands.u.max())
                crossing = int(np.sum((bands.starts[1:] > lo) & (bands.starts[:-1] < hi)))
                got = np.bincount(built.labels.ravel(), minlength=len(shares)) / built.labels.size
                if model.rings:
                    # across the axis, a ring's boundary crosses the rows and columns
                    # (|cos| + |sin|) / w per voxel: 4 / (pi w) on average over its turn
                    changes = sum(np.mean(np.diff(built.labels, axis=i) != 0) for i in range(3))
                    widths = f"along u {4 / np.pi / max(changes, 1e-9) / mean:.2f}"
                else:
                    w = face_widths(built.labels, model.normal)
                    fit = mean * ly.face_spacings(model.normal)[::-1]
                    widths = " / ".join(f"{g / f:.2f}" for g, f in zip(w, fit))
                print(f"| {label if side else f'{label} {size}^3'} | {seed} | {crossing} | "
                      f"{widths} | " + " / ".join(f"{g / s:.2f}" for g, s in zip(got, shares))
                      + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
