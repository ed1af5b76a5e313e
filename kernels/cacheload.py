"""Loading cached kernels without Numba's registry refresh (the `osmap` command turns it on).

Before it loads any cached kernel, Numba refreshes every typing and lowering registry of its CPU
target: it imports dozens of implementation modules and installs thousands of templates, about
0.07 CPU s of a 256x256 `osmap synth`, though machine code read from the cache uses none of
them, only Numba's runtime (NRT), which is set up here instead. A kernel that still needs the
registries (compiled in object mode), or a load that fails this way, gets the refresh and
Numba's own load after all; a compile refreshes them itself. Only on the Numba versions it was
checked against (outputs byte-identical, tests green); any other keeps Numba's own loading.

The console script sets OSMAP_QUICK_LOADS=1 (its worker processes inherit it); importing
osmap_kernels then turns this on. A library user's process keeps Numba's behaviour.
"""

from __future__ import annotations

__all__ = ["QUICK_LOADS_CHECKED", "quick_loads"]

QUICK_LOADS_CHECKED = ("0.68.",)


def quick_loads() -> bool:
    """Patch Numba's cache loading as the module docstring says; returns whether it is on."""
    import numba

    if not numba.__version__.startswith(QUICK_LOADS_CHECKED):
        return False
    try:
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
    return True
