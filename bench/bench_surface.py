"""Benchmark of `osmap surface`: kernel throughput and time to a finished torus grid.

`run()` returns a Markdown section; `python bench/bench_surface.py` prints it. Every figure is the
median of 5 runs (with min and max) after one warm-up run (which also loads or compiles the Numba
kernels), wall-clock time:
- steps/s of the fast axis-aligned kernel path (separable 1D tables): the roll's orientation
  x=u,y=u,z=v on a 32x32 map;
- steps/s of the general path (an exp per node): the same map with path="general";
- steps/s in the cylindrical frame (periodic phi): the torus orientation rho=v,z=v,phi=u, wrap uv;
- wall time to a finished 32x32 torus with the CLI defaults (sampling 20k points, training, OBJ
  text), without the metrics.

Then the fold rate (`fold_rates`): for each variant of tests/surface_samplers.py (roll of
1 and 1.5 turns, torus, and noisy and non-uniform rolls and tori), SEEDS point clouds of
FOLD_POINTS points drawn by those independent samplers are written to .xyz files and fitted the
way users do, `osmap surface cloud.xyz -o grid.obj --seed S` plus the flags docs/surface.md gives
for point files; the OBJ is then scored against the analytic surface (metrics.evaluate with the
shape's exact parameters). A seed fails when shortcut > 0.005, flipped > 0.01,
angle > 6 deg (roll) / 10 deg (torus), fit > 0.2 or (torus) the windings are wrong.

    python bench/bench_surface.py                  # everything
    python bench/bench_surface.py --folds-only [--seeds 0-49] [--variants roll,torus]
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RUNS = 5
KERNEL_STEPS = 20_000
SEEDS = range(50)
QUICK_SEEDS = range(10)
FOLD_POINTS = 60_000
BARS = {"shortcut_edges": 0.005, "flipped_quads": 0.01, "fit_error": 0.2}
ANGLE_BAR = {"roll": 6.0, "torus": 10.0}
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def _stats(values):
    return statistics.median(values), min(values), max(values)


def _timed(fn, runs=RUNS):
    fn()  # warm-up
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def _kernel_rate(shape, path: str) -> list[float]:
    """steps/s of OSMap.train for KERNEL_STEPS steps on the shape's recommended settings."""
    from osmap_cli.surface.fit import build_map, default_schedule, shape_config

    pts = shape.sample(20_000, np.random.default_rng(0))
    cfg = shape_config(shape, (32, 32), "osmap", 0, path=path)
    som, _, data = build_map(cfg, pts)
    schedule = default_schedule(cfg)

    def once():
        som.init_random(data, seed=0)
        som.train(data, KERNEL_STEPS, schedule=schedule, seed=0)

    return [KERNEL_STEPS / t for t in _timed(once)]


def _torus_wall() -> list[float]:
    from osmap_cli.surface.export import obj_text
    from osmap_cli.surface.fit import fit_best, shape_config
    from osmap_cli.surface.shapes import Torus

    def once():
        shape = Torus()
        pts = shape.sample(20_000, np.random.default_rng(0))
        result = fit_best(pts, shape_config(shape, (32, 32), "osmap", 0))
        obj_text(result.grid_xyz, result.wrap)

    return _timed(once)


def _read_obj_vertices(path) -> np.ndarray:
    with open(path) as f:
        return np.array([[float(v) for v in line.split()[1:4]] for line in f
                         if line.startswith("v ")])


def fit_variant(name: str, seed: int, workdir, n_points: int = FOLD_POINTS,
                extra=(), report: bool = True) -> dict:
    """Sample variant `name` with `seed`, write it to an .xyz file, run `osmap surface` on it
    with the documented flags (and `extra`; with `report`, also --report-json to learn how many
    fits were run), and score the OBJ against the analytic surface."""
    from surface_samplers import VARIANTS, sample_variant

    from osmap_cli.commands.surface import surface_command
    from osmap_cli.surface.metrics import evaluate
    from osmap_cli.surface.shapes import Roll, Torus

    shape_name, kwargs, flags = VARIANTS[name]
    pts = sample_variant(name, n_points, seed)
    src = Path(workdir) / f"{name}_{seed}.xyz"
    np.savetxt(src, pts, fmt="%.6f")
    out, js = Path(workdir) / f"{name}_{seed}.obj", Path(workdir) / f"{name}_{seed}.json"
    args = [str(src), "-o", str(out), "--seed", str(seed), "--quiet", *flags, *extra]
    if report:
        args += ["--report-json", str(js)]
    surface_command.main(args, standalone_mode=False)
    verts = _read_obj_vertices(out)
    shape = Roll(turns=kwargs.get("turns", 1.0)) if shape_name == "roll" else Torus()
    wrap = (True, True) if shape_name == "torus" else (False, False)
    m = evaluate(verts.reshape(32, 32, 3), wrap, shape)
    fails = [k for k, bar in BARS.items() if m[k] > bar]
    if m["angle_error_deg"] > ANGLE_BAR[shape_name]:
        fails.append("angle_error_deg")
    if shape_name == "torus" and not m["windings_ok"]:
        fails.append("windings")
    m["fails"] = fails
    if js.exists():
        import json

        m["report"] = json.loads(js.read_text())
    for p in (src, out, js):
        p.unlink(missing_ok=True)
    return m


