"""Several exemplars (`osmap synth --also`) measured on development exemplars: docs/fill.md.

Each development exemplar is cut into three disjoint quarter-size crops (top-left, top-right,
bottom-centre); the output has the image's size. Per exemplar and seed it reports each crop's
share of the output's positions and, with texmetrics.py (coh_mean, in its own venv), the
output against the whole image (the union of the crops) over a single-exemplar synthesis
from the first crop against that crop (same options and seed), and over the mean of the three
crops' own single-exemplar syntheses (*fair*: the first crop can be the easiest of the three).

With --sheet PATH, a contact sheet of the first seed: per exemplar the three crops, the output
from all three and the output from the first alone (docs/fill_several.jpg).

    python bench/several_measure.py [--names a,b] [--seeds 0,1,2,3,4,5] [--keep DIR] [--sheet PATH]
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from common import FULL_EXEMPLARS, measure_parser, measurement_folder  # noqa: E402
from common import texmetrics_coh as coh  # noqa: E402
from fill_sheet import sheet  # noqa: E402

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions, synthesize  # noqa: E402
from osmap_cli.synth.atlas import synthesize_several  # noqa: E402

NAMES = "water_caustics,bricks_dark_red,basket_weave_diagonal,knit_rope_mesh"


def crops(image: np.ndarray) -> list[np.ndarray]:
    """Three disjoint quarter-size crops: top-left, top-right, bottom-centre."""
    height, width = image.shape[:2]
    h, w = height // 2, width // 2
    return [image[:h, :w], image[:h, width - w:], image[height - h:, w // 2:w // 2 + w]]


def measure(name: str, seed: int, folder: Path) -> dict:
    """Shares and the coherence ratio of one exemplar at one seed."""
    path = FULL_EXEMPLARS / f"{name}.png"
    image = read_image(path).pixels[..., :3]
    parts = crops(image)
    opts = SynthOptions(width=image.shape[1], height=image.shape[0], seed=seed)
    several = synthesize_several(parts, opts)
    singles = [synthesize(part, opts).pixels for part in parts]
    files = {"several": several.pixels}
    for i, (part, single) in enumerate(zip(parts, singles)):
        files[f"crop{i}"], files[f"single{i}"] = part, single
    paths = {}
    for key, pixels in files.items():
        paths[key] = folder / f"{name}_{seed}_{key}.png"
        write_image(str(paths[key]), pixels, 8)
    single = [coh(paths[f"crop{i}"], paths[f"single{i}"]) for i in range(3)]
    return {"shares": [float((several.exemplar_index == i).mean()) for i in range(3)],
            "several": coh(path, paths["several"]), "single": single[0],
            "fair": float(np.mean(single)), "images": [*parts, several.pixels, singles[0]]}


def main() -> None:
    parser = measure_parser(__doc__, seeds="0,1,2,3,4,5")
    parser.add_argument("--names", default=NAMES)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    with measurement_folder(args.keep) as folder:
        print("| exemplar | seed | shares (crop 1, 2, 3) | coh several vs union "
              "| coh single vs its crop | ratio | fair |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for name in args.names.split(","):
            means = []
            for seed in seeds:
                m = measure(name, seed, folder)
                if seed == seeds[0]:
                    rows.append(m["images"])
                means.append((m["several"], m["single"], m["fair"]))
                shares = ", ".join(f"{s:.0%}" for s in m["shares"])
                print(f"| {name} | {seed} | {shares} | {m['several']:.2f} | {m['single']:.2f} "
                      f"| {m['several'] / m['single']:.2f} | {m['several'] / m['fair']:.2f} |",
                      flush=True)
            several, single, fair = np.mean(means, axis=0)
            print(f"| {name} | mean | | {several:.2f} | {single:.2f} | {several / single:.2f} "
                  f"| {several / fair:.2f} |", flush=True)
    if args.sheet:
        write_image(args.sheet, sheet(rows), 8)


if __name__ == "__main__":
    main()
