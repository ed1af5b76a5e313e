"""Where a first run's time goes: the Numba compile of each kernel, what a warm run loads, and
the first run after `pip install .` that the portable kernel cache serves.

Each compile measurement is a fresh process with NUMBA_CACHE_DIR pointed at an empty folder,
running a default 256x256 `synthesize` from a shipped sample with one Numba thread (so that
every compile happens in the calling thread, whose CPU time is then the compile's). Reported:

- compile CPU seconds of each kernel the run calls (time.thread_time() around the first call
  of each dispatcher, callees included), and the signatures it compiled for;
- the two groups that `osmap_cli.synth.warm` compiles side by side (a tree without a portable
  cache), each in a fresh process (CPU seconds; refine after organise, into the same cache, as
  in a first run);
- a warm process: seconds to import numba, and to load each kernel from the cache;
- after install (skipped with --quick): this checkout installed with `pip install` into a new
  virtual environment (timed), then, NUMBA_CACHE_DIR unset and no warmup, the first `osmap
  synth` at 256x256, the first `osmap solid` at 128^3 and the first `osmap carve` (a 64^3
  volume) (each a fresh process: wall, CPU and the kernels it compiled; they run on the
  portable kernels), the background compile for this CPU that the first one
  starts (until its marker appears), the same commands again (this CPU's kernels), and
  paired steady-state runs: this CPU's kernels from the background compile against kernels
  compiled on first use (OSMAP_KERNELS=host, a separate cache: the ordinary way), and the
  portable kernels (forced with NUMBA_CPU_NAME=generic) against this CPU's.

    python bench/bench_compile.py [--quick]
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile

import common
from common import SAMPLES_DIR, fmt, md_table, timed_run

COMMAND = ".venv/bin/python bench/run.py --only compile"

PROBE = r"""
import json, sys, time
from numba.core import dispatcher
orig = dispatcher.Dispatcher._compile_for_args
times = {}
def wrapped(self, *a, **k):
    t = time.thread_time()
    try:
        return orig(self, *a, **k)
    finally:
        key = self.py_func.__module__.split(".")[-1] + "." + self.py_func.__qualname__
        times.setdefault(key, [0.0, 0])
        times[key][0] += time.thread_time() - t
        times[key][1] = len(self.signatures)
dispatcher.Dispatcher._compile_for_args = wrapped
from osmap_cli.imageio import read_image
from osmap_cli.synth import SynthOptions, synthesize
image = read_image(sys.argv[1]).pixels
synthesize(image, SynthOptions(width=256, height=256, seed=1))
print(json.dumps(times))
"""

LOADS = r"""
import json, sys, time
t0 = time.perf_counter()
import numba
t1 = time.perf_counter()
from numba.core import dispatcher
orig = dispatcher.Dispatcher.compile
loads = {}
def wrapped(self, sig):
    t = time.perf_counter()
    try:
        return orig(self, sig)
    finally:
        key = self.py_func.__module__.split(".")[-1] + "." + self.py_func.__qualname__
        loads[key] = loads.get(key, 0.0) + time.perf_counter() - t
