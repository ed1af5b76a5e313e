"""A large output: 4096x4096 from a 256 px exemplar, wall, CPU and peak RSS, against the memory
guard's estimate (osmap_cli.memory.texture_bytes) for the same size.

The exemplar is ../shared/exemplars/water_caustics.png (256x256, RGB; read in place, never
copied into the repository); the section is skipped with a note without it. One run (Numba
cache warmed first by a small one), a fresh process whose peak RSS is the operating system's
own accounting of that child (getrusage RUSAGE_CHILDREN after it exits). --quick: 2048x2048.

    python bench/bench_large.py [--quick]
"""

from __future__ import annotations

import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import common
from common import FULL_EXEMPLARS, fmt

EXEMPLAR = FULL_EXEMPLARS / "water_caustics.png"
COMMAND = ".venv/bin/python bench/run.py --only large"


def _run(cmd) -> tuple[float, float, float]:
    """(wall s, CPU s, peak RSS MiB) of one child."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, after.ru_maxrss / 1024.0


def run(quick: bool = False, log=print) -> str:
    from osmap_cli.memory import human, texture_bytes

    title = "## Large outputs"
    if not EXEMPLAR.exists():
        log(f"[large] {EXEMPLAR} not found: section skipped")
        return (f"{title}\n\n_Skipped on {common.stamp()}: "
                f"`{common.shared_rel(EXEMPLAR)}` is absent._\n")
    osmap = common.osmap_cli()
    if osmap is None:
        raise RuntimeError("the osmap CLI is not installed next to this interpreter")
    size = 2048 if quick else 4096
    with tempfile.TemporaryDirectory(dir=common.tmp_root()) as work:
        out = str(Path(work) / "large.png")
        subprocess.run([str(osmap), "synth", str(EXEMPLAR), "-o", out, "--size", "64", "-q"],
                       check=True)
        log(f"[large] {size}x{size}")
        wall, cpu, peak = _run([str(osmap), "synth", str(EXEMPLAR), "-o", out, "--size",
                                str(size), "--seed", "1", "--quiet"])
    estimate = texture_bytes(size, size, 3)
    return "\n".join([
        title, "",
        f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`; load "
        f"average (1 min) at the end: {common.load_average()}._", "",
        f"`osmap synth {common.shared_rel(EXEMPLAR)} -o OUT --size {size} --seed 1 --quiet` "
        "(256x256 RGB exemplar), one run, Numba cache warm: wall "
        f"{fmt(wall, 1)} s, CPU {fmt(cpu, 1)} s (user + sys), peak RSS {fmt(peak, 0)} MiB; "
        f"the memory guard's estimate for this size: {human(estimate)} (it refuses a size whose "
        "estimate exceeds the available memory or OSMAP_MEMORY_LIMIT, before any work). On a "
        "shared machine read the CPU seconds: on two free cores the wall time is about half of "
        "them.", "",
    ])


if __name__ == "__main__":
    print(run(quick="--quick" in sys.argv, log=lambda m: print(m, file=sys.stderr)))
