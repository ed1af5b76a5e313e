"""Volume coherence against real material's: what coh_mean a volume's slices score beside what
the photographed material itself scores where the exemplar does not show it.

Each 128 px development exemplar is cut into four 64 px quadrants at its own scale. One quadrant
is the exemplar; the other three are real material of the same photograph that it does not
contain, and texmetrics.py scores each against it (raw coh_mean). Methods structure and osmap
make a 64^3 volume from the same quadrant (seed 1, default options), scored on each slice family
(raw coh_mean; the worst family is the bar's). A volume whose worst family scores at most what
the unseen quadrants score continues the material as coherently as the material continues
itself; a lower score than that is verbatim copy, which a volume can only have on some families
(docs/solid.md, "A volume cannot copy on all three axes").

    python bench/solid_coherence_real.py [--names terrazzo_granite,...] [--quadrant 0]
        [--methods structure,osmap]

Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import NAMES, load_exemplar, texmetrics, worst_axis

FAMILIES = ("z", "y", "x")
SIDE = 128


def quadrants(image: np.ndarray) -> list:
    """The four quadrants of a square image: top left, top right, bottom left, bottom right."""
    half = image.shape[0] // 2
    return [image[r:r + half, c:c + half] for r in (0, half) for c in (0, half)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--names", default=",".join(NAMES))
    ap.add_argument("--quadrant", type=int, default=0, choices=range(4),
                    help="which quadrant is the exemplar (0 top left ... 3 bottom right)")
    ap.add_argument("--methods", default="structure,osmap")
    args = ap.parse_args(argv)
    from osmap_cli.imageio import write_image
    from osmap_cli.solid import SolidOptions, synthesize_solid

    methods = args.methods.split(",")
    print("| exemplar (64 px quadrant) | real unseen quadrants | "
          + " | ".join(f"method {m}: z / y / x" for m in methods) + " |\n"
          + "|---" * (2 + len(methods)) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in args.names.split(","):
            parts = quadrants(load_exemplar(name, SIDE))
            exemplar = parts[args.quadrant]
            stem = name.replace("/", "_")
            ex_path = folder / f"{stem}_ex.png"
            write_image(ex_path, exemplar, 8)
            real = []
            for index, part in enumerate(parts):
                if index != args.quadrant:
                    path = folder / f"{stem}_unseen{index}.png"
                    write_image(path, part, 8)
                    real.append(worst_axis(texmetrics(ex_path, path))["coh_mean"])
            cells = []
            for method in methods:
                side = exemplar.shape[0]
                options = SolidOptions(width=side, height=side, depth=side, seed=1, method=method)
                out = folder / f"{stem}_{method}.npy"
                np.save(out, synthesize_solid([exemplar], options).voxels)
                scores = texmetrics(ex_path, out)
                cells.append(" / ".join(f"{scores[f]['coh_mean']:.2f}" for f in FAMILIES))
            print(f"| {name} (quadrant {args.quadrant}) | {' / '.join(f'{r:.2f}' for r in real)} | "
                  + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
