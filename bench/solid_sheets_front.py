"""The front of planar layers from one exemplar: the angle the layers are turned by (about
their grain, or towards the cube diagonal) against the figures of bench/solid_structure.py
(worst-axis scale, axis-energy, hist, coherence raw and at matched sharpness), with each slice
family's scale (texmetrics, x / y / z), the band width each family shows by construction (in
the exemplar's spacing), and a contact sheet of the volumes at each angle
(FOLDER/turn_AXIS_ANGLE.png).

    python bench/solid_sheets_front.py [--tilts 25,35,45] [--axis grain|diagonal] [--sides 64]
        [--names wood_planks_horizontal] [--pictures FOLDER]

Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import solid_structure as bench
from solid_meters import load_exemplar, texmetrics

from osmap_cli.solid.structure import layers as ly


def towards_diagonal(normal, grain, degrees: float) -> np.ndarray:
    """The normal turned `degrees` towards the cube diagonal nearest it."""
    normal = np.asarray(normal, np.float64)
    diagonal = np.where(normal >= 0, 1.0, -1.0) / np.sqrt(3.0)
    side = diagonal - (diagonal @ normal) * normal
    side /= max(np.linalg.norm(side), 1e-9)
    return np.cos(np.radians(degrees)) * normal + np.sin(np.radians(degrees)) * side


def main(argv=None) -> int:
    from osmap_cli.imageio import write_image

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tilts", default="25,35,45")
    ap.add_argument("--axis", choices=("grain", "diagonal"), default="grain")
    ap.add_argument("--sides", default="64")
    ap.add_argument("--names", default="wood_planks_horizontal")
    ap.add_argument("--pictures", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.axis == "diagonal":
        ly.turned_normal = towards_diagonal
    print("| exemplar | side | turn (deg) | normal (z, y, x) | width shown z / y / x | scale x / "
          "y / z | granules bright / dark | scale | axis-energy | hist | coh_mean raw / "
          "matched |\n|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for tilt in (float(t) for t in args.tilts.split(",")):
            ly.TILT = tilt
            pictures = []
            for name in args.names.split(","):
                for side in (int(s) for s in args.sides.split(",")):
                    exemplar = load_exemplar(name, side)
                    ex_path = folder / f"{name}_{side}.png"
                    write_image(ex_path, exemplar, 8)
                    voxels, _, _, report = bench.synthesize([exemplar], side, "structure")
                    vol_path = folder / f"{name}_{side}.npy"
                    np.save(vol_path, voxels)
                    from osmap_cli.solid.structure.method import plan

                    normal = plan([exemplar], np.zeros(3, np.int64), seed=1).model.normal
                    shown = ly.face_spacings(normal) * ly.stereological_scale(normal)
                    axes = texmetrics(ex_path, vol_path)
                    per_axis = " / ".join(f"{axes[a]['scale']:.2f}" for a in ("x", "y", "z"))
                    r = bench.measure(ex_path, vol_path, exemplar, voxels)
                    print(f"| {name} | {side} | {tilt:g} | "
                          + ", ".join(f"{v:.2f}" for v in normal) + " | "
                          + " / ".join(f"{v:.2f}" for v in shown) + f" | {per_axis} | "
                          f"{r['bright']:.2f} / {r['dark']:.2f} | {r['scale']:.2f} | "
                          f"{r['axis']:.2f} | {r['hist']:.2f} | {r['coh']:.2f} / "
                          f"{r['matched']:.2f} |", flush=True)
                    pictures.append(((name, side), bench.cut_picture(voxels, exemplar)))
            if args.pictures is not None:
                bench._sheet(pictures, args.pictures / f"turn_{args.axis}_{tilt:g}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
