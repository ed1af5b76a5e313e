"""The planks (or any layered exemplar) per slice family: texmetrics' scale and granules' bright
and dark shifts on the faces normal to x, y and z, for the finished volume and for the
structure's antialiased identity guide alone (the phase colours as the fill reads them), so
that a figure out of its bar can be traced to the layers' geometry or to the fill.

    OSMAP_SHARED=/work/shared TEXMETRICS_PYTHON=/tmp/texmetrics-venv/bin/python \
        python bench/solid_sheets_faces.py [--sides 64,128] [--names wood_planks_horizontal]
        [--seeds 1,2] [--set KEY=VALUE] [--patch MODULE.NAME=VALUE] [--keep DIR]

--keep DIR writes every volume there (NAME_SIDE_sSEED.npy and _guide.npy) to look at.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import granules_report, load_exemplar, texmetrics

sys.path.insert(0, str(Path(__file__).resolve().parent))


def guide_volume(exemplar, side: int, seed: int) -> np.ndarray:
    """The structure's identity guide as the fill reads it (bench/solid_sheets_guide.py)."""
    from solid_sheets_guide import guide

    return guide(exemplar, side, seed)[1]


def faces(ex_path: Path, vol_path: Path) -> dict:
    tex = texmetrics(ex_path, vol_path)
    gran = granules_report(ex_path, vol_path)
    return {a: (tex[a]["scale"], gran[a]["bright_shift"], gran[a]["dark_shift"]) for a in "xyz"}


def main(argv=None) -> int:
    from solid_structure import synthesize

    from osmap_cli.imageio import write_image

    ap = argparse.ArgumentParser()
    ap.add_argument("--sides", default="64")
    ap.add_argument("--names", default="wood_planks_horizontal")
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--set", action="append", default=[], help="a solid option KEY=VALUE")
    ap.add_argument("--patch", action="append", default=[],
                    help="MODULE.NAME=VALUE: a constant of osmap_cli.solid.structure.MODULE")
    ap.add_argument("--no-guide", action="store_true")
    ap.add_argument("--keep", type=Path)
    a = ap.parse_args(argv)
    changes = {}
    for kv in a.set:
        key, value = kv.split("=", 1)
        try:
            changes[key] = float(value) if "." in value else int(value)
        except ValueError:
            changes[key] = value
    import importlib

    for kv in a.patch:
        key, value = kv.split("=", 1)
        module, attr = key.rsplit(".", 1)
        setattr(importlib.import_module(f"osmap_cli.solid.structure.{module}"), attr,
                float(value))
    print("| volume | seed | what | scale x / y / z | bright x / y / z | dark x / y / z |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = a.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for name in a.names.split(","):
            for side in (int(s) for s in a.sides.split(",")):
                exemplar = load_exemplar(name, side)
                ex_path = folder / f"{name}_{side}.png"
                write_image(ex_path, exemplar, 8)
                for seed in (int(s) for s in a.seeds.split(",")):
                    volumes = {"volume": synthesize([exemplar], side, "structure", seed,
                                                    changes)[0]}
                    if not a.no_guide:
                        volumes["guide"] = guide_volume(exemplar, side, seed)
                    for what, voxels in volumes.items():
                        path = folder / f"{name}_{side}_s{seed}" \
                            f"{'' if what == 'volume' else '_' + what}.npy"
                        np.save(path, voxels)
                        f = faces(ex_path, path)
                        cols = [" / ".join(f"{f[x][i]:.2f}" for x in "xyz") for i in range(3)]
                        print(f"| {name} {side}^3 | {seed} | {what} | " + " | ".join(cols)
                              + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
