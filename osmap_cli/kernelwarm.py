"""Which compiled kernels a run uses, and compiling them ahead of it.

A first run must not wait for Numba to compile (about 30 CPU s for `osmap synth`, more with
`osmap solid`). The mechanism, in the order a user meets it:

1. **Build** (``pip install .``, the build hook in buildhook/osmap_build.py): the warm-up
   plan (osmap_cli.kernelplan) is run with Numba's target set to the ``generic`` CPU; the
   compiled entries go into the package as its *portable cache* (osmap_cli.kernelcache).
   Generic code runs on any CPU of the architecture, about 10 % slower than code compiled for
   this one.
2. **First runs** (:func:`prepare`, called by the console script before any command): when the
   cache holds no kernels compiled for this CPU yet, the portable ones are seeded into Numba's
   cache folder and the run uses them (NUMBA_CPU_NAME=generic), so it starts at once.
3. **After such a run** (:func:`after_run`, once its outputs are committed): a background
   process (lowest priority, one at a time) compiles every signature of the portable cache for
   this CPU and marks the cache ready; later runs use those. ``osmap warmup`` does the same in
   the foreground, on every core.

Without a portable cache (a development tree, another numba than the build's) nothing changes:
kernels compile on first use, `osmap synth` in two processes at once (osmap_cli.synth.warm).

OSMAP_KERNELS chooses: ``auto`` (the console script's default: as above), ``host`` (the
library's default: this CPU's kernels only, compiled on first use), ``portable`` (the portable
kernels while this CPU's are not compiled, and no background compile). A NUMBA_CPU_NAME set by
the user wins over all three.

    python -m osmap_cli.kernelwarm portable [--if-stale] DEST   # the build step (DEST/<package>/
                                                                 # and manifest.json)
"""

from __future__ import annotations

import contextlib
import os
import sys

from osmap_cli import kernelcache
from osmap_cli.kernelplan import PLAN, plan_digest, write_inputs

__all__ = ["after_run", "build_portable", "compile_for_host", "prepare", "using_portable"]

POLICIES = ("auto", "host", "portable")
COMPILE_LOCK = "osmap-compile.lock"
PLAN_ENV = "OSMAP_WARM_PLAN"  # set in the processes that run the plan: no nested compiles

_state = {"portable": False, "policy": "host"}


# ---------------------------------------------------------------------------------------------
# choosing the target of a run


def policy() -> str:
    value = os.environ.get("OSMAP_KERNELS", "host").strip().lower()
    return value if value in POLICIES else "host"


def using_portable() -> bool:
    """Whether this process chose the portable kernels."""
    return _state["portable"]


