"""How particle volumes of method structure read over seeds, statistic by statistic, and how
much the profile meter's reading of one volume moves between cut sets (its repeatability).

    python bench/solid_particles_seeds.py [--side 64] [--names terrazzo_granite]
        [--seeds 1,2,3,4,5] [--cut-sets 4] [--keep DIR]
    python bench/solid_particles_seeds.py --spheres 3 [--side 64]

For every volume: the profile meter's relative error of every figure (fraction, d50, d90,
area-weighted diameter, solidity, elongation) on the axis slices and the diagonal planes, for
the built structure alone (each particle in its source profile's flat colour on the matrix's
mean colour) and the finished volume; then the finished volume read again with --cut-sets other
sets of cuts of the meter's own kind (axis slices at other positions, the diagonal planes at
other offsets): the spread of the worst error over them is the meter's own noise on that volume.
Names as bench/solid_structure.py (development exemplars, `samples/NAME`). --spheres N: the
meter's cut families on N volumes of random non-overlapping spheres (isotropic by construction),
the diagonal planes' figures against 30 axis slices per family of the same volume: what the
meter's nearest-sampled diagonal planes read differently whatever the material.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from solid_meters import load_exemplar

FIGURES = ("fraction", "d50", "d90", "diameter", "solidity", "elongation")


def meter_on(exemplar, volume, shift: float = 0.0):
    """The profile meter's errors (by family and figure) and worst, with the axis slices moved
    `shift` of their spacing and the diagonal planes' offsets spread evenly over the meter's
    range, moved `shift` of their spacing; not the meter's own cuts at any shift)."""
    from osmap_cli.solid.structure import meter as mt
    from osmap_cli.solid.structure.analysis import analyse
    from osmap_cli.solid.structure.particles import pooled
    from osmap_cli.solid.structure.profiles import relative_errors
    from osmap_cli.solid.structure.slices import oblique_slice

    found = analyse(exemplar, False)
    reader = found.reader
    want = reader.profiles(exemplar, False)
    side = volume.shape[0]
    step = side / (mt.SLICES + 1)
    index = np.clip(np.rint(step * (1 + np.arange(mt.SLICES)) + shift * step).astype(int),
                    0, side - 1)
    axes = pooled([reader.profiles(np.ascontiguousarray(np.take(volume, i, axis=d)), False)
                   for d in (2, 1, 0) for i in index])
    offsets = [-0.3 + 0.6 * (k + 0.5 + shift) / len(mt.OFFSETS) for k in range(len(mt.OFFSETS))]
    diagonal = pooled([reader.profiles(oblique_slice(volume, n, nearest=True, offset=o), False)
                       for n in mt.NORMALS for o in offsets])
    errors = {"axes": relative_errors(axes, want), "diagonal": relative_errors(diagonal, want)}
    return errors, max(v for e in errors.values() for v in e.values())


def sphere_bias(side: int, trials: int) -> None:
    """Print the diagonal planes' figures over the axis slices' on random sphere volumes."""
    from osmap_cli.solid.structure.meter import diagonal_cuts
    from osmap_cli.solid.structure.particles import pooled
    from osmap_cli.solid.structure.profiles import profile_stats
    from osmap_cli.solid.structure.slices import axis_slices

    rng = np.random.default_rng(0)
    zz, yy, xx = np.mgrid[0:side, 0:side, 0:side]
    for trial in range(trials):
        spheres = []
        for _ in range(4000):
            r, c = rng.uniform(2, 6), rng.uniform(0, side, 3)
            if all(np.linalg.norm(c - c2) >= r + r2 + 1.5 for c2, r2 in spheres):
                spheres.append((c, r))
            if len(spheres) > 120:
                break
        volume = np.zeros((side,) * 3, bool)
        for c, r in spheres:
            volume |= (zz - c[0] + 0.5) ** 2 + (yy - c[1] + 0.5) ** 2 + (xx - c[2] + 0.5) ** 2 \
                <= r * r

        def read(cuts):
            return pooled([profile_stats(np.ascontiguousarray(c).astype(np.int64), (1,))
                           for c in cuts]).figures()

        axes = read(s for _, _, s in axis_slices(volume, 30))
        diagonal = read(diagonal_cuts(volume))
        print(f"| spheres {side}^3 #{trial + 1} ({len(spheres)}), diagonal / axes - 1 | "
              + " | ".join(f"{diagonal[k] / axes[k] - 1:+.2f}" for k in FIGURES) + " | |",
              flush=True)


def _line(label, errors, worst):
    cells = [f"{errors['axes'][k]:+.2f}/{errors['diagonal'][k]:+.2f}" for k in FIGURES]
    return f"| {label} | " + " | ".join(cells) + f" | {worst:.2f} |"


def main() -> None:
    from osmap_cli.solid import SolidOptions, synthesize_solid
    from osmap_cli.solid.structure.meter import profile_meter
    from osmap_cli.solid.structure.method import build_structure, plan

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=64)
    ap.add_argument("--names", default="terrazzo_granite")
    ap.add_argument("--seeds", default="1,2,3,4,5")
    ap.add_argument("--cut-sets", type=int, default=4)
    ap.add_argument("--keep", type=Path, default=None, help="save the volumes here")
    ap.add_argument("--spheres", type=int, default=0,
                    help="only the meter's cut families on this many random sphere volumes")
    args = ap.parse_args()
    print("| volume | " + " | ".join(f"{k} axes/diag" for k in FIGURES) + " | worst |")
    print("|---" * (len(FIGURES) + 2) + "|")
    if args.spheres:
        sphere_bias(args.side, args.spheres)
        return
    for name in args.names.split(","):
        exemplar = load_exemplar(name, args.side)
        for seed in (int(s) for s in args.seeds.split(",")):
            started = time.perf_counter()
            found = plan([exemplar], [0, 0, 0], seed=seed, probe_cap=args.side)
            built = build_structure(found, (args.side,) * 3, seed, False)
            structure = time.perf_counter() - started
            final = synthesize_solid([exemplar], SolidOptions(
                width=args.side, height=args.side, depth=args.side, seed=seed,
                method="structure")).voxels
            label = f"{Path(name).name} {args.side}^3 s{seed}"
            for stage, vol in (("built", built.identity), ("final", final)):
                prof = profile_meter(exemplar, vol)
                signed = {fam: {k: prof[fam][k] / prof["exemplar"][k] - 1 for k in FIGURES}
                          for fam in ("axes", "diagonal")}
                print(_line(f"{label} {stage}", signed, prof["worst"]), flush=True)
            worsts = [meter_on(exemplar, final, shift)[1]
                      for shift in np.linspace(-0.5, 0.5, args.cut_sets)]
            print(f"| {label} final, {args.cut_sets} other cut sets: worst "
                  + ", ".join(f"{w:.2f}" for w in worsts)
                  + f" (structure step {structure:.1f} s) |", flush=True)
            if args.keep:
                args.keep.mkdir(parents=True, exist_ok=True)
                np.save(args.keep / f"{Path(name).name}_{args.side}_s{seed}.npy", final)
                np.save(args.keep / f"{Path(name).name}_{args.side}_s{seed}_owner.npy",
                        built.regions)


if __name__ == "__main__":
    main()
