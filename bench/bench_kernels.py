"""OS-Map kernel throughput, winner-search cost against window size, and a roofline per kernel.

`run_kernels()` and `run_roofline()` return Markdown sections (`bench/run.py --only kernels`,
`--only roofline`). All timings are CPU seconds of this (single-threaded) process unless a
column says wall, median of RUNS runs after a warm-up, so that the other jobs on a shared machine
disturb them less; the roofline's machine limits are measured in the same run.

    python bench/bench_kernels.py [--quick] [--only kernels|roofline]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import common
from common import md_table

RUNS = 5


def _cpu_median(fn, runs=RUNS):
    fn()  # warm-up (loads the compiled kernels)
    times = []
    for _ in range(runs):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return statistics.median(times), min(times), max(times)


def _rotation_3d(a, b, c):
    import numpy as np
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rz = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rx = np.array([[1, 0, 0], [0, cc, -sc], [0, sc, cc]])
    return rz @ ry @ rx


# ----------------------------------------------------------------------------- kernels

def kernel_configs():
    """(label, OSMap kwargs, data, schedule) for the OS-Map paths on 2D and 3D maps."""
    import numpy as np

    from osmap_cli.engine import Orientation, Schedule

    rng = np.random.default_rng(0)
    pos = np.stack(np.meshgrid(np.arange(32.0), np.arange(32.0), indexing="ij"), -1)
    pos = pos.reshape(-1, 2)
    texture = dict(window=(16, 16), target_jacobian=np.eye(2), range_kernel=(2.0, 1.0),
                   bounds=[[0, 31], [0, 31]])
    tex_schedule = Schedule(alpha_max=0.5, alpha_min=0.05, sigma_max=1.5, sigma_min=0.3)
    aniso = [[1.0, 0.25], [1.0, 0.25]]
    data3 = rng.random((20_000, 3))
    w3 = np.array([[1.0, 0.25, 0.5]] * 3)
    frames = np.broadcast_to(_rotation_3d(0.4, 0.7, 0.2), (1, 3, 3, 3)).copy()
    vol_schedule = Schedule(sigma_max=3.0, sigma_min=0.5)
    return [
        ("2D map 64x64, texture setting, axis-aligned (fast path)", (64, 64),
         dict(texture, orientation=Orientation.angles([0.0, np.pi / 2], aniso)), pos,
         tex_schedule),
        ("2D map 64x64, texture setting, rotated 30 deg (general path)", (64, 64),
         dict(texture, orientation=Orientation.angles([np.pi / 6, np.pi / 6 + np.pi / 2],
                                                       aniso)), pos, tex_schedule),
        ("3D map 24^3, 3D data, window 12^3, axis-aligned (fast path)", (24, 24, 24),
         dict(window=(12, 12, 12), orientation=Orientation.axis_aligned(w3)), data3,
         vol_schedule),
        ("3D map 24^3, 3D data, window 12^3, rotated frame (general path)", (24, 24, 24),
         dict(window=(12, 12, 12), orientation=Orientation(frames, w3)), data3, vol_schedule),
        ("2D map 128x128, 2D data, classic SOM, global window, sigma 16 -> 0.5", (128, 128),
         {}, rng.random((10_000, 2)), Schedule(sigma_max=16.0, sigma_min=0.5)),
    ]


def kernel_rates(quick: bool):
    from osmap_cli.engine import OSMap
    from osmap_kernels.som import is_classic
    steps = 5_000 if quick else 20_000
    rows = []
    for label, shape, kwargs, data, schedule in kernel_configs():
        som = OSMap(shape, data.shape[1], **kwargs)
        path = ("classic" if is_classic(som._params)
                else "separable" if som._params.separable else "general")

        def once(som=som, data=data, schedule=schedule):
            som.init_random(data, seed=0)
            som.train(data, steps, schedule=schedule, seed=1)

        med, lo, hi = _cpu_median(once, 3 if quick else RUNS)
        rows.append([label, path, f"{steps / med:,.0f}", f"{steps / hi:,.0f}–{steps / lo:,.0f}",
                     f"{med / steps * 1e6:.2f}"])
    return rows, steps


def search_costs(quick: bool):
    """µs per step of the window scan and of the inverse map on a 128x128 map (2D data), for
    square windows; sigma 0.05 (the update touches one node) isolates the search, sigma 2 with
    alpha 0.1 adds the update and, for the inverse map, the refiling of moved nodes."""
    import numpy as np

    from osmap_cli.engine import OSMap
    from osmap_kernels.som import train_steps

    n, dim = 128, 2
    steps = 5_000 if quick else 20_000
    rng = np.random.default_rng(0)
    data = rng.random((20_000, dim))
    xs = data[rng.integers(0, len(data), steps)]
    rows = []
    fits = {"scan": [], "search": [], "refile": [], "miss": []}
    for w in (4, 8, 16, 32, 64, 128):
        som = OSMap((n, n), dim, window=(w, w)).init_random(data, seed=0)
        p = som._params
        high = np.array(p.grid) - np.array(p.window) + 1
        origins = (rng.random((steps, 3)) * high).astype(np.int64)
        b = som._buckets(data)
        cells = []
        for sigma, alpha in ((0.05, 0.0), (2.0, 0.1)):
            alphas, sigmas = np.full(steps, alpha), np.full(steps, sigma)
            for bucket_from in (steps, 0):
                w0 = som.weights.copy()

                def once(som=som, w0=w0, origins=origins, alphas=alphas, sigmas=sigmas, p=p,
                         b=b, bucket_from=bucket_from):
                    som.weights[:] = w0
                    train_steps(som.weights, xs, origins, alphas, sigmas, p, b, bucket_from)

                med, _, _ = _cpu_median(once, 3)
                cells.append(med / steps * 1e6)
        scan0, inv0, scan2, inv2 = cells
        pays = som._buckets_pay(np.array([0.05, 2.0]))
        rows.append([f"{w}x{w} ({w * w:,} nodes)", f"{scan0:.2f}", f"{inv0:.2f}",
                     f"{scan2:.2f}", f"{inv2:.2f}",
                     " / ".join("inverse map" if x else "scan" for x in pays)])
        fits["scan"].append(scan0 / (w * w))
        fits["miss"].append((w, inv0))
        if w == n:
            fits["search"].append(inv0)
            fits["refile"].append((inv2 - inv0) - (scan2 - scan0))
    return rows, steps, fits


def run_kernels(quick: bool = False, log=print) -> str:
    """The `kernels` section."""
    import numpy as np

    from osmap_cli import engine
    t0 = time.perf_counter()
    load0 = common.load_average()
    log("[kernels] OS-Map paths ...")
    rate_rows, steps = kernel_rates(quick)
    log("[kernels] winner search against window size ...")
    search_rows, search_steps, fits = search_costs(quick)
    off = np.arange(-20, 21)
    updated = int((np.exp(-(off[:, None] ** 2 + off[None, :] ** 2) / 8.0) >= 1e-3).sum())
    refile_ns = fits["refile"][0] / updated * 1e3 if fits["refile"] else float("nan")
    miss_ns = statistics.median((t - fits["search"][0]) / (128 * 128 / w ** 2) * 1e3
                                for w, t in fits["miss"] if w < 128)
    out = [
        "## OS-Map kernels",
        f"_{common.stamp()}; reproduce with `.venv/bin/python bench/run.py --only kernels"
        f"{' --quick' if quick else ''}`; section took {(time.perf_counter() - t0) / 60:.1f} "
        f"min; load average (1 min) at start / end: {load0} / {common.load_average()}._",
        f"Training steps per second of `OSMap.train` (one thread), {steps:,} steps per run, "
        f"median of {3 if quick else RUNS} runs (min–max) in CPU time, after a warm-up. The "
        "texture setting is the one `osmap synth` organises with (coherent targets x + J D, "
        "range kernel (2, 1), bounds, 16x16 window, sigma 1.5 -> 0.3); the fast path uses "
        "1D tables (every A_k diagonal), the general path evaluates exp(-D^T A_k D / 2 "
        "sigma^2) per node and component; the classic path is the fast path for Kohonen's "
        "SOM (target x, no range kernel, bounds or periodic component), each row's nodes "
        "updated in a vectorised loop (the same weights, bit for bit).",
        md_table(["configuration", "kernel path", "steps/s", "range", "µs/step"], rate_rows),
        f"### Winner search against window size\n\nµs per step (CPU, median of 3 runs of "
        f"{search_steps:,} steps) on a 128x128 map with 2D data (uniform), windows placed at "
        "random. *Search only*: sigma 0.05, the update touches one node. *With update*: sigma "
        f"2, alpha 0.1, {updated} nodes updated per step (fewer at the map's edges), and the "
        "inverse map refiles every "
        "node that moved. Both searches return the same winner (tests/test_engine.py), so the "
        "choice is only about speed; the last column is what `OSMap.train` picks "
        "(search only / with update) from its cost model.",
        md_table(["window", "scan", "inverse map", "scan + update", "inverse map + update",
                  "auto picks"], search_rows),
        f"Fitted on this run: scan {fits['scan'][-1] * 1e3:.2f} ns per window node (128x128 "
        f"window); inverse-map search {fits['search'][0]:.2f} µs per step (whole-map window) "
        f"+ {miss_ns:.0f} ns x map size / window size (median over the local windows); "
        f"refiling {refile_ns:.1f} ns per updated node. The engine's cost model uses "
        f"{engine.SCAN_COST * 1e9 * 2:.1f} ns (2 components; "
        f"{engine.BLOCK_SCAN_COST * 1e9 * 2:.1f} ns for windows of whole rows, which the "
        f"kernel scans block-wise), {engine.SEARCH_COST * 1e6:.2f} µs "
        f"+ {engine.MISS_COST * 1e9:.0f} ns x map size / window size, and "
        f"{engine.REFILE_COST * 1e9:.0f} ns (only their ratios matter; refiling is set lower "
        "than fitted here because this table's random map moves nearly every updated node to "
        "another cell, a real run's late steps few: the value is the fastest switch point "
        "for the SOM benchmark's runs). The inverse map pays "
        "once the window holds more than a few hundred nodes and the radius has shrunk; a "
        "local window is penalised by map size / window size (out-of-window nodes are "
        "skipped), so the small windows of `osmap synth` keep the scan.",
    ]
    return "\n\n".join(out) + "\n"


# ----------------------------------------------------------------------------- roofline

def machine_limits(quick: bool):
    """(GB/s of a STREAM-like triad, GFLOP/s of an in-cache multiply-add loop), one thread."""
    import numpy as np
    from numba import njit

    @njit(cache=False)
    def triad(a, b, c, s):
        for i in range(a.shape[0]):
            a[i] = b[i] + s * c[i]

    @njit(cache=False, fastmath=True)
    def fma_loop(x, reps, s, t):
        for _ in range(reps):
            for i in range(x.shape[0]):
                x[i] = x[i] * s + t

    n = 1 << (22 if quick else 24)
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    med, _, _ = _cpu_median(lambda: triad(a, b, c, 0.5), 5)
    bandwidth = 3 * 8 * n / med / 1e9  # two reads and one write (write-allocate not counted)
    x = np.ones(2048)
    reps = 20_000
    med, _, _ = _cpu_median(lambda: fma_loop(x, reps, 0.999999, 1e-7), 5)
    flops = 2 * x.size * reps / med / 1e9
    return bandwidth, flops


def roofline_rows(quick: bool, bandwidth: float, peak: float):
    """Per kernel: measured time per unit of work and the model's bytes and flops for it."""
    import numpy as np

    from osmap_cli.engine import Orientation, OSMap
    from osmap_kernels.som import train_steps

    steps = 5_000 if quick else 20_000
    rng = np.random.default_rng(0)
    d = 3
    data = rng.random((20_000, d))
    xs = data[rng.integers(0, len(data), steps)]
    rows = []

    def per_step(som, sigma, alpha, origins):
        p = som._params
        b = som._buckets(data)
        w0 = som.weights.copy()
        alphas, sigmas = np.full(steps, alpha), np.full(steps, sigma)

        def once():
            som.weights[:] = w0
            train_steps(som.weights, xs, origins, alphas, sigmas, p, b, steps)
        med, _, _ = _cpu_median(once, 3)
        return med / steps

    def line(name, unit, seconds, nbytes, nflops, model):
        gbs = nbytes / seconds / 1e9
        gfl = nflops / seconds / 1e9
        bound = "memory" if nflops / nbytes < peak / bandwidth else "compute"
        limit = nbytes / (bandwidth * 1e9) if bound == "memory" else nflops / (peak * 1e9)
        rows.append([name, model, f"{seconds * 1e9:.1f} ns / {unit}", f"{nbytes:.0f} B",
                     f"{nflops:.0f}", f"{nflops / nbytes:.2f}", f"{gbs:.1f}", f"{gfl:.2f}",
                     f"{seconds / limit:.0f}x ({bound})"])

    # window scan: 64x64 map, global window, update of one node
    scan = OSMap((64, 64), d).init_random(data, 0)
    t = per_step(scan, 0.05, 0.0, np.zeros((steps, 3), np.int64)) / scan.size
    line("winner scan", "node", t, 4 * d, 3 * d,
         f"per window node: read {d} float32; {d} sub + {d} mul + {d} add")

    # update: 128x128 torus, 1x1 window (the winner is the origin), sigma 4, alpha 0.1
    origins = np.zeros((steps, 3), np.int64)
    origins[:, 1:] = rng.integers(0, 128, (steps, 2))
    sigma = 4.0
    off = np.arange(-40, 41)
    q = off[:, None] ** 2 + off[None, :] ** 2
    n_iso = int((np.exp(-q / (2 * sigma ** 2)) >= 1e-3).sum())
    iso = OSMap((128, 128), d, wrap=(True, True), window=(1, 1)).init_random(data, 0)
    t = per_step(iso, sigma, 0.1, origins) / n_iso
    line("update, fast path (separable)", "node", t, 8 * d, 6 * d,
         f"per updated node ({n_iso} at sigma 4): read + write {d} float32; per component "
         "1 mul (weight) + 2 (target) + 3 (m += a h (t - m))")
    theta = [0.5, 0.5 + np.pi / 2, 1.0]
    weights = [[1.0, 0.25]] * d
    gen = OSMap((128, 128), d, wrap=(True, True), window=(1, 1),
                orientation=Orientation.angles(theta, weights)).init_random(data, 0)
    quad = gen._params.quad[0][:, 1:, 1:]
    grid = np.stack(np.meshgrid(off, off, indexing="ij"), -1).astype(np.float64)
    qk = np.einsum("...a,kab,...b->k...", grid, quad, grid)
    n_gen = int((np.exp(-qk / (2 * sigma ** 2)).max(axis=0) >= 1e-3).sum())
    t = per_step(gen, sigma, 0.1, origins) / n_gen
    line("update, general path (exp per node)", "node", t, 8 * d, 30 * d,
         f"per updated node ({n_gen} at sigma 4): as above + per component "
         "4 flops (exponent) + exp (counted as 20 flops)")

    refine = refine_line(quick)
    if refine is not None:
        name, unit, seconds, nbytes, nflops, model = refine
        line(name, unit, seconds, nbytes, nflops, model)
    return rows


