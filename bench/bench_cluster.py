"""Cluster benchmark: a 40-job `osmap synth` batch with `-j 2` against `--scheduler local:2`
(end to end, interleaved rounds), and the per-task overhead of the cluster path on a running
LocalCluster (osmap_cli.cluster).

`run(quick=False) -> str` returns the Markdown section "## Clusters" (bench/run.py includes
it); `python bench/bench_cluster.py [--quick]` prints it. Needs dask.distributed
(`pip install 'osmap[cluster]'`, which `make venv` installs); the exemplars are 48x48 crops of
samples/ made in a temporary folder.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import common
from common import SAMPLES_DIR, Stats, fmt, md_table

JOBS = 40
SIZE = 64
NOOP_JOBS = 200
COMMAND = ".venv/bin/python bench/run.py --only cluster"


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _exemplars(folder: Path, count: int) -> list[Path]:
    """COUNT 48x48 crops of the shipped samples at different offsets."""
    from osmap_cli.imageio import read_image, write_image

    names = ("cells.png", "brick.png", "weave.png", "grass.png", "gravel.png")
    paths = []
    for i in range(count):
        source = read_image(SAMPLES_DIR / names[i % 5]).pixels
        y, x = 10 * (i // 5) % 80, 9 * (i // 5) % 80
        path = folder / f"ex{i:02d}_{names[i % 5]}"
        write_image(path, source[y:y + 48, x:x + 48], 8)
        paths.append(path)
    return paths


def _cli_batch(exemplars, out: Path, mode: list[str]) -> tuple[float, list[dict]]:
    """`osmap synth EXEMPLARS --out-dir OUT --json` with MODE; (wall seconds, records)."""
    osmap = Path(sys.executable).parent / "osmap"
    cmd = [str(osmap), "synth", *map(str, exemplars), "--out-dir", str(out), "--size",
           str(SIZE), "--json", "-q", *mode]
    started = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:2])} ... {' '.join(mode)} failed "
                           f"({done.returncode}): {done.stderr.strip()[-2000:]}")
    return wall, [json.loads(line) for line in done.stdout.splitlines()]


def _end_to_end(exemplars, work: Path, rounds: int) -> tuple[str, dict]:
    modes = {"-j 2": ["-j", "2"], "--scheduler local:2": ["--scheduler", "local:2"]}
    walls = {name: [] for name in modes}
    busy = {name: [] for name in modes}
    outputs = {}
    for r in range(rounds):
        order = list(modes) if r % 2 == 0 else list(reversed(modes))  # ABBA: fair to both
        for name in order:
            out = work / f"e2e_{r}_{name.split()[-1].replace(':', '')}"
            wall, records = _cli_batch(exemplars, out, modes[name])
            assert len(records) == JOBS and {x["status"] for x in records} == {"ok"}
            walls[name].append(wall)
            busy[name].append(sum(x["seconds"] for x in records))
            _log(f"[cluster] round {r + 1}/{rounds} {name}: {wall:.1f} s")
            outputs.setdefault(name, out)
    same = all((outputs["-j 2"] / p.name).read_bytes()
               == (outputs["--scheduler local:2"] / p.name).read_bytes() for p in exemplars)
    rows = []
    for name in modes:
        wall = Stats(walls[name])
        job_seconds = statistics.median(busy[name])
        # what two workers spent outside the jobs' own run(), per job: start-up, scheduling
        overhead = (2 * wall.median - job_seconds) / JOBS
        rows.append([f"`{name}`", wall.text(1), fmt(JOBS / wall.median, 2),
                     fmt(job_seconds / JOBS, 2), fmt(overhead, 3)])
    table = md_table(["mode", "wall s (median, min–max)", "jobs/s", "job s (mean)",
                      "overhead s/job"], rows)
    return table, {"same": same, "walls": walls}


def _jobs(exemplars, out: Path, replace: bool) -> list:
    from osmap_cli.synth.job import SynthJob
    from osmap_cli.synth.options import SynthOptions

    options = SynthOptions(width=SIZE, height=SIZE, seed=1).validated()
    return [SynthJob(index=i, exemplar=str(path), output=str(out / path.name), options=options,
                     preset="default", preset_values={}, replace=replace)
            for i, path in enumerate(exemplars, 1)]


def _timed(run) -> tuple[float, list[dict]]:
    records: list[dict] = []
    started = time.perf_counter()
    run(records.append)
    return time.perf_counter() - started, records


def _import_seconds(runs: int = 3) -> float:
    """What importing distributed adds to a process's start (median of RUNS)."""
    def once(code: str) -> float:
        started = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        return time.perf_counter() - started

    return statistics.median(once("import distributed") - once("pass") for _ in range(runs))