dispatcher.Dispatcher.compile = wrapped
from osmap_cli.imageio import read_image
from osmap_cli.synth import SynthOptions, synthesize
image = read_image(sys.argv[1]).pixels
t2 = time.perf_counter()
synthesize(image, SynthOptions(width=256, height=256, seed=1))
t3 = time.perf_counter()
synthesize(image, SynthOptions(width=256, height=256, seed=1))
t4 = time.perf_counter()
print(json.dumps({"numba": t1 - t0, "loads": loads, "first": t3 - t2, "second": t4 - t3}))
"""


def _python(code: str, *args, env=None) -> dict:
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          env=env, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def _group_cpu(group: str, env: dict) -> float:
    import resource
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "osmap_cli.synth.warm", group], env=env, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _wall_cpu(argv, env, cwd) -> tuple[float, float]:
    return timed_run(argv, env=env, cwd=cwd)


def _first_run(argv, env, cwd) -> tuple[float, float, int]:
    """(wall s, CPU s, kernel signatures compiled): a run with Numba's cache log on (stdout),
    whose "data saved" lines are the compiles (a kernel loaded from a cache saves nothing)."""
    output = []
    wall, cpu = timed_run(argv, env=dict(env, NUMBA_DEBUG_CACHE="1"), cwd=cwd, output=output)
    return wall, cpu, output[0].count("data saved to")


def _after_install(log) -> list[str]:
    """The section's "after install" paragraph and tables (see the module docstring)."""
    import os
    import shutil
    import statistics
    import time
    from pathlib import Path

    root = Path(tempfile.mkdtemp(prefix="osmap-install-", dir=common.tmp_root()))
    try:
        venv = root / "venv"
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet"]
        subprocess.run([*pip, "pip>=21.3"], check=True, capture_output=True)
        log("[compile] pip install . into a new environment")
        started = time.perf_counter()
        subprocess.run([*pip, str(common.REPO_ROOT)], check=True, capture_output=True)
        install = time.perf_counter() - started
        osmap = str(venv / "bin" / "osmap")
        env = {k: v for k, v in os.environ.items()
               if not k.startswith(("NUMBA_", "OSMAP_")) and k != "PYTHONDONTWRITEBYTECODE"}
        env["HOME"] = str(root)  # no user-wide cache of an earlier run
        work = root / "work"
        work.mkdir()
        synth = [osmap, "synth", str(SAMPLES_DIR / "cells.png"), "-o", "s.png", "--size", "256",
                 "--quiet"]
        solid = [osmap, "solid", str(SAMPLES_DIR / "cells.png"), "-o", "v.npy", "--size", "128",
                 "--quiet"]
        carve = [osmap, "carve", str(SAMPLES_DIR / "vase.obj"), "--exemplar",
                 str(SAMPLES_DIR / "cells.png"), "-o", "c.glb", "--size", "64", "--quiet"]
        commands = {"synth": synth, "solid": solid, "carve": carve}
        log("[compile] first runs")
        first = {name: _first_run(argv, env, work) for name, argv in commands.items()}
        started = time.perf_counter()
        marker = None
        while marker is None and time.perf_counter() - started < 1800:
            marker = next(iter(venv.rglob("osmap-host-*.ready")), None)
            time.sleep(1.0)
        background = time.perf_counter() - started
        log(f"[compile] background compile done after {background:.0f} s more")
        again = {name: _first_run(argv, env, work) for name, argv in commands.items()}
        # steady state, paired: host (background) / host (first use), portable / host
        ordinary = dict(env, OSMAP_KERNELS="host", NUMBA_CACHE_DIR=str(root / "first-use"))
        _wall_cpu(synth, ordinary, work)  # compiles the ordinary way
        portable = dict(env, NUMBA_CPU_NAME="generic", NUMBA_CPU_FEATURES="")  # forced
        ratios = {"host": [], "portable": []}
        for _ in range(5):
            ours = _wall_cpu(synth, env, work)
            ratios["host"].append(ours[1] / _wall_cpu(synth, ordinary, work)[1])
            ratios["portable"].append(_wall_cpu(synth, portable, work)[1] / ours[1])
    finally:
        shutil.rmtree(root, ignore_errors=True)
    shown = {"synth": "`osmap synth cells.png --size 256`",
             "solid": "`osmap solid cells.png --size 128`",
             "carve": "`osmap carve vase.obj --exemplar cells.png --size 64`"}
    rows = [[shown[name], fmt(first[name][0], 1), fmt(first[name][1], 1), first[name][2],
             fmt(again[name][0], 1), fmt(again[name][1], 1), again[name][2]] for name in shown]
    return [
        f"After install: `pip install .` of this checkout into a new virtual environment took "
        f"{install:.0f} s (the build compiles the portable kernels). Then, with NUMBA_CACHE_DIR "
        "unset and no `osmap warmup`, each command's first run (portable kernels) and a run "
        f"after the background compile for this CPU had finished ({background:.0f} s after the "
        "first run), each a fresh process:", "",
        md_table(["command", "first run wall s", "first run CPU s", "first run compiles",
                  "later run wall s", "later run CPU s", "later run compiles"], rows),
        "*compiles*: kernel signatures the run compiled (Numba's cache log; 0: every kernel "
        "came from a cache).", "",
        "Steady state, CPU-second ratios of paired runs (medians of 5 pairs, `osmap synth` "
        "256x256): this CPU's kernels from the background compile / kernels compiled on first "
        f"use the ordinary way {fmt(statistics.median(ratios['host']), 3)}; the portable "
        f"kernels / this CPU's {fmt(statistics.median(ratios['portable']), 3)}.", "",
    ]


