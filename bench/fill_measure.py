"""The figures of docs/fill.md for `osmap inpaint` and `osmap tileable`, on the development
exemplars (seed 0, defaults), measured with texmetrics.py (bench/fill_meter.py, in its venv).

* inpaint: a 64x64 hole and an irregular hole at the centre (bench/fill_sheet.py's): outside
  the mask identical, the 96x96 crop ratio and the rim z (the issue's targets: ratio under
  1.3, rim z under 3);
* exemplar: `inpaint --exemplar`, the top part of each photo (a 40x40 hole) filled from its
  bottom part (bench/fill_sheet.py's exemplar_split): the same three figures;
* tileable: seam_z of the photo and of the result, the centre identical, and the mean
  per-pixel error over the bands, over that of `osmap synth --tileable` at the image's size on
  the same pixels (the issue's target: no worse, 1.0), and the same ratio over the band pixels
  at least FAR px from the edges (patches that do not straddle the wrap lines);
* strip: the proposed reference for the bands: `osmap inpaint` of an interior vertical strip
  as wide as the two wrap bands together (the photo's centre columns), its error over synth's
  on the same pixels, next to the tileable result's wrap strip (the left and right bands) over
  synth's.

    python bench/fill_measure.py [--names a,b] [--what inpaint,exemplar,tileable,strip] [--keep DIR]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from common import FULL_EXEMPLARS, TEXMETRICS_PY, measure_parser, measurement_folder  # noqa: E402
from fill_sheet import blob_hole, exemplar_split, square_hole  # noqa: E402

from osmap_cli.imageio import read_image, write_image  # noqa: E402
from osmap_cli.synth import SynthOptions, synthesize  # noqa: E402
from osmap_cli.synth.fill import border_bands, inpaint, make_tileable  # noqa: E402
from osmap_cli.synth.options import FillOptions  # noqa: E402

METER = Path(__file__).resolve().parent / "fill_meter.py"
# band pixels at least this far from the image's edges: 7x7 patches that do not straddle the
# wrap lines, where the two bands meet
FAR = 4


def geomean(values) -> float:
    return float(np.exp(np.mean(np.log(values))))


class Jobs:
    """Images and masks written to a folder, and the meter's jobs on them."""

    def __init__(self, folder: Path):
        self.folder, self.jobs = folder, []

    def image(self, name: str, pixels: np.ndarray) -> str:
        path = self.folder / f"{name}.png"
        write_image(str(path), pixels, 8)
        return str(path)

    def mask(self, name: str, mask: np.ndarray) -> str:
        path = self.folder / f"{name}_mask.npy"
        np.save(path, mask)
        return str(path)

    def add(self, kind: str, job_id: str, **paths) -> None:
        self.jobs.append({"kind": kind, "id": job_id, **paths})

    def run(self) -> dict:
        spec = self.folder / "jobs.json"
        spec.write_text(json.dumps(self.jobs))
        out = subprocess.run([str(TEXMETRICS_PY), str(METER), str(spec)], capture_output=True,
                             text=True, check=True)
        return {r["id"]: r for r in map(json.loads, out.stdout.splitlines())}


