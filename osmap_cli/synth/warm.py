"""Compiled kernels for `osmap synth`: is Numba's cache ready, and if not, fill it fast.

Numba compiles a kernel on its first call and caches the machine code (next to the kernel
modules, or under NUMBA_CACHE_DIR) per signature and target CPU; every later run loads it. An
installed osmap starts from its portable cache (osmap_cli.kernelwarm); this module covers the
rest (a development tree, a numba other than the build's). Compiling is single-threaded, so on
a cold cache `ensure_compiled` splits the kernels a run uses into two groups of about equal
compile time and compiles one in a child process (`python -m osmap_cli.synth.warm GROUP`) while
this process compiles the other, each by a tiny run that calls the kernels with the argument
types a real run uses; it announces this with one line. A kernel counts as cached only with an
entry for the CPU this process compiles for (an entry of another CPU is never loaded). A file
lock in the cache folder makes concurrent first runs (-j N, several shells) compile once.

Only compiles change; the kernels and their results do not.
"""

from __future__ import annotations

import os
import subprocess
import sys

# CPU seconds to compile each group from an empty cache (BENCHMARKS.md, "Compile"; refine with
# the kernels it shares with organise cached, as in a first run): the announcement's estimate.
# organise includes the lattice kernels (about 2 s) that a regular exemplar's run calls.
GROUP_SECONDS = {"organise": 13.0, "refine": 13.0}
ANNOUNCEMENT = "osmap: compiling kernels, first run only (about {seconds} s)"


def _general(signature) -> bool:
    """som._train's specialisation for the general update (last argument None), the one synth
    runs; the classic one (True) may be cached without it."""
    return str(signature[-1]) == "none"


def _dispatchers(group: str) -> list:
    """(kernel, which of its cached signatures count: None for any) of a group."""
    if group == "organise":
        from osmap_kernels import coherence, lattice, regions, render, som
        return [(coherence.usage_counts, None), (regions.copy_region_areas, None),
                (som._train, _general), (render._vote_rows, None),
                (lattice.snap_field, None), (lattice.phase_sums, None)]
    from osmap_kernels import coherence, regions
    return [(coherence._knn_rows, None), (coherence._refine_rows, None),
            (regions.align_regions, None)]


def _cached(dispatcher, accept=None) -> bool:
    """Whether Numba's cache holds machine code of this kernel's current source for the CPU
    this process compiles for (any signature, or one that `accept` accepts): its index file
    exists, was written for this source (the index's stamp) and has an entry whose target is
    this process's (the key's second part: triple, CPU name, features)."""
    cache = getattr(dispatcher, "_cache", None)
    impl = getattr(cache, "_cache_file", None)
    if impl is None:
        return True  # caching off (e.g. NUMBA_DISABLE_JIT): nothing to warm
    try:
        index = impl._load_index()
        target = dispatcher.targetctx.codegen().magic_tuple()
    except Exception:  # noqa: BLE001 - an unreadable index is a cold one
        return False
    return any(key[1] == target and (accept is None or accept(key[0])) for key in index)


def cold_groups() -> list[str]:
    """The kernel groups a default synth run would have to compile (empty: all cached)."""
    return [g for g in GROUP_SECONDS
            if not all(_cached(d, accept) for d, accept in _dispatchers(g))]


def _lock_path() -> str | None:
    from osmap_kernels import coherence

    cache = getattr(coherence._refine_rows, "_cache", None)
    path = getattr(cache, "_cache_path", None)
    if not path:
        return None
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return None
    return os.path.join(path, "osmap-compile.lock")


