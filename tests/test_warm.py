"""The first-run compile: detected from Numba's cache (this CPU's entries only), announced once,
silent with --quiet; the portable kernels that serve a cold cache, and this CPU's taking over."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from osmap_cli.synth import warm


def test_an_empty_cache_is_cold_and_the_repository_cache_is_warm(tmp_path):
    code = "from osmap_cli.synth.warm import cold_groups; print(cold_groups())"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "['organise', 'refine']"
    assert warm.cold_groups() == []  # the session fixture compiled them


def test_a_regular_exemplars_lattice_kernels_are_warmed_too():
    from osmap_cli.kernelplan import PLAN, plan_exemplar
    from osmap_cli.synth.lattice import find_lattice

    # the build's plan runs a regular exemplar beside the plain one (a lattice run calls them)
    assert "{ex}" in PLAN["synth"] and "{regular}" in PLAN["synth"]
    assert find_lattice(plan_exemplar("regular")) is not None
    assert find_lattice(plan_exemplar()) is None
    # and a development tree's first run compiles them with the organise group
    names = {kernel.__name__ for kernel, _ in warm._dispatchers("organise")}
    assert {"snap_field", "phase_sums"} <= names


@pytest.fixture
def cold(monkeypatch):
    """Pretend the cache is cold once; record what would be compiled."""
    compiled = []
    state = {"cold": True}
    monkeypatch.setattr(warm, "cold_groups", lambda: ["organise", "refine"] if state["cold"]
                        else [])

    def fake_compile(groups, workers):
        compiled.append(groups)
        state["cold"] = False

    monkeypatch.setattr(warm, "_compile", fake_compile)
    return compiled


def test_a_cold_run_announces_the_compile_once(cold, run_cli, small_samples, tmp_path):
    args = ("--size", "32", "--preset", "fast")
    first = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png", *args)
    assert first.code == 0, first.err
    assert cold == [["organise", "refine"]]
    assert first.err_lines[0].startswith("osmap: compiling kernels, first run only (about ")
    second = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "b.png", *args)
    assert second.code == 0 and "compiling" not in second.err
    assert cold == [["organise", "refine"]]


def test_quiet_compiles_without_a_word(cold, run_cli, small_samples, tmp_path):
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png",
                     "--size", "32", "--preset", "fast", "--quiet")
    assert result.code == 0 and result.err == ""
    assert cold == [["organise", "refine"]]


def test_json_keeps_stdout_for_records(cold, run_cli, small_samples, tmp_path):
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "a.png",
                     "--size", "32", "--preset", "fast", "--json")
    assert result.code == 0
    assert "compiling" not in result.out and "compiling kernels" in result.err


def test_a_refused_size_neither_compiles_nor_announces(cold, run_cli, monkeypatch,
                                                       small_samples, tmp_path):
    monkeypatch.setenv("OSMAP_MEMORY_LIMIT", "300M")
    result = run_cli("synth", small_samples / "cells.png", "-o", tmp_path / "big.png",
                     "--size", "4096")
    assert result.code == 1 and "needs about" in result.err
    assert "compiling" not in result.err and cold == []


def test_warmup_command(monkeypatch, run_cli):
    from osmap_cli import kernelwarm

    calls = []

    def fake_warm_host(announce=None, background=False):
        calls.append(announce is not None)
        if announce:
            announce("osmap: compiling 12 kernel signatures for this CPU")
        return len(calls) == 1

    monkeypatch.setattr(kernelwarm, "warm_host", fake_warm_host)
    first = run_cli("warmup")
    assert first.code == 0 and "compiling 12 kernel" in first.err
    assert first.out.strip() == "osmap: kernels compiled"
    again = run_cli("warmup")
    assert again.code == 0 and again.out.strip() == "osmap: kernels already compiled"
    quiet = run_cli("warmup", "--quiet")
    assert quiet.out == "" and quiet.err == "" and calls == [True, True, False]

    def broken(announce=None, background=False):
        raise RuntimeError("compiling for this CPU failed (part 1 of 2 (boom))")

    monkeypatch.setattr(kernelwarm, "warm_host", broken)
    failed = run_cli("warmup")
    assert failed.code == 1 and failed.err_lines == [
        "osmap: error: compiling for this CPU failed (part 1 of 2 (boom))"]


# ---------------------------------------------------------------------------------------------
# the portable cache, on one small kernel (coherence.usage_counts) built as the build step does

KERNEL = """
import numpy as np
from osmap_kernels.coherence import usage_counts
usage_counts(np.zeros((4, 4, 2), np.float32), 8, 8)
"""


def _python(code: str, **env) -> str:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, **env})
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


@pytest.fixture(scope="module")
def portable(tmp_path_factory):
    """A portable cache root holding usage_counts compiled for the generic CPU."""
    root = tmp_path_factory.mktemp("portable")
    scratch = root / "scratch"
    _python(KERNEL, NUMBA_CACHE_DIR=str(scratch), NUMBA_CPU_NAME="generic",
            NUMBA_CPU_FEATURES="")
    _python(f"""
