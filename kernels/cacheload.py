"""Loading cached kernels without Numba's registry refresh (the `osmap` command turns it on).

Before it loads any cached kernel, Numba refreshes every typing and lowering registry of its CPU
target: it imports dozens of implementation modules and installs thousands of templates, about
0.07 CPU s of a 256x256 `osmap synth`, though machine code read from the cache uses none of
them, only Numba's runtime (NRT), which is set up here instead. Likewise a cached kernel's
environment names the module of every Numba function it inlined (numba.np.arrayobj for np.empty)
and Numba imports that module to rebuild it, pulling in most of Numba's implementation (its
unicode, set and masked-array support: about 0.05 s); an environment's module globals are only
read by object-mode code, so one whose module is not imported yet is rebuilt here with its name
alone. A kernel that still needs the registries (compiled in object mode), or a load that fails
this way, gets the refresh and Numba's own load after all; a compile refreshes them itself. Only
on the Numba versions it was checked against (outputs byte-identical, tests green); any other
keeps Numba's own loading.

The runtime itself is set up on a helper thread as soon as osmap_kernels is imported
(`runtime_ahead`), beside the work a run does before its first kernel call.

The console script sets OSMAP_QUICK_LOADS=1 (its worker processes inherit it); importing
osmap_kernels then turns both on. A library user's process keeps Numba's behaviour.
"""

from __future__ import annotations

__all__ = ["QUICK_LOADS_CHECKED", "quick_loads", "runtime_ahead", "start_up_done"]

QUICK_LOADS_CHECKED = ("0.68.",)


def quick_loads() -> bool:
    """Patch Numba's cache loading as the module docstring says; returns whether it is on."""
    import numba

    if not numba.__version__.startswith(QUICK_LOADS_CHECKED):
        return False
    try:
        from numba.core import environment
        from numba.core.caching import Cache
        from numba.core.runtime.nrt import rtsys
    except ImportError:
        return False
    numba_load = Cache.load_overload
    if getattr(numba_load, "quick", False):
        return True

    def load_overload(self, sig, target_context):
        try:
            rtsys.initialize(target_context)
            result = self._load_overload(sig, target_context)
        except Exception:  # noqa: BLE001 - Numba's own way, whatever went wrong
            return numba_load(self, sig, target_context)
        if result is not None and getattr(result, "objectmode", False):
            return numba_load(self, sig, target_context)
        return result

    load_overload.quick = True
    Cache.load_overload = load_overload
    environment._rebuild_env = _quick_rebuild_env(environment._rebuild_env)
    return True


def runtime_ahead() -> None:
    """Set up Numba's runtime (NRT) on a helper thread now, not at the first kernel's load: its
    LLVM compile (about 0.03 CPU s) runs mostly outside the GIL, beside what the process does
    before it calls a kernel (the rest of the imports, reading the input, the set-up). A kernel
    loaded before it is done waits for it (Numba's compiler lock); if it fails, the first load
    sets the runtime up again, as without this. The target context is made here, on the
    calling thread, so that every kernel and the runtime share one."""
    import threading

    from numba.core.registry import cpu_target
    from numba.core.runtime.nrt import rtsys

    context = cpu_target.target_context

    def set_up():
        try:
            rtsys.initialize(context)
        except Exception:  # noqa: BLE001, S110 - see the docstring
            pass

    threading.Thread(target=set_up, name="osmap-runtime", daemon=True).start()


def _quick_rebuild_env(numba_rebuild):
    """Numba's environment rebuild (unpickling a cached kernel), without importing a module
    that is not imported yet: nopython code reads only the environment's constants."""
    import sys

    from numba.core.environment import Environment, lookup_environment

    def rebuild_env(modname, consts, env_name):
        if modname in sys.modules or lookup_environment(env_name) is not None:
            return numba_rebuild(modname, consts, env_name)
        env = Environment({"__name__": modname})
        env.consts[:] = consts
        env.env_name = env_name
        Environment._memo[env_name] = env
        return env

    rebuild_env.quick = True
    return rebuild_env


def start_up_done() -> None:
    """The console script switched the garbage collector off for its start-up
    (osmap_cli.cli._start_up_without_gc; OSMAP_START_UP_GC=off) and this process still runs
    without it: freeze what is loaded and switch it back on. A process that has the collector
    on (a library user's, a worker that inherited the variable) is left alone."""
    import gc
    import os

    if os.environ.get("OSMAP_START_UP_GC") == "off" and not gc.isenabled():
        gc.freeze()
        gc.enable()
