"""coh_mean per slice family: method structure's and method osmap's volumes of each exemplar
(seed 1, default options), scored by texmetrics.py on each family, raw and at matched sharpness
(bench/lowpass.py). The acceptance bar reads the worst family; this shows which family that is.

    python bench/solid_coherence_axes.py [--names wood_planks_horizontal,marble_swirl_green]
        [--side 64]

Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import low_passed, texmetrics, written_exemplars

FAMILIES = ("z", "y", "x")


def per_family(ex_path: Path, volume_path: Path) -> dict:
    """{family: (raw, matched)} coh_mean."""
    raw, matched = texmetrics(ex_path, volume_path), texmetrics(*low_passed(ex_path, volume_path))
    return {f: (raw[f]["coh_mean"], matched[f]["coh_mean"]) for f in FAMILIES}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--names", default="wood_planks_horizontal,marble_swirl_green")
    ap.add_argument("--side", type=int, default=64)
    args = ap.parse_args(argv)
    from osmap_cli.solid import SolidOptions, synthesize_solid

    side = args.side
    print("| volume | made by | z | y | x |\n|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, exemplar, ex_path in written_exemplars(args.names.split(","), side, folder):
            for method in ("structure", "osmap"):
                options = SolidOptions(width=side, height=side, depth=side, seed=1, method=method)
                out = folder / f"{name}_{method}.npy"
                np.save(out, synthesize_solid([exemplar], options).voxels)
                scores = per_family(ex_path, out)
                cells = " | ".join(f"{scores[f][0]:.2f} / {scores[f][1]:.2f}" for f in FAMILIES)
                print(f"| {name} {side}^3 | method {method} | {cells} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
