"""Where the time of one `osmap synth` process goes, phase by phase.

The process runs as the console script does (the collector off for start-up, kernelwarm.prepare,
cli.main, cli.exit_now), with clocks around each step of the job (read + check, compute, write)
and around every kernel's first call (Numba loading it from its cache). Phases, wall and CPU
seconds (CPU: all threads):

- imports: click, numpy, Numba (Numba first here; a run imports it at its first kernel);
- other imports and set-up: osmap, click, OpenImageIO, option parsing;
- read + check: the exemplar read and validated;
- kernel loads: Numba loading each kernel's machine code from its cache, at its first call on
  the main thread (those the synthesis' helper thread loads, osmap_cli.synth.ahead, overlap the
  main thread's work and count in compute);
- compute: the synthesis, loads excluded;
- write: the output encoded and committed, the summary printed;
- interpreter start + exit: what the outside clock sees beyond the inside one (Python's own
  start-up before the first line of osmap, and the exit after the last).

    python bench/run_phases.py synth samples/cells.png -o /tmp/x.png --size 256 --quiet
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from common import fmt, md_table

PROBE = r"""
import json, os, sys, threading, time
T0, C0 = time.perf_counter(), time.process_time()
marks = {"start": (0.0, 0.0)}
def mark(name):
    marks[name] = (time.perf_counter() - T0, time.process_time() - C0)
from osmap_cli import cli, kernelwarm
cli._single_threaded_blas()  # as cli.run() does
os.environ.setdefault("OSMAP_KERNELS", "auto")
os.environ.setdefault("OSMAP_QUICK_LOADS", "1")
cli._start_up_without_gc()
kernelwarm.prepare()
import numba
mark("numba")
from osmap_cli.synth.job import SynthJob
loads = [0.0, 0.0]
for name in ("read", "check", "compute", "stage"):
    def wrapped(self, *args, _method=getattr(SynthJob, name), _name=name):
        if _name == "read":
            mark("set-up")
        if _name == "compute":
            from numba.core import dispatcher
            first = dispatcher.Dispatcher._compile_for_args
            def timed(disp, *a, **k):
                if threading.current_thread() is not threading.main_thread():
                    return first(disp, *a, **k)  # a helper's loads overlap the compute
                t, c = time.perf_counter(), time.process_time()
                try:
                    return first(disp, *a, **k)
                finally:
                    loads[0] += time.perf_counter() - t
                    loads[1] += time.process_time() - c
            dispatcher.Dispatcher._compile_for_args = timed
        result = _method(self, *args)
        mark(_name)
        return result
    setattr(SynthJob, name, wrapped)
code = cli.main(sys.argv[1:])
mark("main")
with open(os.environ["BENCH_PHASES_OUT"], "w") as handle:
    json.dump({"marks": marks, "loads": loads}, handle)
cli.exit_now(code)
"""

PHASES = ("imports: click, numpy, Numba", "other imports and set-up", "read + check",
          "kernel loads", "compute", "write", "interpreter start + exit", "total")


def _one(argv: list[str], env: dict) -> dict:
    """{phase: (wall, CPU)} of one process."""
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "phases.json")
        before = os.times()
        started = time.perf_counter()
        subprocess.run([sys.executable, "-c", PROBE, *argv], env={**env, "BENCH_PHASES_OUT": out},
                       check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - started
        after = os.times()
        with open(out) as handle:
            data = json.load(handle)
    cpu = (after.children_user - before.children_user
           + after.children_system - before.children_system)
    m, (load_wall, load_cpu) = data["marks"], data["loads"]

    def span(a, b):
        return m[b][0] - m[a][0], m[b][1] - m[a][1]

    compute = span("check", "compute")
    return {
        "imports: click, numpy, Numba": tuple(m["numba"]),
        "other imports and set-up": span("numba", "set-up"),
        "read + check": span("set-up", "check"),
        "kernel loads": (load_wall, load_cpu),
        "compute": (compute[0] - load_wall, compute[1] - load_cpu),
        "write": span("compute", "main"),
        # what the outside clock sees beyond the inside one
        "interpreter start + exit": (wall - m["main"][0], cpu - m["main"][1]),
        "total": (wall, cpu),
    }


def measure(argv: list[str], runs: int = 3, env: dict | None = None) -> dict:
    """Median (wall, CPU) seconds of each phase over RUNS processes (one untimed run first)."""
    env = dict(os.environ if env is None else env)
    _one(argv, env)
    samples = [_one(argv, env) for _ in range(runs)]
    return {phase: (statistics.median(s[phase][0] for s in samples),
                    statistics.median(s[phase][1] for s in samples)) for phase in PHASES}


def table(result: dict) -> str:
    return md_table(["phase", "wall s", "CPU s"],
                    [[phase, fmt(wall), fmt(cpu)] for phase, (wall, cpu) in result.items()])


if __name__ == "__main__":
    print(table(measure(sys.argv[1:])))