from osmap_cli import kernelcache
from osmap_cli.kernelwarm import _generic
staged = {str(scratch)!r} + "/" + kernelcache._subpath(kernelcache.package_dir("osmap_kernels"))
added = kernelcache.merge_folder(staged, {str(root / "cache" / "osmap_kernels")!r}, _generic)
kernelcache.write_manifest({str(root / "cache")!r}, ["osmap_kernels"], added)
""")
    return root / "cache"


def _probe(root, cache, policy="auto"):
    """A console-script-like process: prepare(), then the kernel; what it ran on."""
    out = _python(f"""
from osmap_cli import kernelcache, kernelwarm
kernelcache.portable_root = lambda: {str(root)!r}
kernelwarm.prepare()
{KERNEL}
target = usage_counts.targetctx.codegen().magic_tuple()
print(kernelwarm.using_portable(), target[1] if target[1] != "generic" or not target[2] else "?",
      sum(usage_counts.stats.cache_misses.values()))
""", NUMBA_CACHE_DIR=str(cache), OSMAP_KERNELS=policy)
    portable, cpu, compiled = out.split()
    return portable == "True", cpu, int(compiled)  # cpu "?": generic name, this CPU's features


def test_portable_kernels_serve_a_cold_cache_until_this_cpus_are_compiled(portable, tmp_path):
    cache = tmp_path / "cache"
    assert _probe(portable, cache) == (True, "generic", 0)  # seeded, loaded, nothing compiled
    assert _probe(portable, cache, policy="host")[:2] == (False, _host_cpu())
    # this CPU's kernels, as the background compile and `osmap warmup` make them
    _python(f"""
from osmap_cli import kernelcache, kernelwarm
kernelcache.portable_root = lambda: {str(portable)!r}
assert kernelwarm.warm_host() is True
assert kernelwarm.warm_host() is False
""", NUMBA_CACHE_DIR=str(cache))
    assert _probe(portable, cache) == (False, _host_cpu(), 0)
    assert _probe(portable, cache, policy="portable") == (False, _host_cpu(), 0)
    # a cache made ready on another CPU is not taken for this one's
    (marker,) = cache.rglob("osmap-host-*.ready")
    marker.rename(marker.with_name(marker.name.rsplit("-", 1)[0] + "-01234567.ready"))
    assert _probe(portable, cache) == (True, "generic", 0)


def _host_cpu() -> str:
    import llvmlite.binding as llvm

    return llvm.get_host_cpu_name()


def test_an_entry_for_another_cpu_is_not_a_cached_kernel(portable, tmp_path):
    cache = tmp_path / "cache"
    code = f"""
from osmap_cli import kernelcache
kernelcache.portable_root = lambda: {str(portable)!r}
kernelcache.seed(kernelcache.load_manifest())
from osmap_cli.synth import warm
from osmap_kernels.coherence import usage_counts
print(warm._cached(usage_counts))
"""
    assert _python(code, NUMBA_CACHE_DIR=str(cache)) == "False"  # only a generic entry
    assert _python(code, NUMBA_CACHE_DIR=str(cache), NUMBA_CPU_NAME="generic",
                   NUMBA_CPU_FEATURES="") == "True"


def test_the_cache_folder_is_numbas(tmp_path):
    code = """