def run(quick: bool = False, log=print) -> str:
    import os

    sample = SAMPLES_DIR / "cells.png"
    base = dict(os.environ, NUMBA_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(dir=common.tmp_root()) as cache:
        log("[compile] per-kernel compile, empty cache")
        times = _python(PROBE, str(sample), env=dict(base, NUMBA_CACHE_DIR=cache))
        log("[compile] warm loads")
        warm = _python(LOADS, str(sample), env=dict(base, NUMBA_CACHE_DIR=cache))
    groups = {}
    with tempfile.TemporaryDirectory(dir=common.tmp_root()) as cache:
        # one after the other into one cache: refine then finds the kernels it shares with
        # organise cached, as it does in a first run (organise compiles those first)
        for group in ("organise", "refine"):
            log(f"[compile] group {group}")
            groups[group] = _group_cpu(group, dict(base, NUMBA_CACHE_DIR=cache))
    rows = [[f"`{name}`", fmt(cpu, 1), count, fmt(warm["loads"].get(name), 3)]
            for name, (cpu, count) in sorted(times.items(), key=lambda kv: -kv[1][0])]
    total = sum(cpu for cpu, _ in times.values())
    rows.append(["total", fmt(total, 1), "", fmt(sum(warm["loads"].values()), 3)])
    return "\n".join([
        "## Compile: where a first run's time goes", "",
        f"_{common.stamp()}; reproduce with `{COMMAND}`; load average (1 min) at the end: "
        f"{common.load_average()} (CPU seconds are less affected by a busy machine than wall "
        "seconds)._", "",
        "A default 256x256 `synthesize` of `samples/cells.png` in a fresh process with an empty "
        "NUMBA_CACHE_DIR and one Numba thread: *compile CPU s* is the calling thread's CPU time "
        "in each kernel's first call (its callees included); *load s* is the wall time to load "
        "it from the cache in a later, warm process (the first load also sets up Numba's CPU "
        "target, about half a second, whichever kernel comes first).", "",
        md_table(["kernel", "compile CPU s", "signatures", "warm load s"], rows),
        "Without portable kernels (a development tree), a first `osmap synth` compiles the "
        "kernels in two groups at once, one in a child process (`osmap_cli.synth.warm`); each "
        "group in a fresh process (CPU s, interpreter "
        "and imports included; refine with the kernels it shares with organise already cached, "
        "as in a first run, where organise compiles them first): "
        + ", ".join(f"{g} {fmt(s, 1)}" for g, s in groups.items())
        + ". On two idle cores the compile's wall time is about the larger one.", "",
        f"Warm process: `import numba` {fmt(warm['numba'], 2)} s; the first 256x256 "
        f"`synthesize` (kernels loaded from the cache) {fmt(warm['first'], 2)} s, a second one "
        f"in the same process {fmt(warm['second'], 2)} s (one thread).", "",
        *([] if quick else _after_install(log)),
    ])


if __name__ == "__main__":
    print(run(quick="--quick" in sys.argv, log=lambda m: print(m, file=sys.stderr)))