def prepare() -> None:
    """Point Numba at the portable kernels when this CPU's are not compiled yet (see the module
    docstring). Call before anything imports a kernel; never fails a run."""
    chosen = policy()
    _state["policy"] = chosen
    if (chosen == "host" or "NUMBA_CPU_NAME" in os.environ
            or os.environ.get("NUMBA_DISABLE_JIT") == "1" or os.environ.get(PLAN_ENV)):
        return
    manifest = kernelcache.load_manifest()
    if manifest is None:
        return
    try:
        if os.path.exists(kernelcache.host_marker(manifest)):
            return
        if not kernelcache.portable_usable(manifest):
            return
        from numba.core import config
        from numba.core.registry import cpu_target

        if "_toplevel_target_context" in vars(cpu_target):
            return  # something compiled already: too late to change the target
    except Exception:  # noqa: BLE001 - a broken cache must not stop a run: compile instead
        return
    # numba read its configuration when imported (above): set the target and read it again,
    # before anything is compiled, loaded or pickled (seeding pickles numba types)
    saved = {k: os.environ.get(k) for k in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    os.environ["NUMBA_CPU_NAME"] = "generic"
    os.environ["NUMBA_CPU_FEATURES"] = ""
    config.reload_config()
    try:
        kernelcache.seed(manifest)
    except Exception:  # noqa: BLE001 - no portable entries after all: this CPU's, compiled
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        config.reload_config()
        return
    _state["portable"] = True


def after_run(argv: list[str] | None = None) -> None:
    """After a successful run that used the portable kernels (policy auto): start the
    background compile for this CPU, unless one is running or failed before. Says so in one
    line on an interactive terminal (not with -q, --quiet or --json)."""
    import subprocess

    if not _state["portable"] or _state["policy"] != "auto" or "osmap_kernels" not in sys.modules:
        return  # (no kernel ran: `osmap --help`, `osmap info`)
    words = set(sys.argv[1:] if argv is None else argv)
    manifest = kernelcache.load_manifest()
    if manifest is None or os.path.exists(kernelcache.host_marker(manifest)):
        return
    if os.path.exists(kernelcache.host_marker(manifest, "failed")):
        _tell("osmap: warning: compiling the kernels for this CPU failed; `osmap warmup` says "
              "why (runs use the portable ones)", words)
        return
    folder = kernelcache.cache_folder(kernelcache.package_dir("osmap_kernels"))
    with kernelcache.locked(folder, wait=False, name=COMPILE_LOCK) as free:
        if not free:
            return
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    env["OSMAP_KERNELS"] = "host"
    try:
        subprocess.Popen([sys.executable, "-m", "osmap_cli.kernelwarm", "background"], env=env,
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, start_new_session=True, close_fds=True,
                         cwd=os.path.expanduser("~") if os.path.isdir(os.path.expanduser("~"))
                         else "/")
    except OSError:
        return
    _tell("osmap: compiling the kernels for this CPU in the background (once, about a minute); "
          "until then runs use portable ones", words)


def _tell(line: str, words: set) -> None:
    """LINE on stderr, if it is a terminal and the command was not asked to be quiet."""
    with contextlib.suppress(Exception):
        if sys.stderr.isatty() and not words & {"-q", "--quiet", "--json"}:
            print(line, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------
# compiling: the plan (build, or no portable cache) and the portable signatures (this CPU)


def _children(jobs: list[tuple[list[str], dict]], workers: int) -> list[str | None]:
    """Run each (argv, env) as a child process, WORKERS at a time; for each, None if it
    succeeded, else the last line it printed on stderr."""
    import subprocess
    import tempfile

    pending, running, results = list(enumerate(jobs)), [], [None] * len(jobs)
    try:
        while pending or running:
            while pending and len(running) < workers:
                index, (argv, env) = pending.pop(0)
                errors = tempfile.TemporaryFile()
                running.append((index, errors, subprocess.Popen(
                    argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                    stderr=errors)))
            index, errors, process = running[0]
            code = process.wait()
            running.pop(0)
            errors.seek(0)
            lines = errors.read().decode(errors="replace").strip().splitlines()
            errors.close()
            if code != 0:
                results[index] = lines[-1] if lines else f"exit code {code}"
    finally:  # stopped (Ctrl-C, SIGTERM): the children stop too
        for _, errors, process in running:
            process.kill()
            process.wait()
            errors.close()
    return results


def _base_env(staging: str | None, generic: bool) -> dict:
    """A compiling child's environment: STAGING as its NUMBA_CACHE_DIR (None: the user's)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    if staging is not None:
        env["NUMBA_CACHE_DIR"] = staging
    env.update(OSMAP_KERNELS="host", NUMBA_NUM_THREADS="1", OSMAP_QUICK_LOADS="0")
    env[PLAN_ENV] = "1"
    if generic:
        env.update(NUMBA_CPU_NAME="generic", NUMBA_CPU_FEATURES="")
    return env


def _workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def run_plan(generic: bool, workers: int | None = None,
             staging: bool = True) -> tuple[str, list[str]]:
    """Run every plan entry in its own process; with STAGING in its own cache folder (a scratch
    NUMBA_CACHE_DIR each, merged later: no two processes write one numba index), else in the
    user's. Returns the scratch root and the names of the entries that failed."""
    import tempfile

    root = tempfile.mkdtemp(prefix="osmap-warm-")
    work = os.path.join(root, "work")
    os.makedirs(work)
    inputs = write_inputs(work)
    runs = dict(PLAN)
    jobs = []
    for name, args in runs.items():
        env = _base_env(os.path.join(root, "cache", name) if staging else None, generic)
        out = os.path.join(work, f"out-{name}")
        os.makedirs(out)
        fields = dict(inputs, out=out)
        argv = [sys.executable, "-m", "osmap_cli.cli", *(a.format(**fields) for a in args)]
        jobs.append((argv, env))
    results = _children(jobs, workers or _workers())
    return root, [f"{name} ({why})" for name, why in zip(runs, results) if why is not None]


def _staged(root: str, package: str) -> list[str]:
    folder = kernelcache.package_dir(package)
    if folder is None:
        return []
    sub = kernelcache._subpath(folder)
    cache = os.path.join(root, "cache")
    return [os.path.join(cache, name, sub) for name in sorted(os.listdir(cache))
            if os.path.isdir(os.path.join(cache, name, sub))]


def build_portable(dest: str, log=print) -> int:
    """The build step: compile the plan for the generic CPU into DEST (one folder per package
    and manifest.json). Returns the number of cached kernel signatures."""
    import shutil
    import time

    started = time.monotonic()
    root, failed = run_plan(generic=True)
    try:
        if failed:
            raise RuntimeError(f"warm-up runs failed: {', '.join(failed)}")
        shutil.rmtree(dest, ignore_errors=True)
        packages, count = [], 0
        for package in kernelcache.PACKAGES:
            added = sum(kernelcache.merge_folder(staged, os.path.join(dest, package),
                                                 accept=_generic)
                        for staged in _staged(root, package))
            if added:
                packages.append(package)
                count += added
        kernelcache.write_manifest(dest, packages, count, plan=plan_digest())
    finally:
        shutil.rmtree(root, ignore_errors=True)
    log(f"osmap: portable kernel cache: {count} signatures of {', '.join(packages)} "
        f"({time.monotonic() - started:.0f} s)")
    return count


def _generic(key) -> bool:
    return key[1][1] == "generic"


def _portable_kernels(manifest) -> list[tuple[str, str, int]]:
    """(package, index base name, bytes of its portable entries) of every portable kernel."""
    found = []
    for package in manifest["packages"]:
        folder = manifest.folder(package)
        for base, (_, overloads) in kernelcache.index_entries(folder).items():
            size = sum(os.path.getsize(os.path.join(folder, n)) for n in overloads.values()
                       if os.path.exists(os.path.join(folder, n)))
            found.append((package, base, size))
    return found


def compile_for_host(manifest, workers: int | None = None) -> list[str]:
    """Compile every signature of the portable cache for this CPU, WORKERS processes at a
    time (a scratch cache each, then merged into the active folders); returns what failed."""
    import json
    import shutil
    import tempfile

    kernels = sorted(_portable_kernels(manifest), key=lambda k: -k[2])
    workers = max(1, min(workers or _workers(), len(kernels)))
    parts = [[] for _ in range(workers)]
    loads = [0] * workers
    for package, base, size in kernels:  # largest first, each to the least loaded part
        lightest = loads.index(min(loads))
        parts[lightest].append([package, base])
        loads[lightest] += size
    root = tempfile.mkdtemp(prefix="osmap-host-")
    try:
        jobs = []
        for index, part in enumerate(parts):
            env = _base_env(os.path.join(root, "cache", str(index)), generic=False)
            argv = [sys.executable, "-m", "osmap_cli.kernelwarm", "host-part", manifest.root,
                    json.dumps(part)]
            jobs.append((argv, env))
        results = _children(jobs, workers)
        failed = [f"part {i + 1} of {len(parts)} ({why})" for i, why in enumerate(results)
                  if why is not None]
        for package in manifest["packages"]:
            target = kernelcache.cache_folder(kernelcache.package_dir(package))
            with kernelcache.locked(target):
                for staged in _staged(root, package):
                    kernelcache.merge_folder(staged, target, accept=lambda k: not _generic(k))
        return failed
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _compile_part(root: str, part: list[list[str]]) -> int:
    """In a host-target process: compile the portable signatures of the kernels in PART."""
    import importlib

    manifest = kernelcache.load_manifest(root)
    failures = 0
    for package, base in part:
        stamp_overloads = kernelcache.index_entries(manifest.folder(package)).get(base)
        module, rest = base.split(".", 1)
        qualname = rest.rsplit("-", 1)[0]
        try:
            dispatcher = getattr(importlib.import_module(f"{package}.{module}"), qualname)
            for key in stamp_overloads[1]:
                dispatcher.compile(key[0])
        except Exception as exc:  # noqa: BLE001 - report, go on with the others
            failures += 1
            print(f"osmap: {package}.{module}.{qualname}: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
    return 1 if failures else 0


def warm_host(announce=None, background: bool = False) -> bool:
    """Compile this CPU's kernels now: the portable signatures when there is a usable portable
    cache (then mark the cache ready), else the plan's runs. Returns True if anything was
    compiled; raises RuntimeError naming what failed."""
    import shutil

    manifest = kernelcache.load_manifest()
    if manifest is not None and not kernelcache.portable_usable(manifest):
        manifest = None
    if manifest is None:
        if announce:
            announce("osmap: compiling kernels for this CPU (no portable cache to start from)")
        root, failed = run_plan(generic=False, staging=False)  # loads what is cached already
        shutil.rmtree(root, ignore_errors=True)
        if failed:
            raise RuntimeError(f"warm-up runs failed: {', '.join(failed)}")
        return True
    ready = kernelcache.host_marker(manifest)
    if os.path.exists(ready):
        return False
    kernelcache.seed(manifest)
    if announce:
        announce(f"osmap: compiling {manifest.get('signatures', 'the')} kernel signatures for "
                 "this CPU")
    failed = compile_for_host(manifest, workers=1 if background else None)
    if failed:
        kernelcache.touch(kernelcache.host_marker(manifest, "failed"), "\n".join(failed))
        raise RuntimeError(f"compiling for this CPU failed ({', '.join(failed)})")
    with contextlib.suppress(FileNotFoundError):
        os.remove(kernelcache.host_marker(manifest, "failed"))
    kernelcache.touch(ready)
    return True


def lowest_priority() -> None:
    """This process at the lowest CPU priority: nice 19, and on Linux its session's autogroup
    at nice 19 too. The background compile runs in a session of its own (it outlives the run
    that starts it), and with autogroups (most desktop kernels) each session gets a fair share
    of the CPU whatever its processes' nice: a nice-19 compile alone took a whole core from the
    next run (a first `osmap solid` ran on one of two cores)."""
    with contextlib.suppress(OSError, AttributeError):  # (no os.nice on Windows)
        os.nice(19)
    with contextlib.suppress(OSError):  # (no autogroups: nothing to do)
        with open("/proc/self/autogroup", "w") as group:
            group.write("19")


def _background() -> int:
    """The background compile after a portable run: lowest priority, one at a time; SIGTERM
    (a shutdown) stops it and its child, their scratch folders removed."""
    import signal

    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    lowest_priority()
    folder = kernelcache.cache_folder(kernelcache.package_dir("osmap_kernels"))
    with kernelcache.locked(folder, wait=False, name=COMPILE_LOCK) as free:
        if not free:
            return 0
        try:
            warm_host(background=True)
        except RuntimeError:
            return 1
    return 0


def _main(argv: list[str]) -> int:
    import json

    command, rest = argv[0], argv[1:]
    if command == "host-part":
        return _compile_part(rest[0], json.loads(rest[1]))
    if command == "background":
        return _background()
    if command == "portable":  # [--if-stale] DEST
        current = kernelcache.load_manifest(rest[-1])
        if (rest[0] == "--if-stale" and current and kernelcache.portable_usable(current)
                and current.get("plan") == plan_digest()):
            return 0
        build_portable(rest[-1])
        return 0
    print(f"unknown command {command!r}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