from osmap_cli import kernelcache
from osmap_kernels import coherence
print(kernelcache.cache_folder(kernelcache.package_dir("osmap_kernels"))
      == coherence.usage_counts._cache.cache_path)
"""
    assert _python(code) == "True"
    assert _python(code, NUMBA_CACHE_DIR=str(tmp_path)) == "True"


def test_after_a_portable_run_this_cpus_compile_starts_in_the_background(monkeypatch, tmp_path):
    from osmap_cli import kernelcache, kernelwarm

    manifest = kernelcache.Manifest(digest="ab" * 32, packages=["osmap_kernels"])
    monkeypatch.setattr(kernelcache, "load_manifest", lambda root=None: manifest)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    started = []
    monkeypatch.setattr(subprocess, "Popen",
                        lambda argv, **kw: started.append((argv, kw)))
    monkeypatch.setitem(kernelwarm._state, "policy", "auto")
    monkeypatch.setitem(kernelwarm._state, "portable", False)
    kernelwarm.after_run([])
    assert started == []  # a run on this CPU's kernels
    monkeypatch.setitem(kernelwarm._state, "portable", True)
    kernelwarm.after_run([])
    (argv, kw), = started
    assert argv[1:] == ["-m", "osmap_cli.kernelwarm", "background"]
    assert kw["start_new_session"] and "NUMBA_CPU_NAME" not in kw["env"]
    assert kw["env"]["OSMAP_KERNELS"] == "host"
    folder = kernelcache.cache_folder(kernelcache.package_dir("osmap_kernels"))
    with kernelcache.locked(folder, name=kernelwarm.COMPILE_LOCK):
        kernelwarm.after_run([])  # one is running already
    kernelcache.touch(kernelcache.host_marker(manifest, "failed"), "boom")
    kernelwarm.after_run([])  # it failed: `osmap warmup` says why
    monkeypatch.setitem(kernelwarm._state, "policy", "portable")
    os.remove(kernelcache.host_marker(manifest, "failed"))
    kernelwarm.after_run([])  # OSMAP_KERNELS=portable: never
    assert len(started) == 1


def _autogroups_settable() -> bool:
    """Whether a new session may set its autogroup's nice here (Linux with autogroups, /proc
    writable)."""
    probe = "open('/proc/self/autogroup', 'w').write('0')"
    return os.path.exists("/proc/self/autogroup") and subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, start_new_session=True).returncode == 0


@pytest.mark.skipif(not _autogroups_settable(), reason="no settable autogroups here")
def test_the_background_compile_lowers_its_sessions_share_of_the_cpu():
    """In a session of its own (as the background compile runs), nice 19 alone leaves the
    session a full share of the CPU beside the user's next run: its autogroup is niced too."""
    code = ("from osmap_cli.kernelwarm import lowest_priority; lowest_priority(); "
            "print(open('/proc/self/autogroup').read(), end='')")
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           start_new_session=True, check=True).stdout
    assert shown.split()[-2:] == ["nice", "19"], shown


def test_quick_loads_load_the_same_kernels_without_compiling():
    code = """
import numpy as np
from numba.core.caching import Cache
from osmap_kernels.coherence import usage_counts
from osmap_kernels.regions import copy_region_areas
pos = np.random.default_rng(1).integers(0, 8, (6, 6, 2)).astype(np.float32)
counts = usage_counts(pos, 8, 8)
areas = copy_region_areas(pos, np.broadcast_to(np.eye(2, dtype=np.float32), (6, 6, 2, 2)).copy(),
                          False)
missed = sum(usage_counts.stats.cache_misses.values()) + sum(
    copy_region_areas.stats.cache_misses.values())
import sys
print(getattr(Cache.load_overload, "quick", False), "numba.np.arrayobj" in sys.modules, missed,
      counts.sum(), areas.tobytes().hex())
"""
    quick = _python(code, OSMAP_QUICK_LOADS="1").split()
    plain = _python(code, OSMAP_QUICK_LOADS="0").split()
    assert quick[0] == "True" and plain[0] == "False"
    # the kernels' environments rebuilt without importing Numba's array implementation
    assert quick[1] == "False" and plain[1] == "True"
    assert quick[2:] == plain[2:] and quick[2] == "0"  # loaded from the cache, same results


