"""The veins' and layers' structure alone, before the fill: the built volume's identity guide
(every voxel its phases' mean colours, antialiased as the fill reads it) and its labels (the
same colours, hard-edged) measured by the independent meters against the exemplar's
segmentation rendered the same way (every pixel its phase's mean colour, hard-edged); the
guide's axis-energy also against the exemplar itself, and the exemplar against its own
segmentation (how much finer its texture reads than its phases' layout). It separates the
model's sizes and boxiness from the fill's.

    python bench/solid_sheets_guide.py [--sides 64,128] [--names marble_swirl_green,...]
        [--seed 1] [--set KEY=VALUE] [--pictures DIR]

--set changes a module constant of osmap_cli.solid.structure.sheets (AMPLITUDES=0.1,0.3, ...);
--pictures writes each guide's preview beside the rendered segmentation.
Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from solid_meters import granules, load_exemplar, solidlook, texmetrics, worst_axis


def guide(exemplar, side: int, seed: int):
    """(the rendered segmentation (H, W, C), the guide volume (Z, Y, X, C), the plan)."""
    from osmap_cli.solid.structure.method import build_structure, plan

    found = plan([exemplar], np.zeros(3, np.int64), "auto", 0, seed, False, probe_cap=side)
    built = build_structure(found, (side,) * 3, seed, False)
    return found.ex_identity[0], built.identity, found, found.colours[built.labels]


def run(names, sides, seed, pictures=None, log=print):
    from osmap_cli.imageio import write_image
    from osmap_cli.solid.preview import render_preview

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in names:
            for side in sides:
                exemplar = load_exemplar(name, side)
                seg, vol, found, hard = guide(exemplar, side, seed)
                ex_path = folder / f"{name}_{side}_seg.png"
                write_image(ex_path, np.clip(seg, 0, 1), 8)
                real_path = folder / f"{name}_{side}.png"
                write_image(real_path, exemplar, 8)
                vol_path = folder / f"{name}_{side}_guide.npy"
                np.save(vol_path, np.clip(vol, 0, 1))
                hard_path = folder / f"{name}_{side}_labels.npy"
                np.save(hard_path, np.clip(hard, 0, 1).astype(np.float32))
                tex = worst_axis(texmetrics(ex_path, vol_path))
                tex_hard = worst_axis(texmetrics(ex_path, hard_path))
                tex_ex = worst_axis(texmetrics(ex_path, real_path))
                look = solidlook(real_path, vol_path)
                gran = granules(ex_path, vol_path)
                log(f"| {name} | {side} | {found.kind} | {gran['bright_shift']:.2f} / "
                    f"{gran['dark_shift']:.2f} | {tex['scale']:.2f} / {tex_hard['scale']:.2f} | "
                    f"{tex_ex['scale']:.2f} | {look['worst_axis_ratio']:.2f} ("
                    + " / ".join(f"{look[a]['axis_ratio']:.2f}" for a in "xyz")
                    + f") | {'; '.join(found.model_lines())} |")
                if pictures:
                    Path(pictures).mkdir(parents=True, exist_ok=True)
                    prev = render_preview(np.clip(vol, 0, 1))[..., :3]
                    h = prev.shape[0]
                    big = np.repeat(np.repeat(seg[..., :3], 2, 0), 2, 1)[:h]
                    pad = np.zeros((h, big.shape[1], 3), np.float32)
                    pad[:big.shape[0]] = big
                    write_image(Path(pictures) / f"{name}_{side}.png",
                                np.clip(np.concatenate([prev, pad], 1), 0, 1), 8)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sides", default="64,128")
    parser.add_argument("--names", default="marble_swirl_green,wood_planks_horizontal")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--pictures")
    args = parser.parse_args(argv)
    from osmap_cli.solid.structure import sheets

    for item in args.set:
        key, value = item.split("=", 1)
        parsed = tuple(float(v) for v in value.split(",")) if "," in value else float(value)
        setattr(sheets, key, parsed)
    print("| exemplar | px | structure | guide granules bright / dark | scale guide / labels | "
          "scale exemplar / its layout | guide axis-energy worst (x / y / z) | model |\n"
          "|---|---|---|---|---|---|---|---|")
    run(args.names.split(","), [int(s) for s in args.sides.split(",")], args.seed,
        args.pictures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
