"""Solid benchmark: timings of `synthesize_solid` (64^3 and 128^3 from a 128 px exemplar) and
the quality table from texmetrics.py and solidlook.py on the solid development exemplars, for
the default method (osmap), `--method kopf` and the previous default (`--method legacy`, the
same as `--preset legacy`) side by side.

`run(quick=False) -> str` returns the Markdown section "## Solid" (bench/run.py includes it);
`python bench/bench_solid.py --timing` prints only its timing table (about two minutes).
Exemplars come from ../shared/exemplars/small (never copied into the repository); 64 px
exemplars are those downscaled by OpenImageIO. Quality runs texmetrics.py in its own venv.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
# ../shared beside the checkout (a worktree one level deeper finds it too)
SHARED = next((p / "shared" for p in REPO.parents if (p / "shared" / "exemplars").is_dir()),
              REPO.parent / "shared")
EXEMPLARS = SHARED / "exemplars" / "small"
TEXMETRICS = SHARED / "tools" / "texmetrics.py"
SOLIDLOOK = SHARED / "tools" / "solidlook.py"
METHODS = ("osmap", "kopf", "legacy")
# quality-table rows: the methods, and the default's settings before session 8 (preset muted)
VARIANTS = (("osmap", "osmap", ()), ("muted", "osmap", (("position_weight", 3.0),
                                                       ("final_histogram", 0.5))),
            ("kopf", "kopf", ()), ("legacy", "legacy", ()))
TEXMETRICS_PY = Path(os.environ.get("TEXMETRICS_PYTHON", "/tmp/texmetrics-venv/bin/python"))
NAMES = ("terrazzo_granite", "marble_swirl_green", "wood_planks_horizontal",
         "gravel_green_stones")


def _exemplar(name: str, side: int) -> np.ndarray:
    from osmap_cli.imageio import read_image
    from osmap_cli.texture.pyramid import resize

    image = read_image(EXEMPLARS / f"{name}.png").pixels
    return image if image.shape[0] == side else resize(image, side, side)


def _time(exemplar, side: int, runs: int, seed: int = 1, method: str = "osmap", changes=()):
    from osmap_cli.solid import SolidOptions, synthesize_solid

    options = SolidOptions(width=side, height=side, depth=side, seed=seed,
                           method=method).replace(**dict(changes))
    walls, cpus = [], []
    for _ in range(runs):
        wall, cpu = time.perf_counter(), time.process_time()
        result = synthesize_solid([exemplar], options)
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return walls, cpus, result


def _luminance(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image, np.float64)
    if image.shape[-1] >= 3:
        return image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    return image[..., 0]


def axis_peak(image: np.ndarray) -> float:
    """Squared-gradient energy (luminance, central differences, as solidlook.py) within 7.5
    degrees of the grid axes over the energy in the flanks 7.5 to 22.5 degrees from them, times 2
    (their angular widths): 1 for any texture without a peak at the axes, whatever its own
    orientation; block edges and pixel staircases, which lie exactly on the axes, raise it.
    solidlook's axis-energy ratio also rises when a volume lacks the exemplar's orientation (an
    isotropic volume of a diagonally veined marble scores 1.35): this one does not."""
    lum = _luminance(image)
    gy = (lum[2:, 1:-1] - lum[:-2, 1:-1]) / 2
    gx = (lum[1:-1, 2:] - lum[1:-1, :-2]) / 2
    energy = gx ** 2 + gy ** 2
    angle = np.degrees(np.arctan2(gy, gx)) % 90.0
    off = np.minimum(angle, 90.0 - angle)
    flanks = energy[(off >= 7.5) & (off < 22.5)].sum()
    return float(2.0 * energy[off < 7.5].sum() / flanks) if flanks > 0 else 0.0


def volume_axis_peak(voxels: np.ndarray) -> float:
    """The worst slice family's mean axis_peak over 8 slices (the slices solidlook.py reads)."""
    n = voxels.shape[0]
    idx = np.linspace(2, n - 3, 8).astype(int)
    families = (lambda i: voxels[i], lambda i: voxels[:, i], lambda i: voxels[:, :, i])
    return max(float(np.mean([axis_peak(take(i)) for i in idx])) for take in families)


