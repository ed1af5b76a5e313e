"""osmap against the fastest peer, the Resynthesizer engine, run side by side.

The peer is a command kept outside the repository (../shared/peers/resynth/resynth_cli, see its
README there); the section is skipped with a note when it is absent. For every shipped sample
and output size, `osmap synth` and the peer run in turn, A B A B ..., each a fresh process timed
from outside (start-up included); the ratio osmap / peer is taken pair by pair, so a drift of
the shared machine's speed cancels. Reported: each case's median pair ratio, and their
geometric mean per size. osmap runs as installed and warmed up (`osmap warmup` first: this
CPU's kernels), with Python's default bytecode caching (a PYTHONDONTWRITEBYTECODE in the
environment is dropped for its runs). Two more rows at 256x256: the Numba floor
(bench/numba_floor.py: Python, numpy and Numba imported, one cached kernel loaded and called,
nothing else) against the peer on the same samples, the start-up cost no change inside osmap
can remove; and a batch, one `osmap synth` call over all the samples (--out-dir) against the
peer run once per sample in turn, as a folder pipeline would. Last, where one 256x256 run's
time goes, phase by phase (bench/run_phases.py), beside the peer's whole run.

    python bench/bench_peer.py [--quick] [--runs N]
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import common
import run_phases
from common import SAMPLES_DIR, SHARED_DIR, fmt, md_table, timed_run

PEER = SHARED_DIR / "peers" / "resynth" / "resynth_cli"
# (output side, shipped samples): 128 px exemplars -> 256x256, 256 px exemplars -> 512x512
CASES = ((256, ("cells", "brick", "weave", "grass", "gravel", "wood_top")),
         (512, ("grass_256", "brick_256", "gravel_256")))
QUICK_CASES = ((256, ("cells", "brick")), (512, ("grass_256",)))
FLOOR = Path(__file__).resolve().parent / "numba_floor.py"
COMMAND = ".venv/bin/python bench/run.py --only peer"


def _geomean(values):
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values else float("nan")


def _paired(ours, peer, runs, env):
    """One untimed run of each, then `runs` pairs in turn: (median wall ours, median wall peer,
    median pair ratio of wall, of CPU)."""
    timed_run(ours, env=env)  # warm the kernel cache and the file cache
    timed_run(peer, env=env)
    walls, ratios, cpu_ratios = [], [], []
    for _ in range(runs):
        a_wall, a_cpu = timed_run(ours, env=env)
        b_wall, b_cpu = timed_run(peer, env=env)
        walls.append((a_wall, b_wall))
        ratios.append(a_wall / b_wall)
        cpu_ratios.append(a_cpu / b_cpu)
    return (statistics.median(w for w, _ in walls), statistics.median(w for _, w in walls),
            statistics.median(ratios), statistics.median(cpu_ratios))


def run(quick: bool = False, runs: int | None = None, log=print) -> str:
    title = "## Against the Resynthesizer engine (peer)"
    if not PEER.exists():
        log(f"[peer] {PEER} not found: section skipped")
        return (f"{title}\n\n_Skipped on {common.stamp()}: the peer command "
                f"`{common.shared_rel(PEER)}` is not present on this machine._\n")
    osmap = common.osmap_cli()
    if osmap is None:
        raise RuntimeError("the osmap CLI is not installed next to this interpreter")
    runs = runs or (2 if quick else 3)
    load_start = common.load_average()
    cases = QUICK_CASES if quick else CASES
    work = Path(tempfile.mkdtemp(prefix="osmap-peer-", dir=common.tmp_root()))
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    subprocess.run([str(osmap), "warmup", "--quiet"], env=env, check=True)
    rows, by_size, floors = [], {}, []
    try:
        for size, names in cases:
            for name in names:
                sample = SAMPLES_DIR / f"{name}.png"
                ours = [str(osmap), "synth", str(sample), "-o", str(work / "osmap.png"),
                        "--size", str(size), "--seed", "1", "--quiet"]
                peer = [str(PEER), str(sample), str(work / "peer.png"), str(size), str(size)]
                ours_s, peer_s, ratio, cpu_ratio = _paired(ours, peer, runs, env)
                by_size.setdefault(size, []).append((ratio, cpu_ratio))
                log(f"[peer] {name} -> {size}: osmap/peer wall {ratio:.2f}, cpu {cpu_ratio:.2f}")
                floor_ratio = "-"
                if size == 256:
                    floor = _paired([sys.executable, str(FLOOR)], peer, runs, env)
                    floors.append(floor[2])
                    floor_ratio = fmt(floor[2])
                    log(f"[peer] numba floor / peer, {name} -> {size}: {floor[2]:.2f}")
                rows.append([f"{name} -> {size}x{size}", fmt(ours_s), fmt(peer_s), fmt(ratio),
                             fmt(cpu_ratio), floor_ratio])
        names = cases[0][1]
        batch = [str(osmap), "synth", *(str(SAMPLES_DIR / f"{n}.png") for n in names),
                 "--out-dir", str(work / "batch"), "--overwrite", "--size", "256", "--seed", "1",
                 "--quiet"]
        peers = " && ".join(f"{shlex.quote(str(PEER))} {shlex.quote(str(SAMPLES_DIR / n))}.png "
                            f"{shlex.quote(str(work / 'peer.png'))} 256 256" for n in names)
        batch_ratio = _paired(batch, ["sh", "-c", peers], runs, env)
        log(f"[peer] batch of {len(names)} at 256: osmap/peer wall {batch_ratio[2]:.2f}")
        sample = SAMPLES_DIR / f"{names[0]}.png"
        phases = run_phases.measure(
            ["synth", str(sample), "-o", str(work / "phases.png"), "--size", "256", "--seed",
             "1", "--quiet"], runs=max(runs, 3), env=env)
        peer_one = [str(PEER), str(sample), str(work / "peer.png"), "256", "256"]
        peer_walls = [timed_run(peer_one, env=env) for _ in range(max(runs, 3))]
    finally:
        shutil.rmtree(work, ignore_errors=True)
    summary = [[f"{size}x{size} ({len(v)} samples, geometric mean)",
                fmt(_geomean([r for r, _ in v])), fmt(_geomean([c for _, c in v]))]
               for size, v in by_size.items()]
    summary.append([f"Numba floor, 256x256 ({len(floors)} samples, geometric mean)",
                    fmt(_geomean(floors)), "-"])
    summary.append([f"batch: one call, {len(names)} samples at 256x256 / the peer once each",
                    fmt(batch_ratio[2]), fmt(batch_ratio[3])])
    return "\n".join([
        title, "",
        f"_{common.stamp()}; reproduce with `{COMMAND}{' --quick' if quick else ''}`; load "
        f"average (1 min) at start / end: {load_start} / {common.load_average()} (the peer runs "
        "up to 8 threads, osmap one per core: on a busy machine the peer gets the larger share "
        "of the CPU, and the wall ratios grow)._", "",
        "`osmap synth EXEMPLAR -o OUT --size N --seed 1 --quiet` (this CPU's kernels cached, "
        "bytecode cached) and the "
        "Resynthesizer engine (`resynth_cli EXEMPLAR OUT N N`, its defaults; outside the "
        "repository, used only to measure) on the shipped samples, each a fresh process timed "
        f"from outside, run in turn {runs} times after one untimed run each; ratios are "
        "osmap / peer, pair by pair, medians (below 1: osmap is faster). *Numba floor*: "
        "`bench/numba_floor.py` (a process that imports numpy and Numba and calls one cached "
        "kernel, nothing else) / the peer's whole 256x256 run, the same samples: the start-up "
        "any Numba program pays, which no change inside osmap removes. *Batch*: one `osmap "
        "synth` over all the 256x256 samples (`--out-dir`) / the peer run once per sample.",
        "",
        md_table(["size", "osmap / peer wall", "osmap / peer CPU"], summary),
        md_table(["case", "osmap wall s", "peer wall s", "wall ratio", "CPU ratio",
                  "Numba floor / peer wall"], rows),
        f"Where one `osmap synth {names[0]}.png --size 256` goes (medians of "
        f"{max(runs, 3)} runs, wall and CPU seconds; bench/run_phases.py), beside the peer's "
        f"whole run on the same sample: wall {fmt(statistics.median(w for w, _ in peer_walls))}"
        f" s, CPU {fmt(statistics.median(c for _, c in peer_walls))} s.", "",
        run_phases.table(phases),
    ])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--runs", type=int, default=None)
    args = ap.parse_args(argv)
    print(run(quick=args.quick, runs=args.runs, log=lambda m: print(m, file=sys.stderr)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
