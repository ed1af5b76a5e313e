"""Where particle volumes gain or lose their size: the built structure alone (every particle in
its source profile's flat colour on the matrix's mean colour, no fill) against the finished
volume of method structure, each measured by granules.py, texmetrics' scale (worst axis) and
the profile meter (its worst statistic per cut family: axis slices, diagonal planes).

    python bench/solid_particles_stages.py [--sides 64,128]
        [--names gravel_green_stones,terrazzo_granite,samples/cells] [--seed 1]

A built figure near 1 with a finished one far from it puts the error in the fill, not in the
particle model. Names as bench/solid_structure.py (development exemplars, `samples/NAME`).
Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import granules, load_exemplar, texmetrics, worst_axis


def _worst(errors: dict) -> str:
    name = max(errors, key=errors.get)
    return f"{name} {errors[name]:.2f}"


def stages(name: str, side: int, seed: int, folder: Path) -> list[dict]:
    """One row per stage (built, final) of one volume."""
    from osmap_cli.imageio import write_image
    from osmap_cli.solid import SolidOptions, synthesize_solid
    from osmap_cli.solid.structure.meter import profile_meter
    from osmap_cli.solid.structure.method import build_structure, plan

    exemplar = load_exemplar(name, side)
    ex_path = folder / f"{Path(name).name}_{side}.png"
    write_image(ex_path, exemplar, 8)
    found = plan([exemplar], [0, 0, 0], seed=seed, probe_cap=side)
    if found.kind != "particles":
        return []
    built = build_structure(found, (side,) * 3, seed, False)
    final = synthesize_solid([exemplar], SolidOptions(width=side, height=side, depth=side,
                                                      seed=seed, method="structure")).voxels
    rows = []
    for stage, voxels in (("built", built.identity), ("final", final)):
        path = folder / f"{Path(name).name}_{side}_{stage}.npy"
        np.save(path, voxels)
        gran = granules(ex_path, path)
        prof = profile_meter(exemplar, voxels)
        rows.append({"name": name, "side": side, "stage": stage,
                     "bright": gran["bright_shift"], "dark": gran["dark_shift"],
                     "scale": worst_axis(texmetrics(ex_path, path))["scale"],
                     "axes": _worst(prof["errors"]["axes"]),
                     "diagonal": _worst(prof["errors"]["diagonal"]),
                     "worst": prof["worst"]})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sides", default="64,128")
    ap.add_argument("--names", default="gravel_green_stones,terrazzo_granite,samples/cells")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print("| exemplar | side | stage | granules bright / dark | scale | profile worst: axes | "
          "diagonal | worst |\n|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.names.split(","):
            for side in (int(s) for s in args.sides.split(",")):
                for r in stages(name, side, args.seed, Path(tmp)):
                    print(f"| {r['name']} | {r['side']}^3 | {r['stage']} | {r['bright']:.2f} / "
                          f"{r['dark']:.2f} | {r['scale']:.2f} | {r['axes']} | "
                          f"{r['diagonal']} | {r['worst']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
