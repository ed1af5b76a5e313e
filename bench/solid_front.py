"""The measured front of `osmap solid` (issue 13): one point per variant of the method, each the
medians over the four solid development exemplars, with a contact sheet of the volumes.

Issue 13 asks for axis-energy <= 1.15 (median, none above 1.3), colour hist <= 0.8, coh_mean no
worse than the previous default, |log2 scale| < 0.3 and slice contrast >= 0.7 at once; no
variant meets them all, so this shows what each knob trades. Variants are the methods and the
option changes measured in sessions 6 to 8 (docs/solid.md), all run here with today's code.

    python bench/solid_front.py [--side 64] [--only NAME,NAME] [--sheet docs/solid_front_64.jpg]

Prints a Markdown table; --sheet writes the contact sheet (one row per variant, in the table's
order; one column per exemplar: the `--preview` cube of each volume). Needs the meters' venv
(TEXMETRICS_PYTHON, as bench_solid.py). About 6 minutes at 64^3, 40 at 128^3, on two cores.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_solid import NAMES, _exemplar, _look, _matched_coherence, _metrics, _worst

# (name, method, option changes, what it stands for)
VARIANTS = (
    ("default", "osmap", {}, "the default (--method osmap)"),
    ("muted", "osmap", {"position_weight": 3.0, "final_histogram": 0.5},
     "--preset muted (the default before session 8)"),
    ("pw6", "osmap", {"position_weight": 6.0}, "position weight 6"),
    ("fh1", "osmap", {"final_histogram": 1.0}, "a full final histogram match"),
    ("w6", "osmap", {"kopf_window": 6}, "6x6 slice windows"),
    ("w6fh1", "osmap", {"kopf_window": 6, "final_histogram": 1.0},
     "6x6 windows and a full histogram match"),
    ("stride1", "osmap", {"kopf_stride": 1}, "every window centre (4x the work)"),
    ("sharpen0", "osmap", {"sharpen": 0}, "no mean-shift sharpening (Kopf's mean)"),
    ("kopf", "kopf", {}, "--method kopf (Kopf et al. 2007)"),
    ("legacy", "legacy", {}, "--method legacy (the default before issue 13)"),
)


def _point(name, method, changes, side, folder, seed=1):
    """Synthesize the four volumes of one variant; per-exemplar figures and previews."""
    from osmap_cli.imageio import write_image
    from osmap_cli.solid import SolidOptions, synthesize_solid
    from osmap_cli.solid.preview import render_preview

    rows, previews = [], []
    for material in NAMES:
        exemplar = _exemplar(material, side)
        ex_path = folder / f"{material}_{side}.png"
        write_image(ex_path, exemplar, 8)
        options = SolidOptions(width=side, height=side, depth=side, seed=seed,
                               method=method).replace(**changes)
        started = time.perf_counter()
        result = synthesize_solid([exemplar], options)
        seconds = time.perf_counter() - started
        vol_path = folder / f"{material}_{side}_{name}.npy"
        np.save(vol_path, result.voxels)
        worst = _worst(_metrics(ex_path, vol_path))
        look = _look(ex_path, vol_path)
        rows.append({"material": material, "axis": look["worst_axis_ratio"],
                     "hist": worst["hist"], "coh": worst["coh_mean"],
                     "matched": _matched_coherence(ex_path, vol_path), "scale": worst["scale"],
                     "contrast": look["lowest_contrast_ratio"],
                     "stripe": look["worst_stripe_ratio"], "s": seconds})
        previews.append(render_preview(result.voxels))
        print(f"[front] {name} {material}: " + " ".join(
            f"{k} {v:.2f}" for k, v in rows[-1].items() if k != "material"), file=sys.stderr,
            flush=True)
    return rows, previews


def _summary(rows) -> dict:
    def median(key):
        return statistics.median(r[key] for r in rows)

    # wood with one exemplar is excepted from the scale bar, as in the issue
    scales = [abs(math.log2(r["scale"])) for r in rows if not r["material"].startswith("wood")]
    return {"axis": median("axis"), "axis_max": max(r["axis"] for r in rows),
            "hist": median("hist"), "coh": median("coh"), "matched": median("matched"),
            "scale": median("scale"), "log2_max": max(scales),
            "contrast_min": min(r["contrast"] for r in rows), "stripe": median("stripe"),
            "s": median("s")}


def _sheet(previews_by_variant, path: Path) -> None:
    """Rows: variants; columns: exemplars; each cell a preview, 4 px apart on white; the whole
    at a third of the size (the previews are enlarged views)."""
    from osmap_cli.imageio import write_image
    from osmap_cli.texture.pyramid import resize

    cells = [p for row in previews_by_variant for p in row]
    h = max(c.shape[0] for c in cells)
    w = max(c.shape[1] for c in cells)
    gap = 4
    rows, cols = len(previews_by_variant), len(previews_by_variant[0])
    sheet = np.ones((rows * (h + gap) - gap, cols * (w + gap) - gap, 3), np.float32)
    for i, row in enumerate(previews_by_variant):
        for j, cell in enumerate(row):
            rgb = cell[..., :3] if cell.shape[2] >= 3 else np.repeat(cell[..., :1], 3, axis=2)
            y, x = i * (h + gap), j * (w + gap)
            sheet[y:y + cell.shape[0], x:x + cell.shape[1]] = rgb
    write_image(path, resize(sheet, sheet.shape[0] // 3, sheet.shape[1] // 3), 8)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=64, help="exemplar side and volume side")
    ap.add_argument("--only", default="", help="comma-separated variant names")
    ap.add_argument("--sheet", type=Path, default=None, help="write the contact sheet here")
    args = ap.parse_args(argv)
    chosen = [v for v in VARIANTS if not args.only or v[0] in args.only.split(",")]
    lines = ["| variant | axis-energy median (max) | hist | coh_mean raw / matched sharpness | "
             "scale median (max abs log2) | lowest contrast | stripe | s per volume |",
             "|---|---|---|---|---|---|---|---|"]
    sheet_rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, method, changes, label in chosen:
            rows, previews = _point(name, method, changes, args.side, Path(tmp))
            s = _summary(rows)
            lines.append(f"| {name}: {label} | {s['axis']:.2f} ({s['axis_max']:.2f}) | "
                         f"{s['hist']:.2f} | {s['coh']:.2f} / {s['matched']:.2f} | "
                         f"{s['scale']:.2f} ({s['log2_max']:.2f}) | {s['contrast_min']:.2f} | "
                         f"{s['stripe']:.2f} | {s['s']:.1f} |")
            print(lines[-1], file=sys.stderr, flush=True)
            sheet_rows.append(previews)
    if args.sheet is not None:
        _sheet(sheet_rows, args.sheet)
    print(f"{args.side} px -> {args.side}^3, seed 1, worst axis, medians over "
          f"{', '.join(NAMES)}\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