def make(name: str, what, jobs: Jobs) -> dict:
    """The outputs of one exemplar and their jobs; returns what is known without the meter."""
    path = FULL_EXEMPLARS / f"{name}.png"
    image = read_image(path).pixels[..., :3]
    shape = image.shape[:2]
    if "inpaint" in what:
        for hole_name, hole in (("square", square_hole(shape)), ("irregular", blob_hole(shape))):
            out = inpaint(image, hole, SynthOptions(seed=0)).pixels
            jobs.add("inpaint", f"{name}/{hole_name}", original=str(path),
                     output=jobs.image(f"{name}_{hole_name}", out),
                     mask=jobs.mask(f"{name}_{hole_name}", hole))
    if "exemplar" in what:
        top, bottom, hole = exemplar_split(image)
        out = inpaint(top, hole, SynthOptions(seed=0), exemplars=[bottom]).pixels
        jobs.add("exemplar", f"{name}/exemplar", photo=str(path),
                 original=jobs.image(f"{name}_top", top),
                 output=jobs.image(f"{name}_from_exemplar", out),
                 mask=jobs.mask(f"{name}_top_hole", hole))
    if "tileable" not in what and "strip" not in what:
        return {}
    border = FillOptions().band(shape)
    bands = border_bands(shape, border)
    wrap = np.zeros(shape, bool)
    wrap[:, :border] = wrap[:, -border:] = True
    middle = np.zeros(shape, bool)
    middle[:, shape[1] // 2 - border:shape[1] // 2 + border] = True
    rows, cols = np.indices(shape)
    edge = np.minimum(np.minimum(rows, shape[0] - 1 - rows), np.minimum(cols, shape[1] - 1 - cols))
    far = bands & (edge >= FAR)
    masks = {m: jobs.mask(f"{name}_{m}", v)
             for m, v in (("bands", bands), ("far", far), ("wrap", wrap), ("middle", middle))}
    tiled = make_tileable(image, border, SynthOptions(seed=0)).pixels
    outputs = {"tileable": jobs.image(f"{name}_tileable", tiled),
               "synth": jobs.image(f"{name}_synth", synthesize(image, SynthOptions(
                   seed=0, width=shape[1], height=shape[0], tileable=True)).pixels)}
    jobs.add("band", f"{name}/photo/bands", exemplar=str(path), output=str(path),
             mask=masks["bands"], tileable=True)
    for source, output in outputs.items():
        for mask_name in ("bands", "far", "wrap", "middle"):
            jobs.add("band", f"{name}/{source}/{mask_name}", exemplar=str(path), output=output,
                     mask=masks[mask_name], tileable=True)
    if "strip" in what:
        strip = inpaint(image, middle, SynthOptions(seed=0)).pixels
        jobs.add("band", f"{name}/strip/middle", exemplar=str(path), tileable=False,
                 output=jobs.image(f"{name}_strip", strip), mask=masks["middle"])
    return {"border": border, "centre_same": bool(np.array_equal(image[~bands], tiled[~bands]))}


def main() -> None:
    parser = measure_parser(__doc__, sheet=False)
    parser.add_argument("--names", default=",".join(sorted(
        p.stem for p in FULL_EXEMPLARS.glob("*.png"))))
    parser.add_argument("--what", default="inpaint,exemplar,tileable,strip")
    args = parser.parse_args()
    what, names = args.what.split(","), args.names.split(",")
    with measurement_folder(args.keep) as folder:
        jobs = Jobs(folder)
        known = {name: make(name, what, jobs) for name in names}
        r = jobs.run()
    if "inpaint" in what:
        print("| exemplar | 64x64: crop ratio | rim z | irregular: crop ratio | rim z "
              "| outside identical |\n| --- | --- | --- | --- | --- | --- |")
        for n in names:
            sq, ir = r[f"{n}/square"], r[f"{n}/irregular"]
            print(f"| {n} | {sq['crop_ratio']:.2f} | {sq['rim_z']:.2f} | {ir['crop_ratio']:.2f} "
                  f"| {ir['rim_z']:.2f} | {sq['outside_identical'] and ir['outside_identical']} |")
    if "exemplar" in what:
        print("\n| exemplar | crop ratio | rim z | outside identical |\n| --- | --- | --- | --- |")
        for n in names:
            e = r[f"{n}/exemplar"]
            print(f"| {n} | {e['crop_ratio']:.2f} | {e['rim_z']:.2f} | {e['outside_identical']} |")
    if "tileable" in what:
        print("\n| exemplar | border | seam_z photo | seam_z tileable | centre identical "
              f"| band error tileable | synth --tileable | ratio | ratio {FAR}+ px from the edges "
              "|\n" + "| --- " * 9 + "|")
        ratios, far = [], []
        for n in names:
            t, s = r[f"{n}/tileable/bands"], r[f"{n}/synth/bands"]
            ratios.append(t["error"] / s["error"])
            far.append(r[f"{n}/tileable/far"]["error"] / r[f"{n}/synth/far"]["error"])
            print(f"| {n} | {known[n]['border']} | {r[f'{n}/photo/bands']['seam_z']:.2f} "
                  f"| {t['seam_z']:.2f} | {known[n]['centre_same']} | {t['error']:.2f} "
                  f"| {s['error']:.2f} | {ratios[-1]:.2f} | {far[-1]:.2f} |")
        print(f"| geometric mean | | | | | | | {geomean(ratios):.2f} | {geomean(far):.2f} |")
    if "strip" in what:
        print("\n| exemplar | tileable wrap strip / synth | inpainted interior strip / synth |"
              "\n| --- | --- | --- |")
        pairs = []
        for n in names:
            pairs.append((r[f"{n}/tileable/wrap"]["error"] / r[f"{n}/synth/wrap"]["error"],
                          r[f"{n}/strip/middle"]["error"] / r[f"{n}/synth/middle"]["error"]))
            print(f"| {n} | {pairs[-1][0]:.2f} | {pairs[-1][1]:.2f} |")
        print(f"| geometric mean | {geomean([p[0] for p in pairs]):.2f} "
              f"| {geomean([p[1] for p in pairs]):.2f} |")


if __name__ == "__main__":
    main()
