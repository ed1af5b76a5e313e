"""Numba kernels of osmap, installed as `osmap_kernels`: pure functions, arrays in, arrays out.

Every `@njit(cache=True)` kernel here that a command's default run calls is compiled ahead of
its first run, with no list to keep: an installed package carries them compiled for the generic
CPU of its kind in `portable-cache/` (the build step runs each command once and keeps what
Numba compiled), and this CPU's are compiled in the background after the first run
(osmap_cli.kernelwarm).
"""

import os as _os

if _os.environ.get("OSMAP_QUICK_LOADS") == "1":
    from osmap_kernels.cacheload import quick_loads as _quick_loads
    from osmap_kernels.cacheload import runtime_ahead as _runtime_ahead

    if _quick_loads() and _os.environ.get("NUMBA_DISABLE_JIT") != "1":
        _runtime_ahead()

from osmap_kernels.cacheload import start_up_done as _start_up_done  # noqa: E402

_start_up_done()


def parallel_launches_threadsafe() -> bool:
    """Whether two Python threads may run parallel kernels at once: Numba's omp and tbb
    threading layers allow it; its workqueue layer (taken when neither an OpenMP nor a TBB
    runtime is found) aborts the process when they do."""
    import numba
    from numba.np.ufunc.parallel import _launch_threads

    _launch_threads()  # picks the layer now, as the first parallel kernel would
    return numba.threading_layer() in ("omp", "tbb")
