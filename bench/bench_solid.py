"""Solid benchmark: timings of `synthesize_solid` (64^3 and 128^3 from 128 px exemplars, the
structure step's own seconds), the quality table of every method on the solid development
exemplars (bench/solid_structure.py: the independent meters and the profile meter, with contact
sheets docs/solid_methods_64.jpg and _128.jpg), the wood set's rings and spacing, and the
unseen-material reference.

`run(quick=False) -> str` returns the Markdown section "## Solid" (bench/run.py includes it);
`python bench/bench_solid.py --timing` prints only its timing table.
Exemplars come from ../shared/exemplars/small (never copied into the repository); 64 px
exemplars are those downscaled by OpenImageIO. Quality runs texmetrics.py in its own venv.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from solid_meters import (
    NAMES,
    REPO,
    TEXMETRICS_PY,
    load_exemplar,
    texmetrics,
    worst_axis,
)

METHODS = ("structure", "osmap", "kopf", "legacy")
TIMED = ("structure", "osmap", "kopf")


def _synth_2d(exemplar_path: Path, size: str, folder: Path) -> dict:
    """texmetrics of `osmap synth` from the exemplar at `size` (N or WxH), seed 1."""
    out = folder / f"2d_{exemplar_path.stem}.png"
    subprocess.run([sys.executable, "-m", "osmap_cli.cli", "synth", str(exemplar_path), "-o",
                    str(out), "--size", size, "--seed", "1", "-q"], check=True)
    return texmetrics(exemplar_path, out)


def _unseen_material_row(name: str, side: int, folder: Path) -> str:
    """One row of the unseen-material reference: each half of the exemplar in turn is the
    exemplar, the other half is real material of the same photo that it does not contain.
    texmetrics scores that held-out half, and `osmap synth` from the same half (which copies),
    against it; their ratio is what the best conceivable non-copying synthesis would score
    against copying synthesis on this meter."""
    from osmap_cli.imageio import write_image

    image = load_exemplar(name, side)
    half = side // 2
    unseen, copying = [], []
    for cut, (seen, held_out) in {"top": (image[:half], image[half:]),
                                  "bottom": (image[half:], image[:half])}.items():
        seen_path = folder / f"{name}_{side}_{cut}.png"
        held_path = folder / f"{name}_{side}_{cut}_held_out.png"
        write_image(seen_path, seen, 8)
        write_image(held_path, held_out, 8)
        unseen.append(worst_axis(texmetrics(seen_path, held_path))["coh_mean"])
        size = f"{2 * seen.shape[1]}x{2 * seen.shape[0]}"
        copying.append(worst_axis(_synth_2d(seen_path, size, folder))["coh_mean"])
    ratios = [u / c for u, c in zip(unseen, copying)]
    return (f"| {name} | {side} x {half} | {' / '.join(f'{u:.2f}' for u in unseen)} | "
            f"{' / '.join(f'{c:.2f}' for c in copying)} | "
            f"{' / '.join(f'{r:.2f}' for r in ratios)} |")


def _timing_rows(quick: bool) -> list[str]:
    """Wall and CPU seconds per method and size, and the structure step's own seconds."""
    from solid_structure import synthesize

    rows = []
    for name in ("marble_swirl_green", "gravel_green_stones"):
        exemplar = load_exemplar(name, 128)
        for method in TIMED:
            synthesize([exemplar], 16, method)  # compile
            for side, runs in ((64, 1 if quick else 3), (128, 1 if quick else 2)):
                walls, cpus, steps = [], [], []
                for _ in range(runs):
                    cpu = time.process_time()
                    _, wall, step, _ = synthesize([exemplar], side, method)
                    walls.append(wall)
                    cpus.append(time.process_time() - cpu)
                    steps.append(step)
                step = (f"{statistics.median(steps):.1f}" if steps[0] is not None else "-")
                rows.append(f"| {name} | {method} | {side}^3 | {runs} | "
                            f"{statistics.median(walls):.1f} | {min(walls):.1f} | "
                            f"{max(walls):.1f} | {statistics.median(cpus):.1f} | {step} |")
    return rows


def _wood_rows(folder: Path) -> list[str]:
    """The wood set (samples/wood_end, _side, _top) per method: the end face's rings and the
    side face's spacing, as tests/test_solid_structure.py reads them."""
    from osmap_cli.imageio import read_image, write_image
    from osmap_cli.solid import SolidOptions, synthesize_solid
    from osmap_cli.solid.structure import measures
    from osmap_cli.solid.structure.layers import ring_centre
    from osmap_cli.solid.structure.segment import lab

    ims = [read_image(REPO / "samples" / f"wood_{n}.png").pixels for n in ("end", "side", "top")]
    rows = []
    for method in METHODS:
        result = synthesize_solid(ims, SolidOptions(width=64, height=64, depth=64, seed=1,
                                                    method=method))
        vol = result.voxels
        fits = [ring_centre(lab(vol[:, :, x])[..., 0]) for x in (16, 32, 48)]
        periods = []
        for y in (16, 32, 48):
            ac = measures.autocorrelation(lab(vol[:, y])[..., 0])
            periods.append(measures.first_peak(measures.along(ac, 90.0, 32)))
        centres = " / ".join("-" if c is None else f"{c[0]:.0f}, {c[1]:.0f}" for c, _ in fits)
        rows.append(f"| {method} | {centres} | "
                    f"{' / '.join(f'{r:.2f}' for _, r in fits)} | "
                    f"{' / '.join(f'{p:.1f} ({a:.2f})' for p, a in periods)} |")
        if method == METHODS[0]:
            from osmap_cli.solid.preview import render_preview

            write_image(folder / "wood.png", render_preview(vol), 8)
    return rows


