"""The acceptance figures of `osmap solid`'s structure-first method beside the slice
optimisations: for every development exemplar and size, each method's volume is measured by the
independent meters (texmetrics.py, solidlook.py, granules.py, coherence at matched sharpness with
bench/lowpass.py) and by the profile meter (osmap_cli.solid.structure.meter), and a contact
sheet shows each volume's preview cube, its three middle slices and an oblique cut.

    python bench/solid_structure.py [--sides 64,128] [--methods structure,osmap,kopf,legacy]
        [--names terrazzo_granite,...] [--sheet docs/solid_structure_64.jpg] [--json out.json]
        [--markdown out.md] [--set KEY=VALUE] [--fill KEY=VALUE]

Names are development exemplars (../shared/exemplars/small), shipped samples as `samples/NAME`
(resized to the side like the others) or `wood_set` (samples/wood_end, _side, _top as
--x/--y/--z, at their 128 px). Prints two Markdown tables, each once: one row per volume, then
one row per method against the acceptance bars (BARS); --markdown writes the same to a file.
--set changes a solid option of method structure, --fill a field of its fill (Fill; or of
its Optimisation record as optimisation.FIELD).
Needs the meters' venv (TEXMETRICS_PYTHON, as bench/solid_meters.py).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from solid_meters import (
    NAMES,
    REPO,
    granules,
    load_exemplar,
    matched_coherence,
    solidlook,
    texmetrics,
    worst_axis,
)

WOOD_SET = ("wood_end", "wood_side", "wood_top")


@contextlib.contextmanager
def fill_changed(changes):
    """Method structure's Fill record with `changes` (field: value) while inside."""
    from osmap_cli.solid import method_structure

    if not changes:
        yield
        return
    original = method_structure.Options.from_solid.__func__

    own = {k: v for k, v in changes.items() if not k.startswith("optimisation.")}
    nested = {k.split(".", 1)[1]: v for k, v in changes.items() if k.startswith("optimisation.")}

    def changed(cls, opts):
        options = original(cls, opts)
        fill = dataclasses.replace(options.fill, **own)
        if nested:
            fill = dataclasses.replace(fill, optimisation=dataclasses.replace(
                fill.optimisation, **nested))
        return dataclasses.replace(options, fill=fill)

    method_structure.Options.from_solid = classmethod(changed)
    try:
        yield
    finally:
        method_structure.Options.from_solid = classmethod(original)


def synthesize(exemplars, side: int, method: str, seed: int = 1, changes=None, fill=None):
    """(voxels, seconds, structure step seconds or None, the method's report lines)."""
    from osmap_cli.solid import SolidOptions, synthesize_solid

    options = SolidOptions(width=side, height=side, depth=side, seed=seed,
                           method=method).replace(**dict(changes or {}))
    started = time.perf_counter()
    with fill_changed(fill):
        result = synthesize_solid(exemplars, options)
    seconds = time.perf_counter() - started
    structure = next((float(line.split()[2]) for line in result.report
                      if line.startswith("structure step")), None)
    return result.voxels, seconds, structure, list(result.report)


def measure(ex_path: Path, vol_path: Path, exemplar, voxels) -> dict:
    from osmap_cli.solid.structure.meter import profile_meter

    worst = worst_axis(texmetrics(ex_path, vol_path))
    look = solidlook(ex_path, vol_path)
    gran = granules(ex_path, vol_path)
    prof = profile_meter(exemplar, voxels)
    return {"axis": look["worst_axis_ratio"], "contrast": look["lowest_contrast_ratio"],
            "stripe": look["worst_stripe_ratio"], "hist": worst["hist"],
            "coh": worst["coh_mean"], "matched": matched_coherence(ex_path, vol_path),
            "scale": worst["scale"], "bright": gran["bright_shift"], "dark": gran["dark_shift"],
            "profile": prof["worst"] if prof else None,
            "profile_detail": prof}


