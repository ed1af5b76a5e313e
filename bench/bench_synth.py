"""Speed of `osmap synth` end to end, as a user sees it (a fresh process per run).

Every run is a subprocess: interpreter start-up, imports, reading the exemplar, synthesis and
writing the PNG, with this CPU's kernels (OSMAP_KERNELS=host). The Numba cache is warmed by one
untimed run per sample first; a run that compiles every kernel on first use is measured once,
separately, with NUMBA_CACHE_DIR pointed at an empty directory (the first run after
`pip install .`, which starts from the portable kernels, is in bench_compile.py's section). If
the `osmap` CLI is not installed next to this interpreter (or does not work yet), a `python -c`
script calling the library does the same work, and the table says so.

Times are wall-clock seconds on a shared machine: compare them with the baselines measured in
the same run (interpreter start-up), never with absolute numbers from another machine.

    python bench/bench_synth.py [--quick] [--runs N] [--samples brick,cells]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

import common
from common import SAMPLES_DIR, Stats, fmt, md_table, timed_run

SAMPLES = ("brick", "cells", "weave", "gravel")
QUICK_SAMPLES = ("brick", "cells")
SIZES = (256, 512)
SEED = 1
COMMAND = ".venv/bin/python bench/run.py --only synth"

LIBRARY_SCRIPT = (
    "import sys\n"
    "from osmap_cli.imageio import read_image, write_image\n"
    "from osmap_cli.synth import SynthOptions, synthesize\n"
    "src, out, n, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])\n"
    "ex = read_image(src).pixels\n"
    "res = synthesize(ex, SynthOptions(width=n, height=n, seed=seed))\n"
    "write_image(out, res.pixels)\n"
)


class Runner:
    """Builds the command for one synthesis, through the CLI or the library fallback."""

    def __init__(self):
        self.cli = common.osmap_cli()
        self.python = sys.executable

    @property
    def label(self) -> str:
        if self.cli:
            return f"CLI: `{self.cli.name} synth EXEMPLAR -o OUT --size N --seed {SEED} --quiet`"
        return ("**library fallback** (the `osmap` CLI is not available next to "
                f"`{self.python}`): `python -c` script that reads the exemplar, calls "
                "`synthesize(ex, SynthOptions(width=N, height=N, seed=1))` and writes the PNG")

    def synth_cmd(self, sample: Path, out: Path, size: int) -> list[str]:
        if self.cli:
            return [str(self.cli), "synth", str(sample), "-o", str(out), "--size", str(size),
                    "--seed", str(SEED), "--quiet"]
        return [self.python, "-c", LIBRARY_SCRIPT, str(sample), str(out), str(size), str(SEED)]


def channels(path: Path) -> str:
    try:
        import OpenImageIO as oiio
        return str(oiio.ImageInput.open(str(path)).spec().nchannels)
    except Exception:  # noqa: BLE001 - only decorative
        return "?"


def measure(cmd, runs: int, env=None):
    walls, cpus = [], []
    for _ in range(runs):
        wall, cpu = timed_run(cmd, env=env)
        walls.append(wall)
        cpus.append(cpu)
    return Stats(walls), Stats(cpus)


def run(quick: bool = False, runs: int | None = None, samples=None, log=print) -> str:
    """Measure and return the Markdown section."""
    t_start = time.perf_counter()
    load0 = common.load_average()
    runs = runs or (3 if quick else 5)
    samples = list(samples or (QUICK_SAMPLES if quick else SAMPLES))
    runner = Runner()
    py = sys.executable
    scratch = common.fresh_dir("osmap-bench-synth-")
    try:
        log(f"[synth] {'CLI' if runner.cli else 'library fallback (no working osmap CLI)'}; "
            f"{runs} runs per cell; samples {', '.join(samples)}")
        # this CPU's kernels, compiled on first use: the steady state, and a cold run that
        # compiles (the first run after an install is bench_compile.py's: portable kernels)
        base_env = dict(os.environ, OSMAP_KERNELS="host")

        # Baselines, same machine, same run.
        log("[synth] baselines: python -c pass, import, --help")
        py_start, _ = measure([py, "-c", "pass"], runs)
        imp, _ = measure([py, "-c", "import osmap_cli.synth, osmap_cli.imageio"], runs)
        help_stats = None
        if runner.cli:
            timed_run([str(runner.cli), "--help"])  # warm the file cache
            help_stats, _ = measure([str(runner.cli), "--help"], runs)

        # Cold: every kernel compiled, with an empty Numba cache.
        first = SAMPLES_DIR / f"{samples[0]}.png"
        cold_env = dict(base_env, NUMBA_CACHE_DIR=str(scratch / "numba-cold-cache"))
        log(f"[synth] cold run (fresh NUMBA_CACHE_DIR): {first.name} -> 256x256")
        cold_wall, cold_cpu = timed_run(runner.synth_cmd(first, scratch / "cold.png", 256),
                                        env=cold_env)

        rows, warm_first_256 = [], None
        for name in samples:
            sample = SAMPLES_DIR / f"{name}.png"
            if not sample.exists():
                log(f"[synth] missing sample {sample}, skipped")
                continue
            out = scratch / f"{name}.png"
            timed_run(runner.synth_cmd(sample, out, 256))  # untimed warm-up (Numba cache)
            cells = {}
            for size in SIZES:
                wall, cpu = measure(runner.synth_cmd(sample, out, size), runs)
                cells[size] = (wall, cpu)
                log(f"[synth] {name} {size}x{size}: median {wall.median:.2f} s "
                    f"(min {wall.min:.2f}, max {wall.max:.2f}), cpu {cpu.median:.2f} s")
            if warm_first_256 is None:
                warm_first_256 = cells[256][0].median
            w256, c256 = cells[256]
            w512, c512 = cells[512]
            rows.append([f"`{name}.png`", channels(sample), w256.text(), fmt(c256.median),
                         fmt(w256.median / py_start.median, 0) + "x",
                         w512.text(), fmt(c512.median), fmt(w512.median / w256.median)])
    finally:
        shutil.rmtree(scratch, ignore_errors=True)

    elapsed = time.perf_counter() - t_start
    out = ["## Speed: `osmap synth` end to end\n",
           f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`"
           f"; section took {elapsed / 60:.1f} min._\n",
           f"Each run is a fresh process: {runner.label}. Exemplars are the shipped 128 px "
           f"samples (`samples/`), seed {SEED}, default options. Wall seconds, median of {runs} "
           "runs (min–max), after one untimed warm-up run per sample (Numba cache warm); "
           "`cpu` is user+sys CPU seconds of the process (median); `x start` is the 256x256 "
           "wall time over a bare `python -c pass` measured in the same run.\n"]
    out.append(md_table(
        ["sample", "ch", "256x256 s", "cpu s", "x start", "512x512 s", "cpu s", "512/256"],
        rows))
    base_rows = [
        ["`python -c pass` (interpreter start-up)", py_start.text(), "1.0x"],
        ["`python -c \"import osmap_cli.synth, osmap_cli.imageio\"`", imp.text(),
         fmt(imp.median / py_start.median, 1) + "x"],
    ]
    if help_stats:
        base_rows.append(["`osmap --help` (CLI start-up)", help_stats.text(),
                          fmt(help_stats.median / py_start.median, 1) + "x"])
    else:
        base_rows.append(["`osmap --help` (CLI start-up)", "n/a: CLI not available", "–"])
    cold_ratio = f"{cold_wall / warm_first_256:.1f}x warm" if warm_first_256 else "–"
    base_rows.append([f"cold (Numba compile on first use, no portable kernels): `{samples[0]}"
                      ".png` -> 256x256, empty NUMBA_CACHE_DIR, 1 run",
                      f"{cold_wall:.2f} (cpu {cold_cpu:.2f})", cold_ratio])
    if warm_first_256:
        base_rows.append(["compile overhead = cold − warm median (same sample)",
                          f"{cold_wall - warm_first_256:.2f}", "–"])
    out.append("Start-up baselines and the one-off compile (wall seconds):\n")
    out.append(md_table(["what", "s median (min–max)", "ratio"], base_rows))
    out.append(f"{common.core_count()} cores; Numba threads: "
               f"{os.environ.get('NUMBA_NUM_THREADS', 'default (one per core)')}. "
               f"Load average (1 min) at start / end: {load0} / {common.load_average()} "
               "(other jobs on the machine inflate wall times; `cpu` is less affected).")
    return "\n\n".join(s.strip("\n") for s in out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 samples, 3 runs")
    ap.add_argument("--runs", type=int, help="timed runs per cell (default 5, quick 3)")
    ap.add_argument("--samples", help="comma-separated names from samples/ (brick,cells,...)")
    args = ap.parse_args(argv)
    samples = args.samples.split(",") if args.samples else None
    print(run(quick=args.quick, runs=args.runs, samples=samples,
              log=lambda m: print(m, file=sys.stderr, flush=True)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