def _warm_cluster(exemplars, work: Path) -> tuple[str, float, float]:
    """Per-task overhead on a running local cluster: real jobs and no-op (skipped) jobs."""
    from distributed import Client

    from osmap_cli.cluster import ClusterSpec, run_cluster, start_local_cluster
    from osmap_cli.records import run_caught

    started = time.perf_counter()
    cluster = start_local_cluster(2)  # as --scheduler local:2 starts it
    try:
        with Client(cluster) as client:
            client.wait_for_workers(2, timeout=300)
        start_seconds = time.perf_counter() - started
        spec = ClusterSpec(address=cluster.scheduler_address)
        out = work / "warm"
        out.mkdir()
        # first jobs warm the workers up (imports, Numba's cache); not counted
        warm_out = work / "warmup"
        warm_out.mkdir()
        _timed(lambda report: run_cluster(_jobs(exemplars[:2], warm_out, True), spec, False,
                                          False, report))
        real_wall, real = _timed(lambda report: run_cluster(_jobs(exemplars, out, True), spec,
                                                            False, False, report))
        assert {r["status"] for r in real} == {"ok"}
        real_busy = sum(r["seconds"] for r in real)
        # no-op tasks: every output exists and may not be replaced, so each job is "skipped"
        noop = (_jobs(exemplars, out, False) * (NOOP_JOBS // JOBS + 1))[:NOOP_JOBS]
        noop_walls: dict[bool, list[float]] = {False: [], True: []}
        for fail_fast in (False, True, True, False):  # ABBA
            wall, records = _timed(lambda report, ff=fail_fast: run_cluster(
                noop, spec, ff, False, report))
            assert {r["status"] for r in records} == {"skipped"}
            noop_walls[fail_fast].append(wall)
        rows_noop = [(label, statistics.mean(noop_walls[ff]))
                     for label, ff in (("cluster", False), ("cluster, --fail-fast", True))]
        serial_wall, _ = _timed(lambda report: [report(run_caught(j)) for j in noop])
    finally:
        closing = time.perf_counter()
        cluster.close()
        close_seconds = time.perf_counter() - closing
    rows = [
        [f"{JOBS} real jobs ({SIZE}x{SIZE}), 2 workers", fmt(real_wall, 1),
         fmt(real_busy / JOBS, 3), fmt((2 * real_wall - real_busy) / JOBS, 3)],
        *[[f"{NOOP_JOBS} no-op jobs (skipped), {label}", fmt(wall, 2), "–",
           fmt(2 * wall / NOOP_JOBS, 4)] for label, wall in rows_noop],
        [f"{NOOP_JOBS} no-op jobs, in this process (`-j 1`)", fmt(serial_wall, 2), "–",
         fmt(serial_wall / NOOP_JOBS, 4)],
    ]
    table = md_table(["batch on a running `local:2` cluster", "wall s", "job s (mean)",
                      "overhead s/task (worker time)"], rows)
    return table, start_seconds, close_seconds


def run(quick: bool = False, log=_log) -> str:
    try:
        import distributed
    except ImportError:
        return ("## Clusters\n\n_Skipped: dask.distributed is not installed "
                "(`pip install 'osmap[cluster]'`)._\n")
    rounds = 1 if quick else 3
    work = common.fresh_dir("osmap-bench-cluster-")
    try:
        exemplars = _exemplars(work, JOBS)
        log(f"[cluster] end to end: {rounds} round(s) of -j 2 and --scheduler local:2")
        e2e, info = _end_to_end(exemplars, work, rounds)
        log("[cluster] per-task overhead on a running cluster")
        warm, start_seconds, close_seconds = _warm_cluster(exemplars, work)
        import_seconds = _import_seconds()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    gap = (statistics.median(info["walls"]["--scheduler local:2"])
           - statistics.median(info["walls"]["-j 2"]))
    fixed = import_seconds + start_seconds + close_seconds
    return "\n".join([
        "## Clusters: `-j 2` against `--scheduler local:2`",
        "",
        f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`; "
        f"dask.distributed {distributed.__version__}; load average {load:.1f} at the end "
        "(2 shared cores: the machine was not idle)._",
        "",
        f"A {JOBS}-job batch: `osmap synth EX... --out-dir DIR --size {SIZE} --json -q` on "
        f"{JOBS} 48x48 crops of samples/, default preset, end to end (process start, pool or "
        f"cluster start-up, {JOBS} jobs, shut-down), {rounds} interleaved round(s) "
        "(ABBA order). Both modes run two single-threaded workers. *job s* is the mean of "
        "the records' `seconds` (the job's own run); *overhead s/job* = (2 x wall - sum of "
        "job seconds) / jobs, i.e. worker time not spent in jobs, start-up included.",
        "",
        e2e,
        f"Outputs of the two modes byte-identical: {'yes' if info['same'] else 'NO'}.",
        "",
        f"`local:2` took {gap:+.1f} s against `-j 2` (medians). Its fixed costs, measured "
        f"apart: importing distributed {import_seconds:.1f} s, starting the cluster (scheduler, "
        f"two nannies and their worker processes) {start_seconds:.1f} s, closing it "
        f"{close_seconds:.1f} s: {fixed:.1f} s in all, which `-j 2`'s process pool does not "
        "pay (the gap also holds the per-task overhead below, and the noise of a shared "
        "machine, of either sign). "
        "`local:N` is for trying the cluster path out; on a real cluster the start-up is paid "
        "once, by the cluster, not by each batch.",
        "",
        f"Per-task overhead of the cluster path once the cluster runs (started in "
        f"{start_seconds:.1f} s, 2 workers, Numba cache warm): real jobs, and no-op tasks "
        "(every output exists, so each job is reported \"skipped\" after a stat: what is "
        "left is submission, scheduling, pickling the job and its record, the worker's lock "
        "and chdir). *overhead s/task* is worker time per task (2 x wall / tasks; for the real "
        "jobs minus their own seconds); `--fail-fast` adds a distributed Event look-up per "
        "task. No-op rows: the mean of two runs each, in ABBA order.",
        "",
        warm,
    ])


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    raise SystemExit(common.section_main(__doc__, run))