def fold_rates(variants=None, seeds=SEEDS, n_points: int = FOLD_POINTS, extra=(),
               log=print) -> list[str]:
    """Markdown rows: per variant, the seeds failing the bars and the worst metrics."""
    from surface_samplers import VARIANTS

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in variants or VARIANTS:
            t = time.perf_counter()
            results = [fit_variant(name, s, tmp, n_points, extra) for s in seeds]
            failed = [s for s, m in zip(seeds, results, strict=True) if m["fails"]]
            worst = {k: max(m[k] for m in results) for k in
                     ("shortcut_edges", "flipped_quads", "angle_error_deg", "fit_error")}
            restarted = sum(1 for m in results if m.get("report", {}).get("fits_run", 1) > 1)
            seeds_text = f"{min(seeds)}-{max(seeds)}"
            row = (f"| {name} | {seeds_text} | {len(failed)}/{len(results)} | "
                   f"{', '.join(map(str, failed)) or '-'} | {worst['shortcut_edges']:.4f} | "
                   f"{worst['flipped_quads']:.4f} | {worst['angle_error_deg']:.2f} | "
                   f"{worst['fit_error']:.3f} | {restarted} | "
                   f"{(time.perf_counter() - t) / len(results):.1f} s |")
            log(row)
            rows.append(row)
    return rows


FOLD_HEADER = ["| variant | seeds | failed | failing seeds | worst shortcut | worst flipped | "
               "worst angle | worst fit | seeds refitted | s/seed |",
               "|---|---|---|---|---|---|---|---|---|---|"]


def run(quick: bool = False) -> str:
    from osmap_cli.surface.fit import STEPS_PER_NODE
    from osmap_cli.surface.shapes import Roll, Torus

    rows = []
    for label, shape, path in (
        ("axis-aligned path (roll, x=u,y=u,z=v)", Roll(), "auto"),
        ("general path (same map, path=\"general\")", Roll(), "general"),
        ("cylindrical frame (torus, rho=v,z=v,phi=u, wrap uv)", Torus(), "auto"),
    ):
        med, lo, hi = _stats(_kernel_rate(shape, path))
        rows.append(f"| {label} | {med:,.0f} steps/s | {lo:,.0f} | {hi:,.0f} |")
    med, lo, hi = _stats(_torus_wall())
    rows.append(f"| finished 32x32 torus ({STEPS_PER_NODE} steps/node, 20k points) "
                f"| {med:.2f} s | {lo:.2f} | {hi:.2f} |")
    seeds = QUICK_SEEDS if quick else SEEDS
    folds = fold_rates(seeds=seeds, log=lambda r: None)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return "\n".join([
        "## osmap surface",
        "",
        f"32x32 map, {KERNEL_STEPS:,} training steps per kernel run; median of {RUNS} runs after "
        f"one warm-up, wall clock. Machine: {platform.machine()}, {os.cpu_count()} CPUs, "
        f"load average {load:.1f} at the end.",
        "",
        "| measurement | median | min | max |",
        "|---|---|---|---|",
        *rows,
        "",
        f"### Fold rate ({FOLD_POINTS:,} points per cloud written to .xyz, `osmap surface "
        "cloud.xyz -o grid.obj --seed S` with the documented flags, seeds "
        f"{min(seeds)}-{max(seeds)})",
        "",
        "Clouds from the independent samplers of tests/surface_samplers.py; scored against the "
        "analytic surface. A seed fails when shortcut > 0.005, flipped > 0.01, angle > 6 deg "
        "(roll) / 10 deg (torus), fit > 0.2 or (torus) wrong windings. Noisy: Gaussian noise of "
        "1 % of the bounding-box diagonal; non-uniform: density varying 4x (a ramp along the "
        "roll's arc, a cosine around the torus's axis). `seeds refitted`: the fold check found "
        "a fold and refitted (report field fits_run > 1). s/seed includes sampling, the .xyz "
        "file, the fit and the generic --report-json metrics.",
        "",
        *FOLD_HEADER,
        *folds,
        "",
    ])


def _seed_range(text: str) -> range:
    a, _, b = text.partition("-")
    return range(int(a), int(b or a) + 1)


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--folds-only", action="store_true")
    ap.add_argument("--seeds", default="0-49")
    ap.add_argument("--variants", default=None)
    ap.add_argument("--extra", default="", help="extra osmap surface flags, space separated")
    a = ap.parse_args()
    if a.folds_only:
        print("\n".join(FOLD_HEADER))
        fold_rates(a.variants.split(",") if a.variants else None, _seed_range(a.seeds),
                   extra=a.extra.split())
    else:
        print(run())
