"""The front of planar layers from one exemplar: the angle the layers are turned about their
grain against the figures of bench/solid_structure.py (worst-axis scale, axis-energy, hist,
coherence raw and at matched sharpness), with the bands' width each slice family shows by
construction, and a contact sheet of the volumes at each angle (FOLDER/turn_ANGLE.png).

    python bench/solid_sheets_front.py [--tilts 25,35,45] [--sides 64]
        [--names wood_planks_horizontal] [--pictures FOLDER]

Needs the meters' venv (TEXMETRICS_PYTHON, as bench_solid.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import solid_structure as bench

from osmap_cli.solid.structure import layers as ly


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tilts", default="25,35,45")
    ap.add_argument("--sides", default="64")
    ap.add_argument("--names", default="wood_planks_horizontal")
    ap.add_argument("--pictures", type=Path, default=None)
    args = ap.parse_args(argv)
    print("| turn (deg) | band width shown on z / y / x (x the spacing) "
          + bench.HEADER.split("\n")[0][1:] + "\n|---|---" + bench.HEADER.split("\n")[1][1:])
    for tilt in (float(t) for t in args.tilts.split(",")):
        ly.TILT = tilt
        t = np.radians(tilt)
        shown = ly.face_spacings((np.cos(t), np.sin(t), 0.0))
        shown = shown * ly.stereological_scale((np.cos(t), np.sin(t), 0.0))
        prefix = f"| {tilt:g} | " + " / ".join(f"{v:.2f}" for v in shown) + " "
        sheet = None if args.pictures is None else args.pictures / f"turn_{tilt:g}.png"
        bench.run(args.names.split(","), [int(s) for s in args.sides.split(",")],
                  ["structure"], sheet, log=lambda line, p=prefix: print(p + line, flush=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