def _metrics(exemplar_path: Path, volume_path: Path) -> dict:
    out = subprocess.run([str(TEXMETRICS_PY), str(TEXMETRICS), str(exemplar_path),
                          str(volume_path), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _matched_coherence(exemplar_path: Path, volume_path: Path, sigma: float = 1.0) -> float:
    """Worst-axis coh_mean with exemplar and volume low-passed alike (bench/lowpass.py): blur
    no longer scores better, so sharp and soft methods compare on structure."""
    ex_lp = volume_path.with_name(volume_path.stem + "_lp_ex.png")
    vol_lp = volume_path.with_name(volume_path.stem + "_lp.npy")
    subprocess.run([str(TEXMETRICS_PY), str(REPO / "bench" / "lowpass.py"), str(exemplar_path),
                    str(volume_path), str(sigma), str(ex_lp), str(vol_lp)], check=True)
    return _worst(_metrics(ex_lp, vol_lp))["coh_mean"]


def _look(exemplar_path: Path, volume_path: Path) -> dict:
    out = subprocess.run([str(TEXMETRICS_PY), str(SOLIDLOOK), str(exemplar_path),
                          str(volume_path), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _synth_2d(exemplar_path: Path, size: str, folder: Path) -> dict:
    """texmetrics of `osmap synth` from the exemplar at `size` (N or WxH), seed 1."""
    out = folder / f"2d_{exemplar_path.stem}.png"
    subprocess.run([sys.executable, "-m", "osmap_cli.cli", "synth", str(exemplar_path), "-o",
                    str(out), "--size", size, "--seed", "1", "-q"], check=True)
    return _metrics(exemplar_path, out)


def _worst(report: dict) -> dict:
    return report.get("worst") or report["2d"]


def _unseen_material_row(name: str, side: int, folder: Path) -> str:
    """One row of the unseen-material reference: each half of the exemplar in turn is the
    exemplar, the other half is real material of the same photo that it does not contain.
    texmetrics scores that held-out half, and `osmap synth` from the same half (which copies),
    against it; their ratio is what the best conceivable non-copying synthesis would score
    against copying synthesis on this meter."""
    from osmap_cli.imageio import write_image

    image = _exemplar(name, side)
    half = side // 2
    unseen, copying = [], []
    for cut, (seen, held_out) in {"top": (image[:half], image[half:]),
                                  "bottom": (image[half:], image[:half])}.items():
        seen_path = folder / f"{name}_{side}_{cut}.png"
        held_path = folder / f"{name}_{side}_{cut}_held_out.png"
        write_image(seen_path, seen, 8)
        write_image(held_path, held_out, 8)
        unseen.append(_worst(_metrics(seen_path, held_path))["coh_mean"])
        size = f"{2 * seen.shape[1]}x{2 * seen.shape[0]}"
        copying.append(_worst(_synth_2d(seen_path, size, folder))["coh_mean"])
    ratios = [u / c for u, c in zip(unseen, copying)]
    return (f"| {name} | {side} x {half} | {' / '.join(f'{u:.2f}' for u in unseen)} | "
            f"{' / '.join(f'{c:.2f}' for c in copying)} | "
            f"{' / '.join(f'{r:.2f}' for r in ratios)} |")


def run(quick: bool = False, timing_only: bool = False) -> str:
    """The Markdown section "## Solid" (`timing_only`: just its timing table, a few minutes)."""
    from osmap_cli.imageio import write_image
    from osmap_cli.solid.preview import render_preview

    lines = ["## Solid", ""]
    threads = os.environ.get("NUMBA_NUM_THREADS", str(os.cpu_count()))
    ex128 = _exemplar("marble_swirl_green", 128)
    for method in METHODS:
        _time(ex128, 16, 1, method=method)  # compile
    rows = []
    for method in ("osmap", "kopf"):
        for side, runs in ((64, 1 if quick else 3), (128, 1 if quick else 2)):
            walls, cpus, _ = _time(ex128, side, runs, method=method)
            rows.append(f"| {method} | {side}^3 | {runs} | {statistics.median(walls):.1f} | "
                        f"{min(walls):.1f} | {max(walls):.1f} | {statistics.median(cpus):.1f} |")
    lines += [f"Timing: marble_swirl_green (128 px) -> N^3, seed 1, default options, "
              f"NUMBA_NUM_THREADS={threads}; seconds.", "",
              "| method | volume | runs | median wall | min | max | median CPU |",
              "|---|---|---|---|---|---|---|", *rows, ""]

    if timing_only:
        return "\n".join(lines)
    if not TEXMETRICS_PY.exists():
        return "\n".join(lines + ["(texmetrics venv missing: no quality table)", ""])
    table = ["| exemplar | px -> volume | method | worst coh_mean | coh_mean, matched sharpness | "
             "worst coh_p95 | worst hist | worst scale | axis-energy | axis peak | contrast | "
             "stripe | s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    sizes = ((64, 64),) if quick else ((64, 64), (128, 128))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in NAMES:
            for ex_side, side in sizes:
                exemplar = _exemplar(name, ex_side)
                ex_path = folder / f"{name}_{ex_side}.png"
                write_image(ex_path, exemplar, 8)
                for method, engine, changes in VARIANTS:
                    walls, _, result = _time(exemplar, side, 1, method=engine, changes=changes)
                    vol_path = folder / f"{name}_{side}_{method}.npy"
                    np.save(vol_path, result.voxels)
                    worst = _worst(_metrics(ex_path, vol_path))
                    look = _look(ex_path, vol_path)
                    table.append(
                        f"| {name} | {ex_side} -> {side}^3 | {method} | {worst['coh_mean']:.2f} | "
                        f"{_matched_coherence(ex_path, vol_path):.2f} | "
                        f"{worst['coh_p95']:.2f} | {worst['hist']:.2f} | {worst['scale']:.2f} | "
                        f"{look['worst_axis_ratio']:.2f} | "
                        f"{volume_axis_peak(result.voxels):.2f} ({axis_peak(exemplar):.2f}) | "
                        f"{look['lowest_contrast_ratio']:.2f} | "
                        f"{look['worst_stripe_ratio']:.2f} | {walls[0]:.1f} |")
                    if method == "osmap":
                        write_image(REPO / "docs" / f"solid_{name}_{side}.png",
                                    render_preview(result.voxels), 8)
    lines += ["Quality (texmetrics.py: worst of the three slice axes; solidlook.py: worst "
              "axis-energy and stripe ratios, lowest contrast ratio; axis peak: `axis_peak` in "
              "bench/bench_solid.py, worst slice family, the exemplar's in brackets, 1 = no "
              "peak at the grid axes; coh_mean at matched sharpness: exemplar and volume both "
              "low-passed by a Gaussian of sigma 1 first, bench/lowpass.py, so that blur does "
              "not score better), seed 1; methods: osmap "
              "(default), muted (the default's settings before session 8, `--preset muted`), "
              "kopf (`--method kopf`), legacy (the default before issue 13, `--method legacy` or "
              "`--preset legacy`):", "", *table, ""]

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
