"""End to end at 1024x1024 and peak memory of `osmap synth` (and `osmap solid`) against size.

Every run is a fresh `osmap` process started by a small wrapper process, which reports the wall
time and `resource.getrusage(RUSAGE_CHILDREN).ru_maxrss` (the peak resident set of its only
child) once the child has exited. The Numba cache is warmed first by one untimed run per command.

    python bench/bench_memory.py [--quick]
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time

import common
from common import SAMPLES_DIR, Stats, md_table

COMMAND = ".venv/bin/python bench/run.py --only memory"
SAMPLE = "cells"
SIZES = (256, 512, 1024)
SOLID_SIZES = (64, 128)

WRAPPER = (
    "import json, resource, subprocess, sys, time\n"
    "t = time.perf_counter()\n"
    "p = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,\n"
    "                   text=True)\n"
    "wall = time.perf_counter() - t\n"
    "ru = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(json.dumps({'rc': p.returncode, 'wall': wall, 'rss_kib': ru.ru_maxrss,\n"
    "                  'cpu': ru.ru_utime + ru.ru_stime, 'err': p.stderr[-2000:]}))\n"
)


def measured(cmd) -> dict:
    """Wall seconds, CPU seconds and peak RSS (MiB) of one run of cmd in a fresh process."""
    proc = subprocess.run([sys.executable, "-c", WRAPPER, *map(str, cmd)], capture_output=True,
                          text=True, check=True)
    out = json.loads(proc.stdout)
    if out["rc"] != 0:
        raise RuntimeError(f"failed ({out['rc']}): {' '.join(map(str, cmd))}\n{out['err']}")
    return {"wall": out["wall"], "cpu": out["cpu"], "rss": out["rss_kib"] / 1024.0}


def repeat(cmd, runs: int):
    results = [measured(cmd) for _ in range(runs)]
    return (Stats([r["wall"] for r in results]), Stats([r["cpu"] for r in results]),
            max(r["rss"] for r in results))


def run(quick: bool = False, log=print) -> str:
    """Measure and return the Markdown section."""
    t_start = time.perf_counter()
    load0 = common.load_average()
    cli = common.osmap_cli()
    if cli is None:
        return "## Memory and 1024x1024\n\n_Skipped: the `osmap` CLI is not available._\n"
    sample = SAMPLES_DIR / f"{SAMPLE}.png"
    scratch = common.fresh_dir("osmap-bench-memory-")
    runs_small, runs_big = (2, 1) if quick else (5, 3)
    rows, rss = [], {}
    try:
        helps = repeat([cli, "--help"], runs_small)
        rows.append(["`osmap --help` (interpreter + CLI imports)", "–", helps[0].text(), "–",
                     f"{helps[2]:.0f}", "–", "–"])
        tiny = [cli, "synth", sample, "-o", scratch / "out64.png", "--size", 64, "--seed", "1",
                "--quiet"]
        measured(tiny)  # warm the Numba cache
        base = repeat(tiny, runs_small)
        base_rss = base[2]
        rows.append([f"`osmap synth {SAMPLE}.png --size 64` (baseline: libraries + kernels)",
                     f"{runs_small}", base[0].text(), f"{base[1].median:.2f}",
                     f"{base_rss:.0f}", "–", "–"])
        for size in SIZES:
            cmd = [cli, "synth", sample, "-o", scratch / f"out{size}.png", "--size", size,
                   "--seed", "1", "--quiet"]
            runs = runs_big if size >= 1024 else runs_small
            log(f"[memory] synth {size}x{size}, {runs} runs ...")
            wall, cpu, peak = repeat(cmd, runs)
            rss[size] = peak
            pixels = size * size
            prev = SIZES[SIZES.index(size) - 1] if size != SIZES[0] else None
            marginal = ((peak - rss[prev]) * 2**20 / (pixels - prev * prev)) if prev else None
            rows.append([f"`osmap synth {SAMPLE}.png --size {size}`", f"{runs}", wall.text(),
                         f"{cpu.median:.2f}", f"{peak:.0f}",
                         f"{(peak - base_rss) * 2**20 / pixels:.0f}",
                         f"{marginal:.0f}" if marginal is not None else "–"])
        solid_ok = subprocess.run([str(cli), "solid", "--help"], capture_output=True).returncode
        if solid_ok == 0:
            for size in SOLID_SIZES:
                cmd = [cli, "solid", sample, "-o", scratch / f"vol{size}.npy", "--size", size,
                       "--seed", "1", "--quiet"]
                if size == SOLID_SIZES[0]:
                    measured(cmd)
                runs = 1 if (quick or size >= 128) else 3
                log(f"[memory] solid {size}^3, {runs} runs ...")
                wall, cpu, peak = repeat(cmd, runs)
                voxels = size ** 3
                prev = SOLID_SIZES[SOLID_SIZES.index(size) - 1] if size != SOLID_SIZES[0] else 0
                marginal = ((peak - rss[("solid", prev)]) * 2**20 / (voxels - prev ** 3)
                            if prev else None)
                rss[("solid", size)] = peak
                rows.append([f"`osmap solid {SAMPLE}.png --size {size}` ({size}^3)", f"{runs}",
                             wall.text(), f"{cpu.median:.2f}", f"{peak:.0f}",
                             f"{(peak - base_rss) * 2**20 / voxels:.0f}",
                             f"{marginal:.0f}" if marginal is not None else "–"])
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    elapsed = time.perf_counter() - t_start
    out = [
        "## Memory and 1024x1024",
        f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`; section "
        f"took {elapsed / 60:.1f} min; load average (1 min) at start / end: {load0} / "
        f"{common.load_average()}._",
        "Each run is a fresh process started by a wrapper that reads "
        "`resource.getrusage(RUSAGE_CHILDREN).ru_maxrss` (peak resident set of that one child) "
        "after it exits. Wall seconds, median (min–max) of the given number of runs after one "
        f"warm-up run (Numba cache warm); 1024x1024 and 128^3 use fewer runs ({runs_big} and "
        "1), as each takes tens of seconds on this shared machine. `B/px` is (peak − the "
        "64x64 baseline, whose peak is the interpreter, numpy, OpenImageIO, Numba and the "
        "loaded kernels) per output pixel (voxel); `marginal B/px` is the peak's growth per "
        "added pixel from the previous size. Memory proportional to the output shows as "
        "similar B/px at every size.",
        md_table(["command", "runs", "wall s", "cpu s", "peak RSS MiB", "B/px", "marginal B/px"],
                 rows),
    ]
    return "\n\n".join(out) + "\n"


if __name__ == "__main__":
    sys.exit(common.section_main(__doc__, run))