def cut_picture(voxels, exemplar):
    """The preview (cube + middle slices) with an oblique (1, 1, 1) cut and the exemplar
    beside it, enlarged like the slices."""
    from osmap_cli.solid.preview import render_preview
    from osmap_cli.solid.structure.slices import oblique_slice

    prev = render_preview(voxels)
    cut = oblique_slice(voxels, (1.0, 1.0, 1.0))
    h = prev.shape[0]
    scale = max(1, (h - 40) // max(cut.shape[0], 1))

    def big(img):
        img = np.repeat(np.repeat(img[..., :3] if img.shape[2] >= 3 else
                                  np.repeat(img[..., :1], 3, 2), scale, 0), scale, 1)
        out = np.full((h, img.shape[1] + 8, 3), 0.15, np.float32)
        out[(h - img.shape[0]) // 2:(h - img.shape[0]) // 2 + img.shape[0], 4:4 + img.shape[1]] \
            = img
        return out

    return np.concatenate([prev[..., :3], big(cut), big(exemplar[:cut.shape[0], :cut.shape[1]])],
                          1)


def run(names, sides, methods, sheet=None, seed=1, changes=None, log=print, fill=None):
    from osmap_cli.imageio import read_image, write_image

    rows = []
    pictures = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in names:
            for side in sides:
                if name == "wood_set":
                    exemplars = [read_image(REPO / "samples" / f"{n}.png").pixels
                                 for n in WOOD_SET]
                    ex_side = exemplars[0].shape[0]
                    ex_path = REPO / "samples" / "wood_side.png"
                else:
                    exemplars = [load_exemplar(name, side)]
                    ex_side = side
                    ex_path = folder / f"{Path(name).name}_{side}.png"
                    write_image(ex_path, exemplars[0], 8)
                for method in methods:
                    voxels, seconds, structure_s, report = synthesize(
                        exemplars, side, method, seed, changes if method == "structure" else None,
                        fill if method == "structure" else None)
                    vol_path = folder / f"{Path(name).name}_{side}_{method}.npy"
                    np.save(vol_path, voxels)
                    figures = measure(ex_path, vol_path, exemplars[-1 if name == "wood_set"
                                                                   else 0], voxels)
                    row = {"name": name, "side": side, "ex_side": ex_side, "method": method,
                           "seconds": seconds, "structure_s": structure_s,
                           "kind": next((r.split(": ")[1].split(" (")[0] for r in report
                                         if r.startswith("structure built")), ""), **figures}
                    rows.append(row)
                    log(_row(row))
                    pictures.append(((name, side, method),
                                     cut_picture(voxels, exemplars[0])))
    if sheet is not None:
        _sheet(pictures, sheet)
    return rows


def _fmt(v, f="{:.2f}"):
    return "-" if v is None else f.format(v)


def _row(r) -> str:
    return (f"| {r['name']} | {r['ex_side']} -> {r['side']}^3 | {r['method']}"
            f"{' (' + r['kind'] + ')' if r['kind'] else ''} | {r['bright']:.2f} / "
            f"{r['dark']:.2f} | {r['scale']:.2f} | {r['axis']:.2f} | {r['hist']:.2f} | "
            f"{r['contrast']:.2f} | {r['coh']:.2f} / {r['matched']:.2f} | "
            f"{_fmt(r['profile'])} | {r['stripe']:.2f} | {r['seconds']:.1f}"
            f"{' (' + _fmt(r['structure_s'], '{:.1f}') + ')' if r['structure_s'] else ''} |")


HEADER = ("| exemplar | px -> volume | method | granules bright / dark | scale | axis-energy | "
          "hist | contrast | coh_mean raw / matched | profile worst error | stripe | s "
          "(structure s) |\n|---|---|---|---|---|---|---|---|---|---|---|---|")


def summary(rows, method) -> str:
    own = [r for r in rows if r["method"] == method]
    if not own:
        return ""
    axis = [r["axis"] for r in own]
    shifts = [v for r in own for v in (r["bright"], r["dark"])]
    scales = [abs(math.log2(r["scale"])) for r in own]
    prof = [r["profile"] for r in own if r["profile"] is not None]
    return (f"| {method} | {min(shifts):.2f}-{max(shifts):.2f} | {max(scales):.2f} | "
            f"{statistics.median(axis):.2f} ({max(axis):.2f}) | "
            f"{statistics.median(r['hist'] for r in own):.2f} | "
            f"{min(r['contrast'] for r in own):.2f} | "
            f"{statistics.median(r['coh'] for r in own):.2f} / "
            f"{statistics.median(r['matched'] for r in own):.2f} | "
            f"{_fmt(max(prof) if prof else None)} |")


SUMMARY_HEADER = ("| method | granules shifts (all volumes) | max abs log2 scale | axis-energy "
                  "median (max) | hist median | lowest contrast | coh_mean median raw / "
                  "matched | profile worst error |\n|---|---|---|---|---|---|---|---|")
BARS = ("Against the bars (granules shifts 0.85-1.18, |log2 scale| < 0.3, axis-energy median "
        "<= 1.15 and none above 1.3, hist median <= 0.8, lowest contrast >= 0.75, coh_mean no "
        "worse than method osmap, profile errors <= 0.10):")


def tables(rows, methods) -> str:
    """The per-volume table, then the summary against the bars, each once, as Markdown."""
    lines = [HEADER, *(_row(r) for r in rows), "", BARS, "", SUMMARY_HEADER]
    lines += [line for line in (summary(rows, m) for m in methods) if line]
    return "\n".join(lines) + "\n"


def _sheet(pictures, path: Path) -> None:
    from osmap_cli.imageio import write_image

    w = max(p.shape[1] for _, p in pictures)
    gap = 6
    parts = []
    for _, p in pictures:
        pad = np.full((p.shape[0], w, 3), 0.15, np.float32)
        pad[:, :p.shape[1]] = p
        parts.append(pad)
        parts.append(np.ones((gap, w, 3), np.float32))
    picture = np.concatenate(parts[:-1], 0)
    if path.suffix.lower() in (".jpg", ".jpeg"):  # docs/ pictures: at most MAX_BYTES
        import OpenImageIO as oiio
        from contact_sheet import write_jpeg

        buf = oiio.ImageBuf(oiio.ImageSpec(picture.shape[1], picture.shape[0], 3, oiio.FLOAT))
        buf.set_pixels(oiio.ROI(), np.ascontiguousarray(picture, np.float32))
        write_jpeg(buf, path)
    else:
        write_image(path, picture, 8)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sides", default="64,128")
    ap.add_argument("--methods", default="structure,osmap,kopf,legacy")
    ap.add_argument("--names", default=",".join(NAMES))
    ap.add_argument("--seed", type=int, default=1, help="every volume's --seed (default 1)")
    ap.add_argument("--sheet", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--markdown", type=Path, default=None,
                    help="write both tables (Markdown) to this file")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a solid tunable changed for method structure (e.g. "
                    "som_steps_per_node=0: no OS-Map training)")
    ap.add_argument("--fill", action="append", default=[], metavar="KEY=VALUE",
                    help="a field of method structure's fill changed (e.g. label_mismatch=0.1; "
                    "optimisation.position_histogram=9: a field of its Optimisation)")
    args = ap.parse_args(argv)
    from osmap_cli.options import option_spec
    from osmap_cli.solid import SolidOptions

    changes = {}
    for item in args.set:
        key, value = item.split("=", 1)
        changes[key] = option_spec(SolidOptions, key).kind(value)
    fill = {}
    for item in args.fill:
        key, value = item.split("=", 1)
        fill[key] = float(value)
    methods = args.methods.split(",")
    print(HEADER, flush=True)
    rows = run(args.names.split(","), [int(s) for s in args.sides.split(",")], methods,
               args.sheet, seed=args.seed, changes=changes,
               log=lambda line: print(line, flush=True), fill=fill)
    text = tables(rows, methods)
    print(text[text.index(BARS) - 1:])
    if args.markdown is not None:
        args.markdown.write_text(text)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