def ensure_compiled(announce=None) -> bool:
    """Compile the synth kernels now if the cache lacks them (in parallel child processes);
    `announce(line)` is told first. Returns True if anything was compiled. Never fails: if the
    children cannot run, the kernels compile on first use as before."""
    if (os.environ.get("NUMBA_DISABLE_JIT") == "1" or os.environ.get("OSMAP_WARM_PLAN")
            or not cold_groups()):
        return False  # (OSMAP_WARM_PLAN: a run of osmap_cli.kernelwarm's plan compiles itself)
    lock = _lock_path()
    handle = None
    try:
        if lock is not None:
            import fcntl
            handle = open(lock, "a")
            fcntl.flock(handle, fcntl.LOCK_EX)  # another first run compiling: wait for it
        groups = cold_groups()
        if not groups:
            return False
        workers = min(len(groups), os.cpu_count() or 1)
        seconds = sum(GROUP_SECONDS[g] for g in groups) / workers
        if announce is not None:
            announce(ANNOUNCEMENT.format(seconds=int(round(seconds, -1)) or 10))
        _compile(groups, workers)
        return True
    except OSError:
        return False
    finally:
        if handle is not None:
            handle.close()


def _compile(groups: list[str], workers: int) -> None:
    """Compile the groups: all but the largest in child processes (`python -m
    osmap_cli.synth.warm GROUP`, at most workers - 1 at a time), the largest here meanwhile (a
    child first pays an interpreter start-up and the imports, about a second)."""
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    groups = sorted(groups, key=GROUP_SECONDS.get, reverse=True)
    here, rest = groups[0], groups[1:]
    children = []
    if workers > 1:
        for group in rest:
            children.append(subprocess.Popen(
                [sys.executable, "-m", "osmap_cli.synth.warm", group], env=env,
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        rest = []
    for group in [here] + rest:
        compile_group(group)
    for child in children:
        child.wait()  # a failed child only means its kernels compile on first use


def compile_group(group: str) -> None:
    """Call every kernel of `group` once on a tiny problem, with a real run's argument types."""
    import numpy as np

    from osmap_cli.synth.options import SynthOptions

    rng = np.random.default_rng(0)
    lo, hi = np.array([2.0, 2.0]), np.array([13.0, 13.0])
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), (8, 8, 2, 2)).copy()
    if group == "organise":
        from osmap_cli.synth.lattice import Lattice
        from osmap_cli.synth.organise import organise
        from osmap_cli.synth.refine import MAX_KNN_REFERENCES
        from osmap_cli.synth.regular import level_lattice
        from osmap_cli.synth.render import render
        from osmap_cli.texture.references import similar_positions
        from osmap_kernels.coherence import usage_counts
        from osmap_kernels.regions import copy_region_areas

        # first the three kernels that the other group's refine() calls before its own
        # (_knn_rows, usage_counts, copy_region_areas), while that group compiles align_regions,
        # so that it finds them cached rather than compiling them too
        opts = SynthOptions(width=16, height=16).validated()
        similar_positions(rng.random((16, 16, 4), dtype=np.float32), lo, hi, opts.knn,
                          MAX_KNN_REFERENCES)
        pos = np.rint(lo + rng.random((8, 8, 2)) * (hi - lo)).astype(np.float32)
        usage_counts(pos, 16, 16)
        copy_region_areas(pos, jac, False)
        pos = organise((16, 16), (8, 8), np.eye(2), lo, hi, opts, wrap=False, seed=0)
        render(rng.random((16, 16, 3), dtype=np.float32), pos, jac, False, 2)
        # a regular exemplar's lattice (phase_sums, then snap_field)
        level = level_lattice(Lattice(((8.0, 0.0), (0.0, 8.0))), 1, np.eye(2), pos, lo, hi)
        level.snap(pos, lo, hi)
    elif group == "refine":
        from osmap_cli.synth.refine import ALIGN_RADIUS, refine
        from osmap_kernels.regions import AlignParams, align_regions

        opts = SynthOptions(width=16, height=16, sweeps=2).validated()
        feat = rng.random((16, 16, 4), dtype=np.float32)
        pos = np.rint(lo + rng.random((8, 8, 2)) * (hi - lo)).astype(np.float32)
        # align_regions first, with the argument types refine() gives it (see above)
        align_regions(pos, feat, jac, AlignParams(radius=ALIGN_RADIUS, wrap=False, lo=lo, hi=hi,
                                                  seam=1.0, max_area=float(np.inf), reach=1))
        refine(pos, feat, jac, lo, hi, 2, opts, wrap=False, seed=0, salt=0)
    else:
        raise ValueError(f"unknown kernel group {group!r}")


if __name__ == "__main__":
    compile_group(sys.argv[1])