def refine_line(quick: bool):
    """One refinement sweep of `osmap synth` at 256x256 (brick sample), per output pixel."""
    try:
        import numpy as np

        from osmap_cli.imageio import read_image
        from osmap_cli.synth import SynthOptions
        from osmap_cli.synth.pipeline import valid_box
        from osmap_cli.synth.refine import refine
        from osmap_cli.texture.features import appearance_features

        opts = SynthOptions(width=256, height=256, seed=1).validated()
        image = read_image(str(common.SAMPLES_DIR / "brick.png")).pixels
        feat = appearance_features([image], opts.feature_dims)[0]
        jac = opts.jacobian()
        lo, hi = valid_box(image.shape[:2], jac, opts.patch_radius)
        rng = np.random.default_rng(0)
        pos = np.stack([rng.integers(int(lo[0]), int(hi[0]) + 1, (256, 256)),
                        rng.integers(int(lo[1]), int(hi[1]) + 1, (256, 256))], -1)
        pos = pos.astype(np.float32)
        jac_field = np.broadcast_to(jac.astype(np.float32), (256, 256, 2, 2)).copy()

        # a field part-way through: two sweeps from random positions (untimed), then time one
        pos = refine(pos, feat, jac_field, lo, hi, 2, opts, wrap=False, seed=1, salt=0)

        def once():
            refine(pos, feat, jac_field, lo, hi, 1, opts, wrap=False, seed=1, salt=3)
        med, _, _ = _cpu_median(once, 3)
    except Exception as exc:  # noqa: BLE001 - the engine's API may change under us
        print(f"[roofline] refine not measured: {exc!r}", file=sys.stderr)
        return None
    nf = feat.shape[2]
    side = (2 * opts.patch_radius + 1) ** 2
    cands = 1 + 8 * (1 + opts.knn) + opts.random_candidates + 1
    nbytes = cands * side * nf * 4
    nflops = cands * side * nf * 3
    return ("refinement sweep (coherence, 2 threads; 256x256, after 2 sweeps)", "pixel",
            med / (256 * 256), nbytes,
            nflops, f"per pixel and sweep, upper bound (no early exit): {cands} candidates x "
            f"{side} window pixels x {nf} features, 4 B read and 3 flops each (feature reads "
            "hit the cache: the exemplar's features are ~1 MB)")