def test_quick_loads_set_up_numbas_runtime_ahead_on_a_helper_thread():
    code = """
import threading
import osmap_kernels
from numba.core.runtime.nrt import rtsys
helper = [t for t in threading.enumerate() if t.name == "osmap-runtime"]
for t in helper:
    t.join(60)
print(len(helper), rtsys._init)
"""
    assert _python(code, OSMAP_QUICK_LOADS="1") == "1 True"
    # a library user's process sets it up at its first kernel, as Numba does
    assert _python(code, OSMAP_QUICK_LOADS="0") == "0 False"


def test_the_console_script_starts_up_without_the_collector_until_the_kernels_load():
    code = """
import gc
from osmap_cli import cli
cli._start_up_without_gc()
off = not gc.isenabled()
import osmap_kernels
print(off, gc.isenabled(), gc.get_freeze_count() > 0)
"""
    assert _python(code) == "True True True"
    # a process that has the collector on (a library user's, a worker) is left alone
    code = "import gc, osmap_kernels; print(gc.isenabled(), gc.get_freeze_count())"
    assert _python(code, OSMAP_START_UP_GC="off") == "True 0"
    # one that never imports the kernels (a Dask client) has it back after a while
    code = """
import gc, time
from osmap_cli import cli
cli.START_UP_SECONDS = 0.1
cli._start_up_without_gc()
off = not gc.isenabled()
for _ in range(600):
    if gc.isenabled():
        break
    time.sleep(0.05)
print(off, gc.isenabled())
"""
    assert _python(code) == "True True"


def test_the_plans_solid_run_calls_the_structure_fills_kernels(run_cli, monkeypatch, tmp_path):
    from osmap_cli.kernelplan import PLAN, write_inputs
    from osmap_cli.solid import optimise

    # the kernels of method structure's fill that only a fill over several levels, guided by
    # a structure's labels, calls: a plan that misses them compiles them on a user's first run
    called = set()

    def spy(name, kernel):
        def call(*args):
            called.add(name)
            return kernel(*args)
        return call

    for name in ("fill_positions", "kopf_average_labelled", "kopf_cluster_labelled"):
        monkeypatch.setattr(optimise, name, spy(name, getattr(optimise, name)))
    fields = dict(write_inputs(str(tmp_path)), out=str(tmp_path))
    done = run_cli(*(arg.format(**fields) for arg in PLAN["solid"]))
    assert done.code == 0, done.err
    assert called == {"fill_positions", "kopf_average_labelled", "kopf_cluster_labelled"}


def test_the_plans_cells_run_builds_packed_cells(run_cli, monkeypatch, tmp_path):
    from osmap_cli.kernelplan import PLAN, plan_exemplar, write_inputs
    from osmap_cli.solid.structure import cells
    from osmap_cli.solid.structure.analysis import analyse, reads_as_cells

    # packed cells are labelled by a kernel no other structure calls: the plan runs an
    # exemplar that reads as cells, or that kernel compiles on a user's first run
    assert reads_as_cells(analyse(plan_exemplar("cells")))
    assert not reads_as_cells(analyse(plan_exemplar()))
    called = []
    kernel = cells.power_cells
    monkeypatch.setattr(cells, "power_cells", lambda *args: called.append(1) or kernel(*args))
    fields = dict(write_inputs(str(tmp_path)), out=str(tmp_path))
    done = run_cli(*(arg.format(**fields) for arg in PLAN["solid"]))
    assert done.code == 0, done.err
    assert called
