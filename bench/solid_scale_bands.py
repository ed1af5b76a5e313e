"""Where a particle volume's spectrum departs from its exemplar's, stage by stage: method
structure's steps run one by one (the built structure in flat colours, the fill, the per-phase
matching, the particles' mean colours, their colour distributions, their decorrelation from the
packing's crowding, the residual detail, the final histogram), and after each the
luminance (CIELAB L*) power of the volume's slices (8 per axis, Welch windows as texmetrics'
scale) is compared with the exemplar's band by band (octaves of period). Also the colour
variance split of the particles: between their mean colours, within them, and the matrix's.

    python bench/solid_scale_bands.py [--side 128] [--name gravel_green_stones] [--seed 1]
        [--fill KEY=VALUE]

Per stage: `scale` (texmetrics' feature-scale ratio, worst axis: its spectral centroid's
distance from the exemplar's, > 1 coarser), then the slices' absolute power per octave over the
exemplar's (`p2-4` = periods of 2-4 px, ...), then the variance split over the exemplar's. A
stage whose coarse bands (16-64 px) jump above 1 adds the excess; one whose fine bands fall
short of 1 leaves the volume coarser by what it lacks.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from solid_meters import load_exemplar

BANDS = ((16, 32), (8, 16), (4, 8), (2, 4), (1, 2))  # frequency bins r (cycles per window)


def lightness(rgb: np.ndarray) -> np.ndarray:
    """CIELAB L* of an (H, W, C) image (the segmentation's conversion)."""
    from osmap_cli.solid.structure.segment import lab

    return lab(rgb)[..., 0]


def window_power(images, n: int) -> np.ndarray:
    """Welch-averaged radial power (absolute, per frequency bin 1..n/2) of L* images."""
    win = np.outer(np.hanning(n), np.hanning(n))
    fy, fx = np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n), indexing="ij")
    r = np.rint(np.hypot(fy, fx) * n).astype(int)
    acc, count = np.zeros(r.max() + 1), 0
    for lum in images:
        for y in range(0, lum.shape[0] - n + 1, n // 2):
            for x in range(0, lum.shape[1] - n + 1, n // 2):
                c = lum[y:y + n, x:x + n]
                acc += np.bincount(r.ravel(), (np.abs(np.fft.fft2((c - c.mean()) * win)) ** 2)
                                   .ravel(), len(acc))
                count += 1
    return acc[1:n // 2 + 1] / np.bincount(r.ravel())[1:n // 2 + 1] / max(count, 1)


def centroid(power: np.ndarray) -> float:
    """texmetrics' spectral centroid (log2 frequency, weighted by power per log band)."""
    s = power / power.sum()
    w = np.arange(1, len(s) + 1)
    return float((s * w * np.log2(w)).sum() / (s * w).sum())


def slices(voxels: np.ndarray, axis: int) -> list:
    n = voxels.shape[axis]
    pick = np.unique(np.linspace(0, n - 1, min(8, -(-n // 8))).astype(int))
    return [lightness(np.take(voxels, i, axis)) for i in pick]


def split(lum_sets, region_sets) -> tuple[float, float, float, float, float]:
    """(between, within, matrix, fraction, step): the variance of L* between the regions' means
    (weighted by area), within them, over the matrix (region -1), the regions' area fraction
    and their mean L* less the matrix's, pooled over images."""
    lum = np.concatenate([a.ravel() for a in lum_sets])
    reg = np.concatenate([r.ravel() for r in region_sets])
    inside = reg >= 0
    ids, inv = np.unique(reg[inside], return_inverse=True)
    area = np.bincount(inv).astype(np.float64)
    means = np.bincount(inv, lum[inside]) / area
    within = float(((lum[inside] - means[inv]) ** 2).mean())
    between = float(((means[inv] - lum[inside].mean()) ** 2).mean())
    matrix = lum[~inside] if (~inside).any() else np.zeros(1)
    return (between, within, float(matrix.var()), float(inside.mean()),
            float(lum[inside].mean() - matrix.mean()))


def stages(name: str, side: int, seed: int, fill_changes: dict):
    """[(stage, voxels)], the exemplar and its profile ids, the volume's regions."""
    from osmap_cli.solid import SolidOptions
    from osmap_cli.solid.core import SolidTask
    from osmap_cli.solid.method_structure import Options, _fill_labels, final_colours
    from osmap_cli.solid.pipeline import build_pyramid, plan_levels
    from osmap_cli.solid.structure import fill as fl
    from osmap_cli.solid.structure import method as sm
    from osmap_cli.solid.structure.analysis import enlarge
    from osmap_cli.solid.structure.profiles import profile_ids

    exemplar = load_exemplar(name, side)
    opts = SolidOptions(width=side, height=side, depth=side, seed=seed, method="structure")
    opts = opts.validated()
    images = [np.ascontiguousarray(exemplar, np.float32)]
    shapes = plan_levels([exemplar.shape[:2]], opts.shape, opts.levels)
    task = SolidTask(images=images, ex_of_axis=np.zeros(3, np.int64),
                     pyramids=[build_pyramid(images[0], len(shapes))], shapes=shapes,
                     tileable=opts.tileable, seed=opts.seed)
    options = Options.from_solid(opts)
    params = replace(options.fill, **fill_changes)
    found = sm.plan(task.images, task.ex_of_axis, options.structure, options.phases, task.seed,
                    task.tileable, probe_cap=max(task.shapes[0]))
    if found.kind != "particles":
        raise SystemExit(f"{name}: no particles ({found.kind})")
    built = sm.build_structure(found, task.shapes[0], task.seed, task.tileable)
    found = replace(found, ex_labels=_fill_labels(found, task.tileable))
    out = [("built", built.identity)]
    voxels, source = fl.fill(task, found.ex_labels, found.ex_identity, built.labels,
                             built.identity, params)
    out.append(("fill", voxels))
    wrap = task.tileable
    finished = sm.finish(voxels, found, built, params.phase_match, wrap,
                         record=lambda stage, values: out.append((stage, values)))
    out.append(("decorrelated", finished))
    detailed = sm.add_detail(finished, source, found, built, task.exemplars(0),
                             task.ex_of_axis, params.detail, task.seed, wrap)
    out.append(("detail", detailed))
    final = final_colours(detailed, found.images, options.final_histogram)
    out.append(("final", final))
    reader = found.analyses[0].reader
    big = enlarge(exemplar, reader.factor)  # the profiles as the sources read them
    ids, _ = profile_ids(reader.working_mask(big, wrap).astype(np.int64), (1,), wrap)
    return out, big, ids, built.regions


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=128)
    ap.add_argument("--name", default="gravel_green_stones")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fill", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    changes = {}
    for item in args.fill:
        key, value = item.split("=", 1)
        changes[key] = float(value)
    out, big, ids, regions = stages(args.name, args.side, args.seed, changes)
    n = int(np.clip(2 ** np.floor(np.log2(args.side / 2)), 16, 128))
    ex_power = window_power([lightness(load_exemplar(args.name, args.side))], n)
    ex_split = split([lightness(big)], [ids])
    head = ["stage", "scale"] + [f"p{n // hi}-{n // lo}" for lo, hi in BANDS] + [
        "between", "within", "matrix", "fraction", "step"]
    print(f"{args.name} {args.side} px -> {args.side}^3, seed {args.seed}; exemplar L* "
          f"variance between / within / matrix {ex_split[0]:.1f} / {ex_split[1]:.1f} / "
          f"{ex_split[2]:.1f}, particles' fraction {ex_split[3]:.2f}, their L* over the "
          f"matrix's {ex_split[4]:+.1f}")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for stage, voxels in out:
        scales, powers = [], []
        for axis in range(3):
            lum = slices(voxels, axis)
            p = window_power(lum, n)
            powers.append(p)
            scales.append(2 ** (centroid(ex_power) - centroid(p)))
        scale = max(scales, key=lambda v: abs(np.log(v)))
        power = np.mean(powers, 0)
        bands = [power[lo - 1:hi].sum() / ex_power[lo - 1:hi].sum() for lo, hi in BANDS]
        lum_sets, reg_sets = [], []
        for axis in range(3):
            lum_sets += slices(voxels, axis)
            size = regions.shape[axis]
            pick = np.unique(np.linspace(0, size - 1, min(8, -(-size // 8))).astype(int))
            reg_sets += [np.take(regions, i, axis) for i in pick]
        b, w, m, frac, step = split(lum_sets, reg_sets)
        cells = [stage, f"{scale:.2f}"] + [f"{v:.2f}" for v in bands] + [
            f"{b / ex_split[0]:.2f}", f"{w / ex_split[1]:.2f}", f"{m / max(ex_split[2], 1e-9):.2f}",
            f"{frac:.2f}", f"{step:+.1f}"]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