def run_roofline(quick: bool = False, log=print) -> str:
    """The `roofline` section."""
    t0 = time.perf_counter()
    load0 = common.load_average()
    log("[roofline] machine limits (triad, multiply-add loop) ...")
    bandwidth, peak = machine_limits(quick)
    log(f"[roofline] {bandwidth:.1f} GB/s, {peak:.1f} GFLOP/s; kernels ...")
    rows = roofline_rows(quick, bandwidth, peak)
    out = [
        "## Roofline",
        f"_{common.stamp()}; reproduce with `.venv/bin/python bench/run.py --only roofline"
        f"{' --quick' if quick else ''}`; section took {(time.perf_counter() - t0) / 60:.1f} "
        f"min; load average (1 min) at start / end: {load0} / {common.load_average()}._",
        f"Machine limits measured in this run, one thread: memory bandwidth "
        f"**{bandwidth:.1f} GB/s** (STREAM-like triad a = b + s c over three 128 MiB float64 "
        f"arrays, 24 bytes per element counted) and **{peak:.1f} GFLOP/s** (x = x s + t over "
        "a 16 KiB array in L1, Numba fastmath, vectorised; a practical peak, not the vendor "
        "figure). Bytes and flops per unit of work are counted from the code (model column); "
        "`x from limit` = measured time / the time the roofline allows (bytes / bandwidth or "
        "flops / peak, whichever is larger). CPU time, median of 3 runs. The refinement sweep "
        "runs on 2 threads, so its CPU time is the sum over both.",
        md_table(["kernel", "model (counted from the code)", "measured", "bytes", "flops",
                  "flop/B", "GB/s", "GFLOP/s", "x from limit"], rows),
        "Reading: every OS-Map kernel works on data that sits in L1/L2 (a 64x64x3 float32 map "
        "is 48 KiB), so DRAM bandwidth is not the limit; they run at a few percent of the "
        "in-cache flop rate because each node is a short dependent chain (d = 2 or 3 "
        "components, a compare and a branch per node, float32 <-> float64 conversions), not "
        "a long vectorisable stream. The inverse map's search is not in the table: it visits "
        "a handful of cells and nodes through linked lists, so it is latency-bound (about "
        "0.5–1 µs per search, see the kernels section), neither bandwidth- nor flop-bound.",
    ]
    return "\n\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", choices=("kernels", "roofline"))
    args = ap.parse_args(argv)

    def log(m):
        print(m, file=sys.stderr, flush=True)
    if args.only != "roofline":
        print(run_kernels(args.quick, log))
    if args.only != "kernels":
        print(run_roofline(args.quick, log))
    return 0


if __name__ == "__main__":
    sys.exit(main())
