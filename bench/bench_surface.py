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
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import numpy as np

RUNS = 5
KERNEL_STEPS = 20_000


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


def run() -> str:
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
    ])


if __name__ == "__main__":
    print(run())