def run(quick: bool = False, timing_only: bool = False) -> str:
    """The Markdown section "## Solid" (`timing_only`: just its timing table)."""
    from solid_structure import HEADER, SUMMARY_HEADER, summary
    from solid_structure import run as measure_all

    lines = ["## Solid", ""]
    threads = os.environ.get("NUMBA_NUM_THREADS", str(os.cpu_count()))
    lines += [f"Timing: 128 px exemplars -> N^3, seed 1, default options of each method, "
              f"NUMBA_NUM_THREADS={threads}; seconds (wall: median, min, max; CPU: median, all "
              "threads; structure: the structure step's own seconds, analysis, model fit and "
              "building the volume's structure, of method structure's wall time).", "",
              "| exemplar | method | volume | runs | median wall | min | max | median CPU | "
              "structure |", "|---|---|---|---|---|---|---|---|---|", *_timing_rows(quick), ""]
    if timing_only:
        return "\n".join(lines)
    if not TEXMETRICS_PY.exists():
        return "\n".join(lines + ["(texmetrics venv missing: no quality table)", ""])
    sizes = (64,) if quick else (64, 128)
    rows = []
    for side in sizes:
        rows += measure_all(NAMES, (side,), METHODS, REPO / "docs" / f"solid_methods_{side}.jpg")
    from solid_structure import _row

    lines += ["Quality, seed 1, default options of each method (`osmap solid EX --size N "
              "--method M`), exemplars from ../shared/exemplars/small resized to N px: "
              "granules.py's bright and dark shifts (worst axis); texmetrics.py's worst-axis "
              "scale, hist and coh_mean, and coh_mean at matched sharpness (exemplar and volume "
              "both low-passed by a Gaussian of sigma 1 first, bench/lowpass.py); solidlook.py's "
              "worst axis-energy and stripe ratios and lowest contrast; the profile meter "
              "(osmap_cli.solid.structure.meter: the particle profiles' area fraction, sizes "
              "and shapes on 6 slices per axis and 12 diagonal cuts, read with the exemplar's "
              "own segmentation; the largest relative error; particle exemplars only). Contact "
              "sheets: docs/solid_methods_64.jpg, docs/solid_methods_128.jpg (per volume: the "
              "preview cube and middle slices, an oblique (1, 1, 1) cut, the exemplar).", "",
              HEADER, *(_row(r) for r in rows), "",
              "Over the volumes above, against the bars (granules shifts 0.85-1.18, |log2 "
              "scale| < 0.3, axis-energy median <= 1.15 and none above 1.3, hist median <= "
              "0.8, lowest contrast >= 0.75, profile errors <= 0.10, coherence no worse than "
              "method osmap's):", "", SUMMARY_HEADER, *(summary(rows, m) for m in METHODS), ""]
    with tempfile.TemporaryDirectory() as tmp:
        lines += ["The wood set (`osmap solid --x samples/wood_end.png --y samples/wood_side.png "
                  "--z samples/wood_top.png --size 64 --method M`): the centre the end face's "
                  "stripes curve around (rows z, cols y; fitted on x slices 16 / 32 / 48: "
                  "osmap_cli.solid.structure.layers.ring_centre; the exemplar's own: -26, 66, "
                  "residual 0.05, i.e. above the face) with the fit's residual (over the face "
                  "size; straight or broken stripes score high), and the side faces' ring "
                  "spacing (y slices 16 / 32 / 48: the first autocorrelation peak along z and "
                  "its height; the exemplar's: 7.0 px, 0.92):", "",
                  "| method | end face: ring centre (row, col) | residual | side: spacing px "
                  "(autocorrelation) |", "|---|---|---|---|", *_wood_rows(Path(tmp)), ""]
    reference = ["| exemplar | seen half (px) | unseen half: coh_mean (top / bottom seen) | "
                 "`osmap synth` from the seen half: coh_mean | ratio unseen / synth |",
                 "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        for side in (64,) if quick else (64, 128):
            for name in NAMES:
                reference.append(_unseen_material_row(name, side, Path(tmp)))
    lines += ["Reference, what real unseen material scores on this meter: each half of the "
              "exemplar in turn is the exemplar and the other half of the same photograph is "
              "scored against it, beside `osmap synth` from the seen half (2D output twice its "
              "size, seed 1). The ratio is the coherence ratio a synthesis that invents content "
              "as well as nature does would reach; docs/solid.md explains why a volume cannot "
              "copy on all three axes and so sits near this ratio rather than near 1.", "",
              *reference, ""]
    return "\n".join(lines)


if __name__ == "__main__":
    print(run(quick="--quick" in sys.argv, timing_only="--timing" in sys.argv))
